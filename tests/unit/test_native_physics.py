"""The C plant (fmu_src/FrictionPlant/plant.c) against the model layer, step for step.

The C plant is compiled for this machine (tests/native_lib.py: the system ``cc``,
``-O2 -ffp-contract=off``) and stepped beside :class:`papwc.model.dynamics.Plant`
over random force and step-size sequences (hypothesis, derandomized). After every
step the whole state (position, velocity, bristle and drive states, applied force,
breakaway force in effect, draw counters, encoder noise, the integrator's step
proposal), the outputs and any refusal are compared.

Tolerance: none. Both compute with IEEE doubles in the same operation order and call
the same C library for exp, log, sin, pow, ..., so the C plant is equal to the model
layer bit for bit (``float.hex``), with no deviation (the closed form of Eq. (1)),
with each deviation (the same RODAS4 steps, event locations and counter-based
draws) and with all of them at once; a state copied mid-run continues exactly as
the model layer's restored state does.

The rules between parameters: ``fp_check`` accepts and refuses the parameter sets that
:func:`papwc.model.plant.plant_problems` accepts and refuses, with its first message word
for word, over sets drawn at the ends of the ranges and on or one double beside each rule's
boundary (every rule of PLANT_CONSTRAINTS is reached), and the rules' data in
``plant_vars.h`` are the model layer's tables.
"""

from __future__ import annotations

import math
import random
import re
import sys
from pathlib import Path
from typing import Any

import pytest
from harness import REALISM_VARIANTS, inside_max, random_forces
from hypothesis import given, settings
from hypothesis import strategies as st

from papwc.fmubuild.native_tables import plant_header, value_references
from papwc.model.dynamics import STATE_FIELDS, Plant
from papwc.model.plant import (
    ACCELERATION_MAX,
    DAMPING_RATE_MAX,
    INTEGRATED,
    INTEGRATED_OFF_OR_AT_LEAST,
    MODE_FREQUENCY_MAX,
    OFF_OR_AT_LEAST,
    PLANT_CONSTRAINTS,
    PLANT_DEFAULTS,
    PLANT_OUTPUTS,
    PLANT_PARAMETERS,
    PLANT_VARIABLES,
    plant_problems,
)

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from native_lib import NativeLibrary, NativePlant, build_plant_library, compiler  # noqa: E402

pytestmark = pytest.mark.skipif(
    compiler() is None,
    reason="no C compiler (cc, gcc, clang or the ziglang package) to build "
           "fmu_src/FrictionPlant/plant.c")

#: Hypothesis settings of every property here: reproducible, bounded.
SETTINGS = settings(derandomize=True, deadline=None, database=None)


@pytest.fixture(scope="module")
def native(tmp_path_factory: pytest.TempPathFactory) -> NativeLibrary:
    return NativeLibrary(build_plant_library(tmp_path_factory.mktemp("native_plant")))


def bits(value: float | int | bool) -> str:
    """A value as its exact bits (so 0.0 and -0.0 differ)."""
    return value.hex() if isinstance(value, float) else repr(value)


def python_view(plant: Plant) -> dict[str, str]:
    """State fields and outputs of the model layer's plant, as bits."""
    out = {name: bits(value) for name, value in plant.state().items()}
    out.update(x_meas=bits(plant.x_meas()), stuck=bits(plant.v == 0.0),
               x_d_out=bits(plant.x_d_now()), x_d_meas=bits(plant.x_d_meas()))
    return out


def native_view(plant: NativePlant) -> dict[str, str]:
    """The same of the C plant."""
    out = {name: bits(value) for name, value in plant.fields().items()}
    y = plant.outputs()
    assert (y.x, y.v) == (plant.state.x, plant.state.v)
    out.update(x_meas=bits(y.x_meas), stuck=bits(bool(y.stuck)), x_d_out=bits(y.x_d),
               x_d_meas=bits(y.x_d_meas))
    return out


def run_both(native: NativeLibrary, params: dict[str, Any],
             steps: list[tuple[float, float]], copy_at: int) -> None:
    """Step both plants through ``steps``; equal after each; a state copied at ``copy_at``
    continues in a new C plant exactly as the model layer's restored state does."""
    py = Plant(params)
    c = NativePlant(native, params)
    assert native_view(c) == python_view(py)
    saved_py = saved_c = None
    tail: list[dict[str, str]] = []
    for k, (u, h) in enumerate(steps):
        if k == copy_at:
            saved_py, saved_c = py.state(), c.copy_state()
        reason_py, reason_c = py.step(u, h), c.step(u, h)
        assert reason_c == reason_py, (k, u, h)
        view = python_view(py)
        assert native_view(c) == view, (k, u, h)
        if saved_c is not None:
            tail.append(view)
    if saved_c is None:
        return
    py.set_state(saved_py)
    other = NativePlant(native, params)
    other.step(1.0e3, 0.5)  # somewhere else entirely, then the copy over it
    other.set_state(saved_c)
    for (u, h), view in zip(steps[copy_at:], tail, strict=True):
        assert other.step(u, h) == py.step(u, h)
        assert native_view(other) == python_view(py) == view


