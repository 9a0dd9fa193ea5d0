"""FrictionPlant.fmu through fmpy: model description, exactness, bad input, state, instances."""

from __future__ import annotations

import csv
import json
import math
import random
import subprocess
import sys
from ctypes import byref
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2Discard,
    fmi2Error,
)
from fmpy.logging import addLoggerProxy
from fmpy.util import read_csv
from fmpy.validation import validate_fmu

from papwc.build.fmus import FRICTION_PLANT_UNITS, build_pythonfmu
from papwc.build.model_description import add_units
from papwc.errors import BuildError
from papwc.fmu_src.papwc_stickslip import quantize, simulate, step

PROJECT_DIR = Path(__file__).resolve().parent.parent
T = 0.01
PARAMS = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
#: Pulses above f_s both ways, coasting, a sub-stiction force, a reversal while sliding.
U_SEQ = [300.0] * 5 + [0.0] * 20 + [120.0] * 10 + [-300.0] * 5 + [0.0] * 15
U_SEQ += [250.0] * 7 + [-200.0] * 4 + [0.0] * 34
TOL = 1e-12


class Plant:
    """One FrictionPlant instance through fmpy's FMU2Slave, with its log messages kept."""

    def __init__(self, unzipdir: Path, name: str = "plant", logging: bool = True) -> None:
        self.md = read_model_description(str(unzipdir))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.messages: list[tuple[int, str, str]] = []
        self._callbacks = fmi2CallbackFunctions()
        self._logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.logger = self._logger
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(self._callbacks))
        self.fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=str(unzipdir),
            modelIdentifier="FrictionPlant",
            instanceName=name,
        )
        self.fmu.instantiate(callbacks=self._callbacks, loggingOn=logging)
        self.time = 0.0

    def _log(self, component, instance, status, category, message) -> None:
        self.messages.append(
            (status, (category or b"").decode(), (message or b"").decode())
        )

    def init(self, **start: float) -> None:
        """Set parameters, then setup experiment and initialization."""
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name, value in start.items():
            self.fmu.setReal([self.vr[name]], [value])
        self.fmu.exitInitializationMode()

    def step(self, u: float, h: float = T) -> None:
        self.fmu.setReal([self.vr["u"]], [u])
        self.fmu.doStep(self.time, h)
        self.time += h

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vr[n] for n in names])

    def stuck(self) -> bool:
        return bool(self.fmu.getBoolean([self.vr["stuck"]])[0])

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


@pytest.fixture
def plant(friction_plant_unzipped: Path):
    p = Plant(friction_plant_unzipped)
    yield p
    p.close()


# --- model description -----------------------------------------------------------------


def test_fmpy_validation_reports_no_problem(friction_plant_fmu: Path) -> None:
    assert validate_fmu(str(friction_plant_fmu)) == []


