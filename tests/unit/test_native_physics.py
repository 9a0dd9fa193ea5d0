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
"""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from papwc.fmubuild.native_tables import plant_header, value_references
from papwc.model.dynamics import STATE_FIELDS, Plant
from papwc.model.plant import PLANT_DEFAULTS, PLANT_PARAMETERS, PLANT_VARIABLES

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
    out.update(x_meas=bits(plant.x_meas()), stuck=bits(plant.v == 0.0))
    return out


def native_view(plant: NativePlant) -> dict[str, str]:
    """The same of the C plant."""
    out = {name: bits(value) for name, value in plant.fields().items()}
    y = plant.outputs()
    assert (y.x, y.v) == (plant.state.x, plant.state.v)
    out.update(x_meas=bits(y.x_meas), stuck=bits(bool(y.stuck)))
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


def test_a_step_the_model_layer_refuses_is_refused(native: NativeLibrary) -> None:
    params = {"m": 1e-6, "c": 1e9}
    py, c = Plant(params), NativePlant(native, params)
    assert py.step(500.0, 1e300) == c.step(500.0, 1e300) == "the result would not be finite"
    assert native_view(c) == python_view(py)