@pytest.mark.parametrize("params", [
    {},
    {"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3, "seed": 3, "noise_std": 2e-7,
     "x_resolution": 1e-7, "x_d_noise_std": 1e-7, "x_d_resolution": 1e-7},
], ids=["eq1", "flexible_noisy"])
def test_every_output_of_the_model_layer_is_the_c_plants_by_name(
        native: NativeLibrary, params: dict[str, Any]) -> None:
    """Plant.outputs() (papwc.model.dynamics.OUTPUTS, by the names of PLANT_OUTPUTS) is the
    C plant's FpOutputs field for field, bit for bit, at every communication point."""
    py = Plant(params)
    c = NativePlant(native, params)
    rng = random.Random(7)

    def c_outputs() -> dict[str, str]:
        y = c.outputs()
        return {v.name: bits(bool(getattr(y, v.name)) if v.type == "Boolean"
                             else getattr(y, v.name)) for v in PLANT_OUTPUTS}

    assert list(py.outputs()) == [v.name for v in PLANT_OUTPUTS]
    for k in range(80):
        assert c_outputs() == {name: bits(value) for name, value in py.outputs().items()}, k
        u = rng.choice([0.0, 90.0, -140.0, 160.0, 300.0])
        assert py.step(u, 0.01) is None and c.step(u, 0.01) is None


# --- the generated header -------------------------------------------------------------------------


def test_header_numbers_the_variables_as_the_model_description() -> None:
    text = plant_header()
    entries = re.findall(r"X\((\w+), (\d+), (FP_\w+)", text)
    assert [(name, int(vr)) for name, vr, _ in entries] == [
        (v.name, i) for i, v in enumerate(PLANT_VARIABLES)]
    assert value_references() == {v.name: i for i, v in enumerate(PLANT_VARIABLES)}
    kinds = {"Real": "FP_REAL", "Integer": "FP_INTEGER", "Boolean": "FP_BOOLEAN"}
    assert [kind for _, _, kind in entries] == [kinds[v.type] for v in PLANT_VARIABLES]
    assert f"#define FP_N_VARIABLES {len(PLANT_VARIABLES)}" in text


def test_header_starts_and_ranges_are_the_model_layers(native: NativeLibrary) -> None:
    text = plant_header()
    for var in PLANT_PARAMETERS:
        row = re.search(rf"X\({var.name}, \d+, FP_\w+, ([^,]+), ([^,]+), ([^,]+), (\d), (\d)\)",
                        text)
        assert row is not None, var.name
        start, lo, hi, lo_open, hi_open = row.groups()

        def number(text: str) -> float:
            return float(text.strip("()").replace("INFINITY", "inf"))

        assert number(start) == var.default
        assert number(lo) == (-math.inf if var.min is None else var.min)
        assert number(hi) == (math.inf if var.max is None else var.max)
        assert (bool(int(lo_open)), bool(int(hi_open))) == (var.min_open, var.max_open)
    assert tuple(NativePlant(native, {}).fields()) == STATE_FIELDS
    defaults = native.params()
    assert {v.name: getattr(defaults, v.name) for v in PLANT_PARAMETERS} == PLANT_DEFAULTS


# --- Eq. (1): no deviation ------------------------------------------------------------------------

forces = st.one_of(st.just(0.0), st.floats(-1000.0, 1000.0), st.floats(-140.0, 140.0))
step_sizes = st.one_of(st.just(0.01), st.floats(1e-5, 0.1))


@st.composite
def eq1_params(draw: st.DrawFn) -> dict[str, float]:
    f_c = draw(st.floats(0.0, 500.0))
    return {
        "m": draw(st.floats(1e-3, 1e4)),
        "f_c": f_c,
        "f_s": f_c + draw(st.floats(0.0, 300.0)),
        "c": draw(st.floats(0.0, 5000.0)),
        "x0": draw(st.floats(-1.0, 1.0)),
        "v0": draw(st.one_of(st.just(0.0), st.floats(-1.0, 1.0))),
        "x_resolution": draw(st.sampled_from((0.0, 1e-9, 1e-6, 3.3e-5))),
    }


@SETTINGS
@given(params=eq1_params(), steps=st.lists(st.tuples(forces, step_sizes), min_size=1,
                                           max_size=60), copy_at=st.integers(0, 60))
def test_eq1_is_the_model_layer_bit_for_bit(native: NativeLibrary, params: dict[str, float],
                                            steps: list[tuple[float, float]],
                                            copy_at: int) -> None:
    assert Plant(params).is_eq1
    run_both(native, params, steps, copy_at)


