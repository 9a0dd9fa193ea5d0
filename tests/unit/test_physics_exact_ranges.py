"""The physics is exact in double precision over every accepted input (issue 13, group 2).

The ranges are the ``min``/``max`` of the model layer's tables; hypothesis draws
magnitudes over them (log-uniform, and the bounds themselves) and checks

- :func:`papwc.model.stickslip.step` against the same closed form evaluated in
  90-digit decimal arithmetic (relative error of the displacement and velocity
  below 1e-10, beyond the rounding of the position itself);
- the pulse model, Eq. (3), and its inverses;
- whole closed loops of every controller kind on accepted scenarios: no
  exception, no NaN, every force within ``f_p_max``.

Before the ranges were stated, m = 1e-300 kg gave x = 0 while v = 0.29 m/s, and
about one accepted scenario in ten raised ZeroDivisionError or OverflowError.
"""

from __future__ import annotations

import math
import os
from decimal import Decimal, localcontext

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from papwc.controllers.settings import SETTINGS_BY_NAME
from papwc.model.maneuver import MANEUVER_VARIABLES
from papwc.model.plant import OFF_OR_AT_LEAST, PLANT_PARAMETERS
from papwc.model.pulse import pulse_amplitude, pulse_displacement, pulse_width
from papwc.model.stickslip import step
from papwc.model.variables import by_name
from papwc.scenario import parse_scenario
from papwc.scenario_run import run_scenario

#: Fuzz campaigns over every accepted input (seconds each): not in the quick loop.
pytestmark = pytest.mark.slow

PLANT = by_name(PLANT_PARAMETERS)
MANEUVER = by_name(MANEUVER_VARIABLES)
#: Examples per test; PAPWC_FUZZ_EXAMPLES=N runs a longer campaign.
EXAMPLES = int(os.environ.get("PAPWC_FUZZ_EXAMPLES", "250"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow])


# --- a reference in 90-digit decimal arithmetic ----------------------------------------------

_PREC = 90


def _series(z: Decimal, first_factorial: int) -> Decimal:
    """sum_k (-z)**k / (k + first_factorial)!, to the precision."""
    total, power, k = Decimal(0), Decimal(1), 0
    fact = Decimal(math.factorial(first_factorial))
    while True:
        term = power / fact
        total += term
        if abs(term) < Decimal(10) ** -(_PREC - 5):
            return total
        k += 1
        power *= -z
        fact *= k + first_factorial


def _phi1(z: Decimal) -> Decimal:
    return _series(z, 1) if z < 1 else (1 - (-z).exp()) / z


def _phi2(z: Decimal) -> Decimal:
    return _series(z, 2) if z < 1 else (z - 1 + (-z).exp()) / (z * z)


def _segment(x, v, force, h, m, c):
    z = c * h / m
    p1 = _phi1(z)
    return x + v * h * p1 + (force / m) * h * h * _phi2(z), v * (-z).exp() + (force / m) * h * p1


def reference_step(x, v, u, h, m, f_c, f_s, c) -> tuple[float, float]:
    """Eq. (1) over one interval with constant u, in decimal arithmetic (exact inputs)."""
    with localcontext() as ctx:
        ctx.prec, ctx.Emin, ctx.Emax = _PREC, -999999, 999999
        x, v, u, h, m, f_c, f_s, c = (Decimal(q) for q in (x, v, u, h, m, f_c, f_s, c))
        if v == 0 and -f_s <= u <= f_s:  # stuck
            return float(x), 0.0
        # the friction opposes the motion: the velocity's direction, from rest the force's
        s = Decimal(1).copy_sign(u if v == 0 else v)
        force = u - s * f_c
        if v != 0 and s * force < 0:  # decelerating: is the mass at rest before h ends?
            t_star = -m * v / force if c == 0 else (m / c) * (1 + (-c * v / force)).ln()
            if t_star < h:
                x, _ = _segment(x, v, force, t_star, m, c)
                h -= t_star
                if -f_s <= u <= f_s:
                    return float(x), 0.0
                s = -s
                force = u - s * f_c
                v = Decimal(0)
        x_end, v_end = _segment(x, v, force, h, m, c)
        return float(x_end), float(v_end)


# --- strategies over the tables' ranges ------------------------------------------------------


