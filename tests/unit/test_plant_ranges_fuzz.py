"""The model layer's ranges and rules admit only plants that step without refusal in bounded
work (issue 27).

Hypothesis draws every ``[plant]`` field at the edges of its range (its bounds, just inside
them, the thresholds of :data:`papwc.model.plant.OFF_OR_AT_LEAST` and just below them, 5e-324,
1e-300, ...) or at its default; for every set the model layer accepts, the plant
(:class:`papwc.model.dynamics.Plant`, which FrictionPlant.fmu steps) takes communication
steps of 10 ms and 1 ms under forces up to 3 times max(f_s, m * 1 m/s^2), pushing, releasing
and reversing: no step is refused, every state is finite, and no step needs more than
:data:`STEPS_MAX` integrator steps or :data:`EVENTS_MAX` stick-slip events -- the work of a
step, which bounds its time (about 30 us per integrator step in ``papwc bench``'s plant
section on the machine of the README). Before these rules, x_resolution = 5e-324 overflowed,
tau_u = 5e-324 and v_s = 1e-12 with delta_s = 10 were refused by the integrator, and tiny
masses under large forces took up to 20 s a step (200000 integrator steps).

``PAPWC_FUZZ_EXAMPLES=N`` runs a longer campaign (default 300).
"""

from __future__ import annotations

import math
import os

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from papwc.model.dynamics import STATE_FIELDS, Plant
from papwc.model.plant import (
    INTEGRATED_OFF_OR_AT_LEAST,
    OFF_OR_AT_LEAST,
    PLANT_DEFAULTS,
    PLANT_PARAMETERS,
    SCENARIO_PLANT_FIELDS,
    plant_problems,
)
from papwc.model.variables import by_name

PLANT = by_name(PLANT_PARAMETERS)
EXAMPLES = int(os.environ.get("PAPWC_FUZZ_EXAMPLES", "300"))
#: Most integrator steps and stick-slip events one accepted communication step may take.
STEPS_MAX = 20_000
EVENTS_MAX = 1_000
#: Forces applied, in units of max(f_s, m * 1 m/s^2): push, hold, release, reverse, nudge.
FORCES = (0.0, 1.5, 1.5, 0.0, 0.0, -3.0, 0.0, 0.5, 0.0)


def edges(name: str) -> list:
    """The values of ``name`` hypothesis draws: its default and the edges of its range."""
    var = PLANT[name]
    if var.type == "Integer":
        return [var.default, var.min, var.max]
    lo, hi = var.min, var.max
    values = [var.default, lo, hi, 5e-324, 1e-300, 1e-12, 1e-9, 1e-6, 1e-3, 1.0,
              lo * (1 + 1e-9) if lo else 5e-324, hi * (1 - 1e-9), hi / 2]
    for table in (OFF_OR_AT_LEAST, INTEGRATED_OFF_OR_AT_LEAST):
        if name in table:
            values += [table[name], table[name] * (1 - 1e-9), table[name] * (1 + 1e-9)]
    return sorted({v for v in values if lo <= v <= hi and not (var.max_open and v == hi)
                   and not (var.min_open and v == lo)})


@st.composite
def plants_at_edges(draw) -> dict:
    return {name: draw(st.sampled_from(edges(name))) if draw(st.booleans())
            else PLANT_DEFAULTS[name] for name in SCENARIO_PLANT_FIELDS}


@pytest.mark.slow
@settings(max_examples=EXAMPLES, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(params=plants_at_edges(), h=st.sampled_from((0.01, 1e-3)))
def test_every_accepted_plant_steps_without_refusal_in_bounded_work(params, h) -> None:
    if plant_problems(params):
        return  # refused by the model layer: a scenario, an SSP binding or the FMU says so
    plant = Plant(params)
    scale = max(params["f_s"], params["m"] * 1.0)
    for k, factor in enumerate(FORCES):
        plant.work = (0, 0)
        reason = plant.step(factor * scale, h)
        assert reason is None, (k, reason)
        steps, events = plant.work
        assert steps <= STEPS_MAX and events <= EVENTS_MAX, (k, plant.work)
        state = plant.state()
        assert all(math.isfinite(state[name]) for name in STATE_FIELDS)
        assert math.isfinite(plant.x_meas())


@pytest.mark.parametrize(("values", "name", "words"), [
    ({"x_resolution": 5e-324}, "x_resolution", "must be 0 (none) or >= 1e-12 m"),
    ({"tau_u": 5e-324}, "tau_u", "must be 0 (none) or >= 1e-06 s"),
    ({"v_s": 1e-12, "delta_s": 10.0}, "v_s", "must be 0 (none) or >= 1e-06 m/s"),
    ({"m": 1e-6, "f_s": 1e9, "f_c": 100.0, "c": 0.0, "ripple": 0.5}, "m",
     "f_s/m = 1e+15 m/s^2 (f_s = 1000000000.0 N); must be <= 10000 m/s^2 when the plant is "
     "integrated (ripple = 0.5 > 0)"),
    ({"c": 1e9, "tau_u": 1e-3}, "c", "the damping rate c/m = 6.66667e+06 1/s"),
    ({"m_d": 1e-3, "k_t": 1e-12, "c_t": 999e6}, "c_t",
     "the coupling's damping rate c_t*(1/m + 1/m_d) = 9.99007e+11 1/s"),
    ({"f_c": 1e-12, "f_s": 130.0, "v_s": 1e-3}, "f_c",
     "must be 0 (none) or >= 1e-06 N when the plant is integrated (v_s = 0.001 > 0)"),
])
def test_the_settings_that_overflowed_or_took_seconds_are_refused(values, name, words) -> None:
    found = plant_problems({**PLANT_DEFAULTS, **values})
    assert [n for n, _ in found] == [name], found
    assert words in found[0][1], found


@pytest.mark.parametrize(("plant", "words"), [
    ("x_resolution = 5e-324", "field 'x_resolution': x_resolution = 5e-324 m: must be 0 (none) "
     "or >= 1e-12 m"),
    ("tau_u = 5e-324", "field 'tau_u': tau_u = 5e-324 s: must be 0 (none) or >= 1e-06 s"),
    ("v_s = 1e-12\ndelta_s = 10.0", "field 'v_s': v_s = 1e-12 m/s: must be 0 (none) or >= "
     "1e-06 m/s"),
    ("m = 1e-6\nf_c = 0.001\nf_s = 130.0\nc = 0.0\nripple = 0.5",
     "field 'm': m = 1e-06 kg: the breakaway force gives the mass f_s/m = 1.3e+08 m/s^2"),
])
@pytest.mark.parametrize("where", ["fmu", "physics"])
def test_through_the_command_line_one_line_and_nothing_written(
        plant, words, where, tmp_path, capsys) -> None:
    from papwc.cli import main

    scenario = tmp_path / "s.toml"
    scenario.write_text(f'name = "s"\n[plant]\n{plant}\n[[controller]]\nkind = "papwc"\n')
    out = tmp_path / "out"
    assert main(["run", str(scenario), "--out", str(out), "--plant", where]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    assert lines[0].startswith(f"papwc run: error: {scenario}: [plant] ")
    assert words in lines[0], lines[0]
    assert not out.exists()