@pytest.mark.parametrize("params", [
    {"x0": -0.0, "x_resolution": 1e-9},
    {"x0": -0.0, "v0": -0.0, "x_resolution": 1e-6, "f_c": 0.0, "f_s": 0.0, "c": 0.0},
    {"x0": -4e-10, "x_resolution": 1e-9, "noise_std": 1e-12},
])
def test_signed_zeros_are_read_as_the_model_layer_reads_them(
        native: NativeLibrary, params: dict[str, float]) -> None:
    """math.floor gives an integer: the encoder's count of -0.0 is 0, with no sign."""
    run_both(native, params, [(0.0, 0.01), (-0.0, 0.01), (1e-300, 0.01)], 1)


@pytest.mark.parametrize("u, h", [(math.nan, 0.01), (math.inf, 0.01), (-math.inf, 0.01),
                                  (10.0, 0.0), (10.0, -0.01), (10.0, math.inf),
                                  (10.0, math.nan)])
@pytest.mark.parametrize("params", [{}, {"v_s": 1e-3, "tau_u": 2e-3}])
def test_a_bad_input_or_step_is_refused_and_the_state_kept(
        native: NativeLibrary, params: dict[str, float], u: float, h: float) -> None:
    plant = NativePlant(native, params)
    assert plant.step(200.0, 0.01) is None
    before = native_view(plant)
    reason = plant.step(u, h)
    assert reason is not None
    assert (f"input u = {u!r} N is not finite" if not math.isfinite(u)
            else f"step size {h!r} s must be finite and > 0") == reason
    assert native_view(plant) == before


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("field", [f for f in STATE_FIELDS if not f.endswith("_draws")])
def test_a_state_with_a_field_not_finite_is_refused_as_set_state_does(
        native: NativeLibrary, field: str, value: float) -> None:
    plant = NativePlant(native, {"v_s": 1e-3})
    assert plant.step(200.0, 0.01) is None
    assert native.state_check(plant.state) is None
    state = plant.copy_state()
    setattr(state, field, value)
    py = Plant({"v_s": 1e-3})
    with pytest.raises(ValueError) as refused:
        py.set_state({**py.state(), field: value})
    assert native.state_check(state) == str(refused.value)


def test_a_step_the_model_layer_refuses_is_refused(native: NativeLibrary) -> None:
    params = {"m": 1e-6, "c": 1e9}
    py, c = Plant(params), NativePlant(native, params)
    assert py.step(500.0, 1e300) == c.step(500.0, 1e300) == "the result would not be finite"
    assert native_view(c) == python_view(py)


# --- the deviations -------------------------------------------------------------------------------

TWO_PI = 2.0 * math.pi


@st.composite
def base_params(draw: st.DrawFn) -> dict[str, float]:
    f_c = draw(st.floats(20.0, 150.0))
    return {"m": draw(st.floats(50.0, 300.0)), "f_c": f_c,
            "f_s": f_c * draw(st.floats(1.0, 1.6)),
            "c": draw(st.one_of(st.just(0.0), st.floats(1e-3, 900.0)))}


def stribeck(draw: st.DrawFn) -> dict[str, float]:
    return {"v_s": draw(st.floats(1e-4, 1e-2)),
            "delta_s": draw(st.one_of(st.just(1.0), st.just(2.0), st.floats(1.0, 4.0)))}


def lugre(draw: st.DrawFn, m: float) -> dict[str, float]:
    # Stiff bristles cost the model layer many steps: at most a 2 kHz pre-sliding mode here
    # (and at most the model layer's MODE_FREQUENCY_MAX).
    # (often at that bound, less its margin: sqrt(sigma_0/m) computed back can exceed it)
    top = inside_max(min(2000.0, MODE_FREQUENCY_MAX))
    sigma_0 = m * (TWO_PI * draw(st.one_of(st.just(top), st.floats(50.0, top)))) ** 2
    return {"sigma_0": sigma_0, "sigma_1": draw(st.one_of(st.just(0.0), st.floats(1e-3, 2.0)))
            * math.sqrt(sigma_0 * m)}


def ripple(draw: st.DrawFn) -> dict[str, float]:
    return {"ripple": draw(st.floats(0.01, 0.5)), "ripple_period": draw(st.floats(1e-4, 1e-2)),
            "ripple_phase": draw(st.floats(-TWO_PI, TWO_PI))}


def stiction(draw: st.DrawFn, params: dict[str, float]) -> dict[str, float]:
    spread = draw(st.floats(0.01, 0.3))
    # The lowest breakaway force f_s*(1 - spread) stays >= f_c.
    f_s = max(params["f_s"], params["f_c"] / (1.0 - spread))
    while f_s * (1.0 - spread) < params["f_c"]:
        f_s = math.nextafter(f_s, math.inf)
    return {"f_s_spread": spread, "f_s": f_s, "seed": draw(st.integers(0, 2**31 - 1))}


