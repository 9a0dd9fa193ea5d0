"""The table's quantum computed on the native FMU's own C plant (papwc.master.native_plant).

- the binary of the native FrictionPlant.fmu gives its plant (``papwc_plant_api``, checked
  against the model layer's structs); a pythonfmu FMU, no folder or a binary of another
  layout give none, and the quantum is computed on the model layer's Plant;
- :class:`NativePlant` steps, reads and restores states as Plant does, bit for bit, with
  each deviation of scenarios/realism.toml and all of them at once;
- the table's quantum (:func:`papwc.results.quantum.table_quantum`) and so the bound of
  every pulse (``PulseBound.rows``) and the largest ratio per iteration are the same
  numbers, bit for bit, on the C plant and on Plant, on closed-loop traces with those
  deviations;
- a battery worker's record is the same with the native plant and with Plant's.
"""

from __future__ import annotations

import ctypes
import math
import random
from pathlib import Path

import pytest
from harness import DEVIATIONS, table_1

import papwc.results.quantum as quantum_module
from papwc.master.native_plant import (
    FpParams,
    NativePlant,
    NativePlantError,
    NativePlantLibrary,
    binary_path,
    plant_library,
)
from papwc.model.dynamics import Plant
from papwc.results.pulses import PulseBound
from papwc.results.quantum import table_quantum
from papwc.scenario import parse_scenario
from papwc.scenario_run import run_scenario

T = 0.01
#: The deviations of scenarios/realism.toml, and all of them that combine.
CASES = {
    "exact": {},
    **DEVIATIONS,
    "all": {"v_s": 1e-3, "ripple": 0.1, "ripple_period": 1e-3, "f_s_spread": 0.1, "seed": 5,
            "tau_u": 2e-3, "m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3,
            "noise_std": 2e-7, "x_resolution": 1e-7},
}
PLANT = table_1()


@pytest.fixture(scope="module")
def library(friction_plant_unzipped: Path) -> NativePlantLibrary:
    lib = plant_library(friction_plant_unzipped)
    assert lib is not None, f"no plant in {binary_path(friction_plant_unzipped)}"
    return lib


def _same(a: object, b: object) -> bool:
    """Equal to the last bit (repr: 0.0 and -0.0 differ, nan equals nan)."""
    return repr(a) == repr(b)