def test_fmpy_validate_cli_reports_no_problem(friction_plant_fmu: Path) -> None:
    fmpy = Path(sys.executable).with_name("fmpy")
    done = subprocess.run(
        [str(fmpy), "validate", str(friction_plant_fmu)], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "No problems found" in done.stdout


def test_model_description_contract(friction_plant_fmu: Path) -> None:
    md = read_model_description(str(friction_plant_fmu))
    assert md.coSimulation.modelIdentifier == "FrictionPlant"
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    assert md.coSimulation.canGetAndSetFMUstate
    assert md.coSimulation.canSerializeFMUstate
    units = {u.name: u for u in md.unitDefinitions}
    assert set(units) == {"kg", "N", "N.s/m", "m", "m/s"}
    assert (units["N"].baseUnit.kg, units["N"].baseUnit.m, units["N"].baseUnit.s) == (1, 1, -2)
    assert (units["N.s/m"].baseUnit.kg, units["N.s/m"].baseUnit.s) == (1, -1)
    assert (units["m/s"].baseUnit.m, units["m/s"].baseUnit.s) == (1, -1)
    expected = {
        "m": ("parameter", "fixed", "kg", "150"),
        "f_c": ("parameter", "fixed", "N", "100"),
        "f_s": ("parameter", "fixed", "N", "130"),
        "c": ("parameter", "fixed", "N.s/m", "700"),
        "x0": ("parameter", "fixed", "m", "0"),
        "v0": ("parameter", "fixed", "m/s", "0"),
        "x_resolution": ("parameter", "fixed", "m", "0"),
        "u": ("input", "continuous", "N", "0"),
        "x": ("output", "continuous", "m", "0"),
        "v": ("output", "continuous", "m/s", "0"),
        "x_meas": ("output", "continuous", "m", "0"),
    }
    variables = {v.name: v for v in md.modelVariables}
    assert set(variables) == set(expected) | {"stuck"}
    for name, (causality, variability, unit, start) in expected.items():
        v = variables[name]
        assert (v.type, v.causality, v.variability) == ("Real", causality, variability)
        assert v.unit == unit, name
        assert float(v.start) == float(start), name
    assert variables["stuck"].type == "Boolean"
    assert variables["stuck"].causality == "output"
    assert variables["stuck"].start in ("true", True)
    for v in md.modelVariables:
        assert v.description, f"variable {v.name} has no description"
        if v.causality == "output":
            assert v.initial == "exact", v.name
    de = md.defaultExperiment
    assert (float(de.startTime), float(de.stopTime), float(de.stepSize)) == (0.0, 1.0, 0.01)


@pytest.mark.parametrize(
    ("units", "problem"),
    [
        ({**FRICTION_PLANT_UNITS, "m": "lb"}, "unknown unit"),
        ({**FRICTION_PLANT_UNITS, "y": "m"}, "no variable named ['y']"),
        ({**FRICTION_PLANT_UNITS, "stuck": "m"}, "'stuck' is not a Real"),
        ({k: u for k, u in FRICTION_PLANT_UNITS.items() if k != "c"}, "['c'] are given no unit"),
    ],
)
def test_add_units_refuses_with_a_clear_error(
    friction_plant_fmu: Path, tmp_path: Path, units: dict[str, str], problem: str
) -> None:
    copy = tmp_path / "FrictionPlant.fmu"
    copy.write_bytes(friction_plant_fmu.read_bytes())
    with pytest.raises(BuildError, match="FrictionPlant.fmu") as info:
        add_units(copy, units)
    assert problem in str(info.value)
    assert copy.read_bytes() == friction_plant_fmu.read_bytes()


def test_build_of_a_missing_script_is_a_build_error(tmp_path: Path) -> None:
    with pytest.raises(BuildError, match="Missing.py does not exist"):
        build_pythonfmu(tmp_path / "Missing.py", tmp_path)


def test_a_model_that_fails_to_build_is_a_build_error(tmp_path: Path) -> None:
    script = tmp_path / "Broken.py"
    script.write_text(
        "from pythonfmu import Fmi2Slave\n\n\n"
        "class Broken(Fmi2Slave):\n"
        "    def __init__(self, **kwargs):\n"
        "        super().__init__(**kwargs)\n"
        "        raise ValueError('no variables here')\n\n"
        "    def do_step(self, current_time, step_size):\n"
        "        return True\n"
    )
    with pytest.raises(BuildError, match="ValueError: no variables here"):
        build_pythonfmu(script, tmp_path / "out")
    assert "Broken" not in sys.modules
    assert not (tmp_path / "out" / "Broken.fmu").exists()


# --- exactness ---------------------------------------------------------------------------


def test_initial_outputs_follow_x0_v0(plant: Plant) -> None:
    plant.init(x0=0.25, v0=-0.02, x_resolution=0.1)
    assert plant.get("x", "v", "x_meas") == [0.25, -0.02, quantize(0.25, 0.1)]
    assert not plant.stuck()


def test_trajectory_at_fixed_step_is_exact(plant: Plant) -> None:
    plant.init(x_resolution=1e-4)
    expected = simulate(U_SEQ, T, **PARAMS)
    for k, u in enumerate(U_SEQ):
        plant.step(u)
        x, v, x_meas = plant.get("x", "v", "x_meas")
        x_ref, v_ref = expected[k + 1]
        assert abs(x - x_ref) <= TOL and abs(v - v_ref) <= TOL, f"step {k}"
        assert x_meas == quantize(x, 1e-4)
        assert plant.stuck() == (v == 0.0) == (v_ref == 0.0), f"step {k}"
    # the sequence holds sticking, sub-stiction rest and a reversal
    velocities = [v for _, v in expected]
    assert velocities.count(0.0) > 20 and min(velocities) < 0.0 < max(velocities)


def test_other_parameters_and_initial_state_are_exact(plant: Plant) -> None:
    params = {"m": 20.0, "f_c": 15.0, "f_s": 40.0, "c": 5.0}
    plant.init(x0=-0.3, v0=0.2, **params)
    expected = simulate(U_SEQ, T, x0=-0.3, v0=0.2, **params)
    for k, u in enumerate(U_SEQ):
        plant.step(u)
        x, v = plant.get("x", "v")
        assert abs(x - expected[k + 1][0]) <= TOL and abs(v - expected[k + 1][1]) <= TOL


def test_parameters_set_after_initialization_do_not_change_the_motion(plant: Plant) -> None:
    plant.init(x_resolution=1e-3)
    plant.step(300.0)
    for name, value in (("m", 1.0), ("f_c", 0.0), ("x0", 5.0), ("v0", 1.0), ("x_resolution", 0.5)):
        plant.fmu.setReal([plant.vr[name]], [value])
    for u in U_SEQ[1:30]:
        plant.step(u)
    x_ref, v_ref = simulate(U_SEQ[:30], T, **PARAMS)[-1]
    assert plant.get("x", "v", "x_meas") == [x_ref, v_ref, quantize(x_ref, 1e-3)]


def test_variable_step_sizes_are_exact(plant: Plant) -> None:
    plant.init()
    rng = random.Random(12)
    x, v = 0.0, 0.0
    for k in range(200):
        h = rng.choice([1e-4, 0.003, 0.01, 0.0371, 0.1, 0.25])
        u = rng.choice([0.0, 125.0, -125.0, 280.0, -280.0, 140.0])
        plant.step(u, h)
        x, v = step(x, v, u, h, **PARAMS)
        assert plant.get("x", "v") == [x, v], f"step {k}, h = {h}"


def test_simulate_fmu_with_input_is_exact(friction_plant_fmu: Path) -> None:
    changes = [(0.0, 300.0), (0.05, 0.0), (0.25, 120.0), (0.35, -300.0), (0.4, 0.0)]
    rows = []
    for (t0, u), (t1, _) in zip(changes, changes[1:] + [(1.0, None)], strict=True):
        rows += [(t0, u), (t1, u)]
    signals = np.array(rows, dtype=[("time", np.float64), ("u", np.float64)])
    result = simulate_fmu(
        str(friction_plant_fmu), stop_time=1.0, output_interval=T, input=signals
    )
    u_seq = []
    for (t0, u), (t1, _) in zip(changes, changes[1:] + [(1.0, None)], strict=True):
        u_seq += [u] * round((t1 - t0) / T)
    expected = simulate(u_seq, T, **PARAMS)
    assert len(result) == len(expected)
    for k, row in enumerate(result):
        assert abs(row["time"] - k * T) < 1e-12
        assert abs(row["x"] - expected[k][0]) <= TOL, f"t = {row['time']}"
        assert abs(row["v"] - expected[k][1]) <= TOL, f"t = {row['time']}"


def test_fmpy_simulate_cli_with_pulse_input(fmu_dir: Path, tmp_path: Path) -> None:
    """``fmpy simulate build/FrictionPlant.fmu ... --input-file scenarios/pulse_in.csv``."""
    (tmp_path / "build").mkdir()
    (tmp_path / "build" / "FrictionPlant.fmu").write_bytes(
        (fmu_dir / "FrictionPlant.fmu").read_bytes()
    )
    (tmp_path / "scenarios").mkdir()
    (tmp_path / "scenarios" / "pulse_in.csv").write_bytes(
        (PROJECT_DIR / "scenarios" / "pulse_in.csv").read_bytes()
    )
    fmpy = Path(sys.executable).with_name("fmpy")
    command = [
        str(fmpy), "simulate", "build/FrictionPlant.fmu", "--output-interval", "0.01",
        "--stop-time", "1", "--input-file", "scenarios/pulse_in.csv",
    ]  # fmt: skip
    done = subprocess.run(
        [*command, "--output-file", "pulse_out.csv"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    with open(tmp_path / "pulse_out.csv", newline="") as f:
        result = list(csv.DictReader(f))  # fmpy's read_csv cannot read the Boolean column
    pulse = read_csv(PROJECT_DIR / "scenarios" / "pulse_in.csv")
    u_seq = [float(np.interp(k * T + T / 2, pulse["time"], pulse["u"])) for k in range(100)]
    assert set(u_seq) == {300.0, 0.0}
    expected = simulate(u_seq, T, **PARAMS)
    assert len(result) == len(expected) == 101
    for k, row in enumerate(result):
        x, v = float(row["x"]), float(row["v"])
        assert abs(x - expected[k][0]) <= TOL and abs(v - expected[k][1]) <= TOL
        assert row["stuck"] == str(v == 0.0)


# --- bad input ---------------------------------------------------------------------------


@pytest.mark.parametrize("bad_u", [math.nan, math.inf, -math.inf])
def test_non_finite_u_is_discarded_and_nothing_lost(plant: Plant, bad_u: float) -> None:
    plant.init()
    for u in (300.0, 300.0):
        plant.step(u)
    before = plant.get("x", "v", "x_meas")
    plant.fmu.setReal([plant.vr["u"]], [bad_u])
    with pytest.raises(FMICallException) as info:
        plant.fmu.doStep(plant.time, T)
    assert info.value.status == fmi2Discard
    assert plant.get("x", "v", "x_meas") == before
    status, category, message = plant.messages[-1]
    assert (status, category) == (fmi2Discard, "logStatusDiscard")
    assert f"u = {bad_u!r}" in message
    # the host corrects the input and repeats the step: the trajectory is unchanged
    for u in U_SEQ[2:20]:
        plant.step(u)
    assert plant.get("x", "v") == list(simulate(U_SEQ[:20], T, **PARAMS)[-1])


@pytest.mark.parametrize("h", [0.0, -0.01, math.nan, math.inf])
def test_bad_step_size_is_discarded(plant: Plant, h: float) -> None:
    plant.init()
    plant.step(300.0)
    before = plant.get("x", "v")
    plant.fmu.setReal([plant.vr["u"]], [300.0])
    with pytest.raises(FMICallException) as info:
        plant.fmu.doStep(plant.time, h)
    assert info.value.status == fmi2Discard
    assert plant.get("x", "v") == before
    assert f"step size {h!r} s" in plant.messages[-1][2]
    plant.step(300.0)
    assert plant.get("x", "v") == list(simulate([300.0, 300.0], T, **PARAMS)[-1])


@pytest.mark.parametrize(
    ("name", "value", "allowed"),
    [
        ("m", 0.0, "> 0"),
        ("m", -150.0, "> 0"),
        ("m", math.nan, "finite"),
        ("f_c", -1.0, ">= 0"),
        ("f_c", math.inf, "finite"),
        ("f_s", 90.0, ">= f_c"),
        ("c", -700.0, ">= 0"),
        ("x_resolution", -1e-6, ">= 0"),
        ("x_resolution", math.nan, "finite"),
        ("x0", math.inf, "finite"),
        ("v0", math.nan, "finite"),
    ],
)
def test_invalid_parameter_is_refused(plant: Plant, name: str, value: float, allowed: str) -> None:
    """Refused when initialization ends: logged with status Error, then doStep -> Discard.

    exitInitializationMode itself returns OK: with pythonfmu 0.7.0 the only other
    outcome is fmi2Fatal, which frees the instance and aborts a libcosim host.
    """
    plant.init(**{name: value})
    errors = [m for m in plant.messages if m[0] == fmi2Error]
    assert len(errors) == 1
    status, category, message = errors[0]
    assert category == "logStatusError"
    assert f"parameter {name} = {value!r}" in message and allowed in message
    with pytest.raises(FMICallException) as info:
        plant.step(300.0)
    assert info.value.status == fmi2Discard
    assert f"parameter {name}" in plant.messages[-1][2]


def test_messages_are_dropped_when_logging_is_off(friction_plant_unzipped: Path) -> None:
    quiet = Plant(friction_plant_unzipped, "quiet", logging=False)
    try:
        quiet.init(m=-1.0)
        assert quiet.messages == []
        quiet.fmu.setDebugLogging(True, [])
        with pytest.raises(FMICallException):
            quiet.step(300.0)
        assert "parameter m = -1.0" in quiet.messages[-1][2]
    finally:
        quiet.close()


# --- state -------------------------------------------------------------------------------


def test_get_set_fmu_state_restores_exactly(plant: Plant) -> None:
    plant.init()
    for u in U_SEQ[:3]:
        plant.step(u)
    saved_time = plant.time
    state = plant.fmu.getFMUstate()
    snapshot = plant.fmu.serializeFMUstate(state)
    before = (plant.get("x", "v", "x_meas"), plant.stuck())
    first = []
    for u in U_SEQ[3:40]:
        plant.step(u)
        first.append((plant.get("x", "v"), plant.stuck()))
    plant.fmu.setFMUstate(state)
    assert (plant.get("x", "v", "x_meas"), plant.stuck()) == before
    assert plant.fmu.serializeFMUstate(plant.fmu.getFMUstate()) == snapshot
    assert json.loads(snapshot)["time"] == saved_time
    plant.time = saved_time
    second = []
    for u in U_SEQ[3:40]:
        plant.step(u)
        second.append((plant.get("x", "v"), plant.stuck()))
    assert second == first
    plant.fmu.freeFMUstate(state)


def test_serialized_state_restores_exactly_in_another_instance(
    plant: Plant, friction_plant_unzipped: Path
) -> None:
    plant.init(m=90.0, c=300.0, x_resolution=1e-5)
    for u in U_SEQ[:12]:
        plant.step(u)
    data = plant.fmu.serializeFMUstate(plant.fmu.getFMUstate())
    other = Plant(friction_plant_unzipped, "other")
    try:
        other.init()
        other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(data))
        for name in ("x", "v", "x_meas", "m", "c", "x_resolution"):
            assert other.get(name) == plant.get(name), name
        assert other.stuck() == plant.stuck()
        other.time = plant.time
        for u in U_SEQ[12:60]:
            plant.step(u)
            other.step(u)
            assert other.get("x", "v") == plant.get("x", "v")
    finally:
        other.close()


def test_hundred_instances_are_independent(friction_plant_unzipped: Path) -> None:
    rng = random.Random(5)
    cases = []
    for i in range(100):
        f_c = rng.uniform(10.0, 120.0)
        params = {
            "m": rng.uniform(1.0, 300.0),
            "f_c": f_c,
            "f_s": f_c + rng.uniform(0.0, 50.0),
            "c": rng.uniform(0.0, 1000.0),
        }
        u_seq = [rng.choice([0.0, 1.0, -1.0, 2.5, -2.5]) * params["f_s"] for _ in range(40)]
        cases.append((Plant(friction_plant_unzipped, f"plant{i}", logging=False), params, u_seq))
    try:
        for plant, params, _ in cases:
            plant.init(**params)
        for k in range(40):  # interleaved: step every instance once per period
            for plant, _, u_seq in cases:
                plant.step(u_seq[k])
        for plant, params, u_seq in cases:
            x_ref, v_ref = simulate(u_seq, T, **params)[-1]
            x, v = plant.get("x", "v")
            assert abs(x - x_ref) <= TOL and abs(v - v_ref) <= TOL
    finally:
        for plant, _, _ in cases:
            plant.close()


def test_extracted_fmu_holds_the_physics(friction_plant_fmu: Path, tmp_path: Path) -> None:
    unzipdir = Path(extract(str(friction_plant_fmu), str(tmp_path / "x")))
    bundled = (unzipdir / "resources" / "papwc_stickslip.py").read_text()
    assert bundled == (PROJECT_DIR / "fmu_src" / "papwc_stickslip.py").read_text()
    assert (unzipdir / "documentation" / "readme.md").is_file()