def magnitude(lo: float, hi: float, zero: bool = True, decades: float = 15.0):
    """Values in [lo, hi]: the bounds, 0 (if allowed and lo <= 0), log-uniform between."""
    low = lo if lo > 0.0 else hi * 10.0 ** -decades
    if not math.log(low) < math.log(hi):
        return st.sampled_from([lo, hi])
    spread = st.floats(math.log(low), math.log(hi)).map(
        lambda e: min(max(math.exp(e), low), hi))
    ends = [v for v in (lo, hi) if v > 0.0 or zero]
    return st.one_of(st.sampled_from(ends), spread)


def in_range(var, zero: bool = True):
    return magnitude(var.min, var.max, zero=zero and not var.min_open)


def signed(strategy):
    return st.tuples(strategy, st.booleans()).map(lambda p: -p[0] if p[1] else p[0])


@st.composite
def plant_step(draw):
    m = draw(in_range(PLANT["m"]))
    f_c = draw(in_range(PLANT["f_c"]))
    f_s = min(f_c * draw(magnitude(1.0, 1e3)), PLANT["f_s"].max)
    f_s = max(f_s, f_c)
    c = draw(in_range(PLANT["c"]))
    h = draw(in_range(MANEUVER["T"]))
    f_max = SETTINGS_BY_NAME["f_p_max"].max
    u = draw(st.one_of(st.just(0.0), st.just(f_s), st.just(math.nextafter(f_s, math.inf)),
                       magnitude(1e-9, f_max)))
    u = -u if draw(st.booleans()) else u
    x = draw(st.one_of(st.just(0.0), signed(magnitude(1e-12, PLANT["x0"].max))))
    v = draw(st.one_of(st.just(0.0), signed(magnitude(1e-12, PLANT["v0"].max))))
    return x, v, u, h, m, f_c, f_s, c


@given(plant_step())
@example((0.0, 0.0, 300.0, 0.01, 1e-6, 100.0, 130.0, 700.0))
@example((0.0, 0.0, 1e9, 1e3, 1e-6, 0.0, 0.0, 1e9))
@example((0.0, 0.0, 300.0, 0.01, 1e9, 100.0, 130.0, 0.0))
@SETTINGS
def test_step_is_exact_over_the_accepted_ranges(args) -> None:
    x0, v0, u, h, m, c = args[0], args[1], args[2], args[3], args[4], args[7]
    x, v = step(*args)
    xr, vr = reference_step(*args)
    assert math.isfinite(x) and math.isfinite(v)
    # The closed form adds the viscous segment's terms v0*m/c and u*h/c; where they cancel
    # (a mass at its terminal speed within the step) the result is known to their ulp.
    terms = (abs(v0) * m / c, abs(u) * h / c) if c > 0.0 else ()
    ulp = math.ulp(max(abs(x0), abs(xr), *terms))
    assert abs(x - xr) <= 1e-10 * abs(xr - x0) + 2.0 * ulp + 1e-300, (x, xr)
    assert abs(v - vr) <= 1e-10 * max(abs(v0), abs(vr)) + 1e-300, (v, vr)


@st.composite
def pulse(draw):
    m = draw(in_range(PLANT["m"]))
    f_c = draw(in_range(PLANT["f_c"]))
    c = draw(in_range(PLANT["c"]))
    f_max = SETTINGS_BY_NAME["f_p_max"].max
    f_p = draw(magnitude(max(f_c, 1e-9) * (1.0 + 1e-6), f_max)) if f_c < f_max else f_max
    t_p = draw(magnitude(MANEUVER["T"].min, SETTINGS_BY_NAME["t_p_max"].max))
    return f_p, t_p, m, f_c, c


def reference_pulse(f_p, t_p, m, f_c, c) -> float:
    """Eq. (3) by the reference: the pulse, then coasting to rest (decimal arithmetic)."""
    x1, v1 = reference_step(0.0, 0.0, f_p, t_p, m, f_c, f_c, c)
    if f_c == 0.0:
        return math.inf if c == 0.0 else x1 + v1 * m / c
    with localcontext() as ctx:
        ctx.prec, ctx.Emin, ctx.Emax = _PREC, -999999, 999999
        v, mm, cc, fc = Decimal(v1), Decimal(m), Decimal(c), Decimal(f_c)
        t = mm * v / fc if c == 0.0 else (mm / cc) * (1 + cc * v / fc).ln()
        dx, _ = _segment(Decimal(0), v, -fc, t, mm, cc)
        return x1 + float(dx)