def noise(draw: st.DrawFn) -> dict[str, float]:
    """The table's encoder noisy or ideal, the motor encoder's likewise (not both ideal)."""
    table, motor = draw(st.sampled_from(((True, False), (False, True), (True, True))))
    return {"noise_std": draw(st.floats(1e-9, 1e-5)) if table else 0.0,
            "x_d_noise_std": draw(st.floats(1e-9, 1e-5)) if motor else 0.0,
            "seed": draw(st.integers(0, 2**31 - 1)),
            "x_resolution": draw(st.sampled_from((0.0, 1e-9, 1e-6))),
            "x_d_resolution": draw(st.sampled_from((0.0, 1e-9, 1e-6)))}


def lag(draw: st.DrawFn) -> dict[str, float]:
    return {"tau_u": draw(st.floats(1e-4, 0.05))}


def flexible(draw: st.DrawFn, m: float) -> dict[str, float]:
    m_d = draw(st.floats(5.0, 200.0))
    mode = draw(st.floats(5.0, 300.0))  # Hz, with the table free
    return {"m_d": m_d, "k_t": (TWO_PI * mode) ** 2 / (1.0 / m + 1.0 / m_d),
            # none, or at least the model layer's smallest (OFF_OR_AT_LEAST)
            "c_t": draw(st.one_of(st.just(0.0), st.floats(1e-3, 1000.0)))}


#: Deviation -> how its parameters are drawn (on top of drawn m, f_c, f_s, c).
DEVIATIONS = ("stribeck", "lugre", "ripple", "stiction", "noise", "lag", "flexible",
              "all_stick_slip", "all_lugre")


@st.composite
def deviation_params(draw: st.DrawFn, case: str) -> dict[str, float]:
    p = draw(base_params())
    if case in ("stribeck", "all_stick_slip", "all_lugre"):
        p.update(stribeck(draw))
    if case in ("lugre", "all_lugre"):
        p.update(lugre(draw, p["m"]))
    if case in ("ripple", "all_stick_slip", "all_lugre"):
        p.update(ripple(draw))
    if case in ("stiction", "all_stick_slip"):
        p.update(stiction(draw, p))
    if case in ("noise", "all_stick_slip", "all_lugre"):
        p.update(noise(draw))
    if case in ("lag", "all_stick_slip", "all_lugre"):
        p.update(lag(draw))
    if case in ("flexible", "all_stick_slip", "all_lugre"):
        p.update(flexible(draw, p["m"]))
    # A value drawn between 0 and the smallest one the model layer allows (its "0 or >= low"
    # rules) is taken at that smallest value: the deviation stays on, at its boundary.
    for name, low in {**OFF_OR_AT_LEAST, **INTEGRATED_OFF_OR_AT_LEAST}.items():
        if 0.0 < p.get(name, 0.0) < low:
            p[name] = low
    return p


@pytest.mark.parametrize("case", DEVIATIONS)
def test_the_deviation_strategy_draws_inside_the_bounds(case: str) -> None:
    """Issue 44: a strategy draws inside the bounds it derives (a margin on each), so that
    the properties below test valid plants only."""
    @settings(SETTINGS, max_examples=300)
    @given(params=deviation_params(case))
    def check(params: dict[str, float]) -> None:
        assert plant_problems(params) == []

    check()


#: A force held over 1 to 4 steps: a pulse beyond breakaway, a rest, or a force below it.
held_forces = st.tuples(
    st.one_of(st.floats(-400.0, 400.0), st.just(0.0), st.floats(-140.0, 140.0)),
    st.one_of(st.just(0.01), st.floats(1e-4, 0.03)),
    st.integers(1, 4))


@pytest.mark.parametrize("case", [
    # the combined and the flexible cases integrate the most (seconds each)
    pytest.param(case, marks=pytest.mark.slow) if case in ("all_stick_slip", "all_lugre",
                                                           "flexible", "lugre") else case
    for case in DEVIATIONS])
def test_deviation_is_the_model_layer_bit_for_bit(native: NativeLibrary, case: str) -> None:
    @settings(SETTINGS, max_examples=12)
    @given(params=deviation_params(case), held=st.lists(held_forces, min_size=1, max_size=12),
           copy_at=st.integers(0, 30))
    def check(params: dict[str, float], held: list[tuple[float, float, int]],
              copy_at: int) -> None:
        assert not plant_problems(params), plant_problems(params)
        plant = Plant(params)
        assert not plant.is_eq1
        steps = [(u, h) for u, h, n in held for _ in range(n)]
        run_both(native, params, steps, copy_at)

    check()