def test_only_a_native_binary_of_this_layout_gives_a_plant(
        friction_plant_unzipped: Path, pythonfmu_plant_unzipped: Path, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    assert plant_library(None) is None
    assert plant_library(tmp_path) is None  # no modelDescription.xml
    assert binary_path(pythonfmu_plant_unzipped) is not None
    assert plant_library(pythonfmu_plant_unzipped) is None  # exports no papwc_plant_api
    with pytest.raises(NativePlantError, match="exports no papwc_plant_api"):
        NativePlantLibrary(binary_path(pythonfmu_plant_unzipped))
    with pytest.raises(NativePlantError, match="cannot be loaded"):
        NativePlantLibrary(tmp_path / "missing.so")
    path = binary_path(friction_plant_unzipped)
    NativePlantLibrary(path)
    monkeypatch.setattr(FpParams, "layout", FpParams.layout.replace("f_c:", "f_k:"))
    with pytest.raises(NativePlantError, match=r"its FpParams \(.*f_c:FP_REAL.*\) is not "
                                               r"the model layer's"):
        NativePlantLibrary(path)


@pytest.mark.parametrize("case", sorted(CASES))
def test_native_plant_steps_as_plant(library: NativePlantLibrary, case: str) -> None:
    params = {**PLANT, **CASES[case]}
    ref, plant = Plant(params), NativePlant(library, params)
    assert _same(plant.state(), ref.state())
    rng = random.Random(case)
    for k in range(240):
        u = rng.choice((0.0, 0.0, rng.uniform(-300.0, 300.0), math.copysign(131.0, rng.random()
                                                                              - 0.5)))
        h = rng.choice((T, T, 1e-3, 0.0137))
        assert ref.step(u, h) is None
        assert plant.step(u, h) is None
        assert _same(plant.state(), ref.state()), (case, k)
        assert _same((plant.x, plant.v, plant.x_meas(), plant.stuck),
                     (ref.x, ref.v, ref.x_meas(), ref.v == 0.0))
        assert _same(plant._breakaway(plant.x), ref._breakaway(ref.x))
        if k % 80 == 40:  # a state handed over from Plant, and back
            other = NativePlant(library, params)
            other.set_state(ref.state())
            plant = other
            ref.set_state(plant.state())
    plant.reset()
    ref.reset()
    assert _same(plant.state(), ref.state())


def test_native_plant_refuses_as_plant(library: NativePlantLibrary) -> None:
    plant = NativePlant(library, {"tau_u": 2e-3})
    before = plant.state()
    assert plant.step(math.nan, T) == "input u = nan N is not finite"
    assert "step size 0.0 s must be finite and > 0" in plant.step(1.0, 0.0)
    assert plant.state() == before
    for bad, words in (({**before, "x": math.inf}, "x"), ({**before, "noise_draws": -1},
                                                           "noise_draws = -1 is not a count"),
                       ({**before, "v": "0"}, "v = '0' is not a number"),
                       ({"x": 0.0}, "a plant state has the fields")):
        with pytest.raises(ValueError, match=words):
            plant.set_state(bad)
        assert plant.state() == before
    assert ctypes.sizeof(plant.params) == ctypes.sizeof(FpParams)


def _traces(case: str, fmu: Path, unzipped: Path, x_ref: float) -> tuple[dict, list]:
    data = {"name": f"replay_{case}", "plant": {**PLANT, **CASES[case]},
            "maneuver": {"x_ref": x_ref, "T": T, "duration": 1.0, "iterations": 2},
            "controller": [
                {"kind": "pwc", "f_p_max": 300.0, "t_p_max": 0.03, "K_c": 0.5,
                 "tolerance": 0.0, "m_est": 150.0, "f_c_est": 80.0, "F_inv0": 1e-5},
                {"kind": "papwc", "f_p_max": 300.0, "t_p_max": 0.03, "K_c": 0.8,
                 "tolerance": 2e-5, "m_est": 150.0, "f_c_est": 80.0, "delta_inv": 1e-5}]}
    scenario = parse_scenario(data, f"test {case}")
    results = run_scenario(scenario, "fmu", fmu, unzip_dir=unzipped)
    return scenario.plant, [tr for r in results for tr in r.traces]


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_quantum_on_the_native_plant_is_plants(library: NativePlantLibrary,
                                                  case: str) -> None:
    params = {**PLANT, **CASES[case]}
    quantum_module._CACHE.clear()
    native = table_quantum(params, T, library)
    quantum_module._CACHE.clear()
    python = table_quantum(params, T)
    assert _same(native, python)
    assert python.move > 0.0


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_the_bound_on_the_native_plant_is_plants(
        library: NativePlantLibrary, friction_plant_fmu: Path, friction_plant_unzipped: Path,
        case: str) -> None:
    plant, traces = _traces(case, friction_plant_fmu, friction_plant_unzipped, 1e-3)
    quantum_module._CACHE.clear()
    native = PulseBound(plant, T, library)
    native_rows = [native.rows(trace) for trace in traces]
    native_ratios = native.ratios(traces)
    quantum_module._CACHE.clear()
    python = PulseBound(plant, T)
    rows = [python.rows(trace) for trace in traces]
    assert _same(native_rows, rows), case
    assert sum(len(r) for r in rows) >= 4  # the closed loops made pulses to bound
    assert _same(native_ratios, python.ratios(traces))


@pytest.mark.slow
def test_battery_record_is_the_same_with_the_native_plant(
        friction_plant_fmu: Path, friction_plant_unzipped: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    import papwc.master.native_plant as native_plant
    from papwc.battery.worker import execute_run

    data = {"name": "replay", "plant": {**PLANT, **CASES["all"]},
            "maneuver": {"x_ref": 5e-5, "T": T, "duration": 1.0, "iterations": 2},
            "controller": [{"kind": "papwc", "f_p_max": 300.0, "t_p_max": 0.03, "K_c": 0.8,
                            "tolerance": 2e-5, "m_est": 150.0, "f_c_est": 80.0,
                            "delta_inv": 1e-5}]}
    task = {"battery": "replay", "run_id": "r0", "run_hash": "0", "source": "test",
            "data": data}
    calls = []
    real = native_plant.plant_library

    def spy(unzip_dir):
        found = real(unzip_dir)
        calls.append(found)
        return found

    monkeypatch.setattr(native_plant, "plant_library", spy)
    quantum_module._CACHE.clear()
    with_native = execute_run(task, str(friction_plant_fmu), str(friction_plant_unzipped))
    assert calls and calls[-1] is not None
    monkeypatch.setattr(native_plant, "plant_library", lambda unzip_dir: None)
    quantum_module._CACHE.clear()
    with_plant = execute_run(task, str(friction_plant_fmu), str(friction_plant_unzipped))
    assert with_native["status"] == "ok", with_native["message"]
    assert _same(with_native["controllers"], with_plant["controllers"])
    ratios = [it["pulse_ratio"] for c in with_native["controllers"] for it in c["iterations"]]
    assert any(r > 0.0 for r in ratios)