@given(pulse())
@SETTINGS
def test_pulse_model_and_its_inverses_are_exact_over_the_accepted_ranges(args) -> None:
    f_p, t_p, m, f_c, c = args
    d = pulse_displacement(f_p, t_p, m, f_c, c)
    want = reference_pulse(f_p, t_p, m, f_c, c)
    if math.isinf(want):
        assert d == want
        return
    assert math.isfinite(d) and d >= 0.0
    assert abs(d - want) <= 1e-9 * want + 1e-300, (d, want)
    if d > 0.0 and math.isfinite(d):
        width = pulse_width(d, f_p, m, f_c, c)
        assert math.isfinite(width)
        assert abs(pulse_displacement(f_p, width, m, f_c, c) - d) <= 1e-9 * d
        height = pulse_amplitude(d, t_p, m, f_c, c, max(f_c, 1e-9), f_p)
        assert f_c <= height <= f_p
        assert abs(pulse_displacement(height, t_p, m, f_c, c) - d) <= 1e-6 * d


# --- closed loops of every kind over accepted scenarios --------------------------------------


def setting(draw, name: str):
    return draw(in_range(SETTINGS_BY_NAME[name]))


@st.composite
def accepted_scenario(draw):
    T = draw(in_range(MANEUVER["T"]))
    f_c = draw(in_range(PLANT["f_c"]))
    plant = {"m": draw(in_range(PLANT["m"])), "f_c": f_c,
             "f_s": max(f_c, min(f_c * draw(magnitude(1.0, 100.0)), PLANT["f_s"].max)),
             "c": draw(in_range(PLANT["c"])),
             "x_resolution": draw(st.one_of(st.just(0.0), magnitude(
                 OFF_OR_AT_LEAST["x_resolution"], PLANT["x_resolution"].max)))}
    maneuver = {"x_ref": draw(signed(in_range(MANEUVER["x_ref"]))), "T": T,
                "duration": T * draw(st.integers(1, 150)), "iterations": draw(st.integers(1, 2)),
                "timing": draw(st.sampled_from(["immediate", "delayed"])),
                "noise_std": draw(st.one_of(st.just(0.0), in_range(MANEUVER["noise_std"]))),
                "noise_seed": draw(st.integers(0, 5))}
    controllers = []
    for kind in ("pwc", "papwc", "exact"):
        f_p_max = setting(draw, "f_p_max")
        tolerance = draw(st.one_of(st.just(0.0), in_range(SETTINGS_BY_NAME["tolerance"])))
        table = {
            "kind": kind, "f_p_max": f_p_max,
            "t_p_max": draw(st.one_of(st.just(math.inf), magnitude(
                T, max(T, SETTINGS_BY_NAME["t_p_max"].max)))),
            "K_c": draw(st.floats(0.01, 1.99)), "tolerance": tolerance,
            "m_est": setting(draw, "m_est"),
            "f_c_est": max(f_p_max * draw(st.floats(1e-6, 0.999)),
                           SETTINGS_BY_NAME["f_c_est"].min),
            "e_band": max(setting(draw, "e_band"), 2.0 * tolerance + 1e-12),
            "rest_band": draw(st.one_of(st.just(0.0), in_range(SETTINGS_BY_NAME["rest_band"]))),
            "rest_samples": draw(st.integers(1, 3)),
        }
        if table["f_c_est"] >= f_p_max:
            table["f_p_max"] = table["f_c_est"] * 2.0
        if draw(st.booleans()):
            table["k_p"] = setting(draw, "k_p")
            table["k_d"] = setting(draw, "k_d")
        if kind == "pwc":
            table["F_inv0"] = setting(draw, "F_inv0")
        elif kind == "papwc":
            table["delta_inv"] = setting(draw, "delta_inv")
        else:
            table.update(c_est=setting(draw, "c_est"), history=draw(st.integers(1, 20)),
                         max_pulses=draw(st.integers(1, 30)),
                         x_resolution=plant["x_resolution"])
        controllers.append(table)
    return {"name": "fuzz", "plant": plant, "maneuver": maneuver, "controller": controllers}


@given(accepted_scenario())
@settings(max_examples=max(1, EXAMPLES // 2), deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
def test_every_accepted_scenario_runs_without_exception_or_nan(data) -> None:
    scenario = parse_scenario(data, "fuzz.toml")  # accepted: raises otherwise
    for result, settings_ in zip(run_scenario(scenario, "physics"), scenario.controllers,
                                 strict=True):
        assert not result.error, result.error
        for trace in result.traces:
            for name in ("x", "v", "x_meas", "e", "b_hat", "f_c_hat"):
                assert all(math.isfinite(q) for q in trace.column(name)), name
            forces = trace.column("u")[:-1]
            assert all(math.isfinite(f) and abs(f) <= settings_.f_p_max for f in forces)