#: Each deviation at the values of scenarios/realism.toml, and all together.
REALISM = {
    **REALISM_VARIANTS,
    "noise": {"noise_std": 2e-7, "seed": 5, "x_resolution": 1e-7},
    "all": {**REALISM_VARIANTS["all"], "noise_std": 1e-7},
    "motor_encoder": {"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3, "seed": 4,
                      "x_resolution": 1e-7, "x_d_resolution": 1e-7, "x_d_noise_std": 5e-8},
    "motor_encoder_rigid": {"x_d_noise_std": 2e-7, "seed": 6, "x_d_resolution": 1e-7},
}


@pytest.mark.parametrize("case", sorted(REALISM))
def test_realism_run_is_the_model_layer_bit_for_bit(native: NativeLibrary, case: str) -> None:
    """A long run per deviation that sticks, breaks away and slides many times."""
    params = REALISM[case]
    n = 150
    steps = [(u, 0.01) for u in random_forces(len(case), n)]
    run_both(native, params, steps, n // 2)
    plant = NativePlant(native, params)
    stuck = moved = 0
    for u, h in steps:
        assert plant.step(u, h) is None
        stuck += plant.state.v == 0.0
        moved += plant.state.v != 0.0
    # The run exercises both regimes (with LuGre the mass creeps instead of sticking).
    assert moved > 10 and (stuck > 10 or "sigma_0" in params), (stuck, moved)
    if "f_s_spread" in params:
        assert plant.state.stick_draws > 5
    if "noise_std" in params or "x_d_noise_std" in params:
        assert plant.state.noise_draws == n + 1


# --- the rules between parameters -----------------------------------------------------------------


#: The smallest value other than 0 of each parameter that has one (the "0 or >= low" rules).
LOWEST = {**OFF_OR_AT_LEAST, **INTEGRATED_OFF_OR_AT_LEAST}
BY_NAME = {var.name: var for var in PLANT_PARAMETERS}


def edges(var: Any) -> st.SearchStrategy[float]:
    """A parameter's value at or next to the ends of its range, its default or within, at or
    next to its smallest value other than 0 (:data:`LOWEST`), or the smallest double."""
    if var.type == "Integer":
        return st.sampled_from((var.min, var.max, var.default)).map(int)
    lo, hi = var.min, var.max
    values = [var.default, lo, math.nextafter(lo, math.inf), math.nextafter(hi, -math.inf),
              0.5 * (lo + hi), lo + 1e-3 * (hi - lo)]
    if not var.max_open:
        values.append(hi)
    if var.min_open:
        values.remove(lo)
    if var.name in LOWEST:
        low = LOWEST[var.name]
        values += [low, math.nextafter(low, math.inf), math.nextafter(low, -math.inf),
                   0.5 * low, 5e-324]
    return st.one_of(st.sampled_from(values), st.floats(lo, hi, exclude_max=var.max_open))


def near(value: float, draw: st.DrawFn) -> float:
    """``value`` or a float next to it."""
    return draw(st.sampled_from((value, math.nextafter(value, math.inf),
                                 math.nextafter(value, -math.inf))))


#: What :func:`parameter_sets` puts on or next to a boundary: a rule of PLANT_CONSTRAINTS.
RULES = ("none", "f_s", "off", "integrated_off", "acceleration", "damping", "coupling",
         "spread", "lugre", "random_lugre", "presliding", "flexible")


@st.composite
def parameter_sets(draw: st.DrawFn) -> dict[str, float]:
    """Parameters each valid on its own, often on the boundary of a rule between them."""
    # Each parameter at its default half of the time, so that every rule is reached.
    p = {var.name: draw(st.one_of(st.just(var.default), edges(var))) for var in PLANT_PARAMETERS}
    # ("off" drawn five times as often: it has a rule for each of its dozen parameters.)
    rule = draw(st.sampled_from(RULES + ("off",) * 4))
    if rule in ("integrated_off", "acceleration", "damping") and draw(st.integers(0, 3)):
        # An integrated deviation on (at or above its smallest value), so that these apply.
        name = draw(st.sampled_from(INTEGRATED))
        p[name] = max(p[name], LOWEST.get(name, 5e-324))
    if draw(st.integers(0, 3)):
        # The rules before this one in PLANT_CONSTRAINTS made to hold, so that it is reached
        # (else several are violated at once and the first is the one named).
        if rule in ("presliding", "flexible", "none"):
            if p["sigma_0"] > 0.0:
                p["f_c"], p["f_s_spread"] = max(p["f_c"], 1.0), 0.0
            if p["f_s"] * (1.0 - p["f_s_spread"]) < p["f_c"]:
                p["f_s_spread"] = 0.0
            if p["m_d"] > 0.0 and not p["k_t"] > 0.0:
                p["k_t"] = 1.0
        if rule == "presliding":  # a mass light enough for a pre-sliding mode at the bound
            p["f_c"], p["f_s"], p["c"] = min(p["f_c"], 1e3), min(p["f_s"], 1e3), min(p["c"], 1e3)
            p["m"] = min(p["m"], draw(st.floats(1e-6, 250.0)))
        if rule != "f_s":
            p["f_s"] = max(p["f_s"], p["f_c"])
        for name, low in LOWEST.items():
            if 0.0 < p[name] < low:
                p[name] = draw(st.sampled_from((0.0, low)))
        if rule not in ("acceleration", "damping"):
            p["m"] = max(p["m"], p["f_s"] / ACCELERATION_MAX, p["c"] / DAMPING_RATE_MAX)
        if rule != "coupling" and p["m_d"] > 0.0:
            p["c_t"] = min(p["c_t"], 0.5 * DAMPING_RATE_MAX / (1.0 / p["m"] + 1.0 / p["m_d"]))
    if rule in ("lugre", "random_lugre"):
        p["sigma_0"] = max(p["sigma_0"], LOWEST["sigma_0"])
    if rule == "lugre":
        p["f_c"] = draw(st.sampled_from((0.0, 5e-324, LOWEST["f_c"])))
    elif rule == "random_lugre":
        p["f_s_spread"] = max(p["f_s_spread"], LOWEST["f_s_spread"])
        p["f_c"] = min(p["f_c"], p["f_s"] * (1.0 - p["f_s_spread"]))
    if rule == "f_s":
        p["f_s"] = near(p["f_c"], draw)
    elif rule in ("off", "integrated_off"):
        table = OFF_OR_AT_LEAST if rule == "off" else INTEGRATED_OFF_OR_AT_LEAST
        name = draw(st.sampled_from(sorted(table)))
        p[name] = draw(st.sampled_from((5e-324, 0.5 * table[name], 0.0))) if draw(
            st.booleans()) else near(table[name], draw)
        if name == "f_s":
            p["f_c"] = 0.0  # (f_c > f_s or a tiny f_c would be refused first)
    elif rule == "acceleration":
        if draw(st.booleans()):
            p["f_s"] = near(p["m"] * ACCELERATION_MAX, draw)
        else:
            p["m"] = near(p["f_s"] / ACCELERATION_MAX, draw)
    elif rule == "damping":
        if draw(st.booleans()):
            p["c"] = near(p["m"] * DAMPING_RATE_MAX, draw)
        else:
            p["m"] = near(p["c"] / DAMPING_RATE_MAX, draw)
    elif rule == "coupling":
        p["m_d"] = max(p["m_d"], LOWEST["m_d"])
        p["c_t"] = near(DAMPING_RATE_MAX / (1.0 / p["m"] + 1.0 / p["m_d"]), draw)
    elif rule == "spread" and p["f_s_spread"] > 0.0:
        p["f_c"] = near(p["f_s"] * (1.0 - p["f_s_spread"]), draw)
    elif rule == "presliding":
        p["sigma_0"] = near(p["m"] * (2.0 * math.pi * MODE_FREQUENCY_MAX) ** 2, draw)
    elif rule == "flexible" and p["m_d"] > 0.0:
        p["k_t"] = near((2.0 * math.pi * MODE_FREQUENCY_MAX) ** 2
                        / (1.0 / p["m"] + 1.0 / p["m_d"]), draw)
    return {name: value for name, value in p.items() if BY_NAME[name].check(value) is None}


@pytest.mark.slow
def test_check_accepts_and_refuses_as_the_model_layer(native: NativeLibrary) -> None:
    """fp_check and plant_problems agree on every drawn set (the first refusal, word for
    word); among the sets drawn, each rule of PLANT_CONSTRAINTS is the first to refuse."""
    first: set[int | None] = set()

    @settings(SETTINGS, max_examples=1000)
    @given(values=parameter_sets())
    def check(values: dict[str, float]) -> None:
        full = {**PLANT_DEFAULTS, **values}
        found = plant_problems(full)
        assert native.check(full) == (found[0][1] if found else None)
        assert not found or len(found[0][1].encode()) < 300  # (plant.h: msg of 512 holds it)
        first.add(next((i for i, rule in enumerate(PLANT_CONSTRAINTS)
                        if rule.check(full) is not None), None))

    check()
    assert set(range(len(PLANT_CONSTRAINTS))) <= first, (
        "rules never reached by parameter_sets: "
        f"{sorted(set(range(len(PLANT_CONSTRAINTS))) - first)}")


#: An integrated deviation on, per deviation of INTEGRATED (with what it needs).
ON = {"v_s": {"v_s": 1e-3}, "sigma_0": {"sigma_0": 1e4, "sigma_1": 1e3}, "ripple": {"ripple": 0.1},
      "tau_u": {"tau_u": 2e-3}, "m_d": {"m_d": 50.0, "k_t": 1e5}}


def below(x: float) -> float:
    """The double just under ``x``."""
    return math.nextafter(x, -math.inf)


def above(x: float) -> float:
    """The double just over ``x``."""
    return math.nextafter(x, math.inf)


def _cases() -> list[tuple[dict[str, float], str | None]]:
    """Parameter sets (over the defaults) at and around each rule's boundary, each with the
    parameter the model layer names first (None: accepted)."""
    out: list[tuple[dict[str, float], str | None]] = [
        ({}, None),
        ({"f_c": 140.0}, "f_s"),
        ({"f_s": below(100.0)}, "f_s"),
        ({"f_s": 100.0}, None),
    ]
    for name, low in OFF_OR_AT_LEAST.items():
        extra = {"k_t": 1.0} if name == "m_d" else {}
        out += [({name: below(low), **extra}, name), ({name: 5e-324, **extra}, name),
                ({name: low, **extra}, None)]
    for name, low in INTEGRATED_OFF_OR_AT_LEAST.items():
        extra = {"f_c": 0.0} if name == "f_s" else {}
        out += [({name: below(low), **extra}, None),  # Eq. (1) alone: no bound
                ({name: below(low), **extra, **ON["v_s"], **ON["ripple"]}, name),
                ({name: low, **extra, **ON["tau_u"]}, None)]
        out += [({name: 1e-300, **extra, **on}, name) for on in ON.values()]
    for on in ON.values():
        m = 130.0 / ACCELERATION_MAX
        out += [({"m": m, "c": 0.0, **on}, None), ({"m": below(m), "c": 0.0, **on}, "m"),
                ({"m": 1e-6, "f_s": 1e9, "f_c": 1.0, **on}, "m"),
                ({"c": 150.0 * DAMPING_RATE_MAX, **on}, None),
                ({"c": above(150.0 * DAMPING_RATE_MAX), **on}, "c"),
                ({"c": 1e9, "m": 1e-6, "f_s": 1e-3, "f_c": 1e-3, **on}, "c")]
    out += [({"m": 1e-6, "f_s": 1e9}, None), ({"c": 1e9, "m": 1e-6}, None)]  # Eq. (1) alone
    rate = DAMPING_RATE_MAX / (1.0 / 150.0 + 1.0 / 50.0)
    out += [({**ON["m_d"], "c_t": rate}, None),
            ({**ON["m_d"], "c_t": above(rate)}, "c_t"),
            ({"m_d": 1e-3, "k_t": 1e-12, "c_t": 999e6}, "c_t"),
            ({"f_s_spread": 0.5}, "f_s_spread"),
            ({"sigma_0": 1e6, "f_c": 0.0, "f_s": 0.0}, "sigma_0"),
            ({"sigma_0": 1e6, "f_s_spread": 0.1, "f_c": 50.0}, "f_s_spread"),
            ({"m_d": 10.0}, "k_t"),
            ({"sigma_0": 1e12, "m": 1.0}, "sigma_0"),
            ({"m_d": 1e-3, "k_t": 1e12}, "k_t")]
    return out


CASES = _cases()


@pytest.mark.parametrize(("values", "name"), CASES)
def test_each_rule_is_refused_with_the_model_layers_words(
        native: NativeLibrary, values: dict[str, float], name: str | None) -> None:
    full = {**PLANT_DEFAULTS, **values}
    assert all(BY_NAME[n].check(v) is None for n, v in values.items()), values
    found = plant_problems(full)
    assert (found[0][0] if found else None) == name, found
    assert native.check(full) == (found[0][1] if found else None)


def test_the_cases_reach_every_rule_of_the_model_layer() -> None:
    """Each rule of PLANT_CONSTRAINTS (each off-or-at-least entry its own) is the first to
    refuse in some case above: a rule added to the model layer fails here until the C plant
    and a case have it."""
    first = set()
    for values, _ in CASES:
        full = {**PLANT_DEFAULTS, **values}
        first |= {next((i for i, rule in enumerate(PLANT_CONSTRAINTS)
                        if rule.check(full) is not None), None)}
    assert first - {None} == set(range(len(PLANT_CONSTRAINTS)))


def test_header_rule_tables_are_the_model_layers() -> None:
    text = plant_header()

    def table(macro: str) -> list[tuple[str, ...]]:
        body = re.search(rf"#define {macro}\(X\) \\\n((?:    X\(.*\)(?: \\)?\n)+)", text)
        assert body is not None, macro
        return [tuple(part.strip() for part in row.split(", "))
                for row in re.findall(r"X\((.*?)\)(?: \\)?\n", body.group(1))]

    for macro, model in (("FP_OFF_OR_AT_LEAST", OFF_OR_AT_LEAST),
                         ("FP_INTEGRATED_OFF_OR_AT_LEAST", INTEGRATED_OFF_OR_AT_LEAST)):
        rows = table(macro)
        assert [(n, float(low), g.strip('"'), unit.strip('"')) for n, low, g, unit in rows] == [
            (n, low, f"{low:g}", BY_NAME[n].unit_suffix) for n, low in model.items()]
    assert [row[0] for row in table("FP_INTEGRATED")] == list(INTEGRATED)
    for name, value in (("MODE_FREQUENCY_MAX", MODE_FREQUENCY_MAX),
                        ("DAMPING_RATE_MAX", DAMPING_RATE_MAX),
                        ("ACCELERATION_MAX", ACCELERATION_MAX)):
        assert f"#define FP_{name} {float(value)!r}\n" in text
        assert f'#define FP_{name}_TEXT "{value:g}"\n' in text


@pytest.mark.parametrize("case", sorted(REALISM))
def test_tiny_steps_are_refused_or_taken_as_the_model_layer_does(native: NativeLibrary,
                                                                 case: str) -> None:
    """Step sizes down to the smallest double: the integrator's step of h/8 divides by 0."""
    steps = [(200.0, 0.01), (200.0, 5e-324), (200.0, 1e-310), (0.0, 1e-300), (150.0, 1e-12),
             (200.0, 0.003), (-300.0, 5e-324), (0.0, 0.01), (100.0, 1e-320), (300.0, 2e-323),
             (300.0, 0.01)]
    run_both(native, REALISM[case], steps, 3)
    py = Plant(REALISM[case])
    reasons = {py.step(u, h) for u, h in steps}
    assert reasons == ({None} if py.exact else
                       {None, "float division by zero",
                        "the integrator's step size fell below 0.0 s"})


@settings(SETTINGS, max_examples=300)
@given(f_s=st.one_of(
    st.floats(0.0, 1e9, exclude_max=True),
    st.sampled_from((2.0**-24, 5e-324, 2.2250738585072014e-308, 1e-5, 0.0001, 1e-4 * 3,
                     123456789.0, 0.1, 1e-7, 9.999999999999999e-05, 1e8 + 0.5,
                     999999999.9999999))))
def test_values_in_messages_are_written_as_pythons_repr(native: NativeLibrary,
                                                        f_s: float) -> None:
    """The rule f_s >= f_c refused for f_s below f_c = 1e9 N: the message holds repr(f_s)."""
    assert native.check({"f_s": f_s, "f_c": 1e9}) == (
        f"f_s = {f_s!r} N: must be >= f_c = 1000000000.0 N")


@settings(SETTINGS, max_examples=300)
@given(c=st.one_of(
    st.floats(1e4, 1e9, exclude_min=True),
    st.sampled_from((10000.25, 10000.75, 123456.5, 1234565.0, 1234575.0, 999999.5, 9999995.0,
                     99999.95, 100000.0, 1e6, 1e9, math.nextafter(1e4, math.inf)))))
def test_values_in_messages_are_written_as_pythons_format_6g(native: NativeLibrary,
                                                             c: float) -> None:
    """The damping rule refused for m = 1 kg: the message holds format(c/m, ".6g") = c's."""
    values = {**PLANT_DEFAULTS, "m": 1.0, "c": c, "tau_u": 1e-3}
    found = plant_problems(values)
    assert f"c/m = {c:.6g} 1/s" in found[0][1]
    assert native.check(values) == found[0][1]


#: Forces of :func:`test_accepted_edge_plants_step_as_the_model_layer`, in units of
#: max(f_s, m * 1 m/s^2): push, hold, release, reverse, nudge.
EDGE_FORCES = (0.0, 1.5, 1.5, 0.0, -3.0, 0.0, 0.5, 0.0)


@pytest.mark.slow
def test_accepted_edge_plants_step_as_the_model_layer(native: NativeLibrary) -> None:
    """The plants the rules accept at the edges of the ranges and beside the rules' boundaries
    (:func:`parameter_sets`: smallest values other than 0, largest accelerations and damping
    rates, stiffest modes) step bit for bit as the model layer, refusals included."""
    accepted = 0

    @settings(SETTINGS, max_examples=200)
    @given(values=parameter_sets(), h=st.sampled_from((0.01, 1e-3)), copy_at=st.integers(0, 8))
    def check(values: dict[str, float], h: float, copy_at: int) -> None:
        nonlocal accepted
        full = {**PLANT_DEFAULTS, **values}
        if plant_problems(full):
            return
        accepted += 1
        scale = max(full["f_s"], full["m"] * 1.0)
        run_both(native, full, [(factor * scale, h) for factor in EDGE_FORCES], copy_at)

    check()
    assert accepted >= 30, accepted  # (61 of the 200 sets drawn)
