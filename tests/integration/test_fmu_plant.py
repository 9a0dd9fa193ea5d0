"""FrictionPlant.fmu: exactness through the master and fmpy, bad input, refusals, state,
logging and many instances.

Exactness runs on the native FMU (the default); the refusals, logging and the JSON state
of the pythonfmu glue on the pythonfmu FrictionPlant (fixture ``pyplant``); the native
FMU's refusals and states are in test_native_fmu.py.

Force sequences are played into the FMU by the master (``harness.open_loop``: a
SignalSlave into the plant's ``u``); FMI functions are called directly (through the
one harness, ``harness.FmuInstance``) only to provoke refusals and to get, set and
serialize the state.
"""

from __future__ import annotations

import csv
import json
import math
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.util import read_csv
from harness import FMI2_DISCARD, FMI2_ERROR, FmuInstance, open_loop, table_1

from papwc.master import Execution, FixedStepAlgorithm, FmuSlave, SignalSlave
from papwc.model.stickslip import quantize, simulate, step

T = 0.01
PARAMS = table_1()
#: Pulses above f_s both ways, coasting, a sub-stiction force, a reversal while sliding.
U_SEQ = [300.0] * 5 + [0.0] * 20 + [120.0] * 10 + [-300.0] * 5 + [0.0] * 15
U_SEQ += [250.0] * 7 + [-200.0] * 4 + [0.0] * 34
#: The variables recorded from the plant.
OUTPUTS = ("x", "v", "x_meas", "stuck")


@pytest.fixture
def plant(friction_plant_unzipped: Path):
    p = FmuInstance(friction_plant_unzipped, "plant")
    yield p
    p.close()


@pytest.fixture
def pyplant(pythonfmu_plant_unzipped: Path):
    """An instance of the pythonfmu FrictionPlant (``papwc build --backend pythonfmu``)."""
    p = FmuInstance(pythonfmu_plant_unzipped, "plant")
    yield p
    p.close()


def assert_no_error_logged(plant: FmuInstance) -> None:
    assert [m for m in plant.messages if m.status >= FMI2_DISCARD] == []


# --- exactness: the master drives the FMU -----------------------------------------------------
def test_initial_outputs_follow_x0_v0(plant: FmuInstance) -> None:
    plant.init(x0=0.25, v0=-0.02, x_resolution=0.1)
    assert plant.get_many("x", "v", "x_meas") == [0.25, -0.02, quantize(0.25, 0.1)]
    assert not plant.get("stuck")


@pytest.mark.parametrize("resolution", [1e-4, 0.0])
def test_signal_slave_open_loop_equals_simulate_bit_for_bit(
    friction_plant_fmu: Path, resolution: float
) -> None:
    """The master plays U_SEQ into FrictionPlant.fmu: every sample is papwc.model.stickslip's
    simulate exactly (the FMU runs the same code; formerly checked to 1e-12)."""
    with FmuSlave(friction_plant_fmu) as plant:
        plant.set_start_values({**PARAMS, "x_resolution": resolution})
        _, rec = open_loop(plant, U_SEQ, T, OUTPUTS)
    expected = simulate(U_SEQ, T, **PARAMS)
    assert rec.states() == expected
    assert rec.column("x_meas") == [quantize(x, resolution) for x, _ in expected]
    assert rec.column("stuck") == [v == 0.0 for _, v in expected]
    # the sequence holds sticking, sub-stiction rest and a reversal
    velocities = [v for _, v in expected]
    assert velocities.count(0.0) > 20 and min(velocities) < 0.0 < max(velocities)


def test_other_parameters_and_initial_state_are_exact(friction_plant_fmu: Path) -> None:
    params = {"m": 20.0, "f_c": 15.0, "f_s": 40.0, "c": 5.0}
    with FmuSlave(friction_plant_fmu) as plant:
        plant.set_start_values({**params, "x0": -0.3, "v0": 0.2})
        _, rec = open_loop(plant, U_SEQ, T, OUTPUTS)
    assert rec.states() == simulate(U_SEQ, T, x0=-0.3, v0=0.2, **params)


def test_the_harness_as_a_slave_gives_the_same_trajectory(plant: FmuInstance) -> None:
    """The fmpy harness stepped by the master is the master's own FmuSlave, bit for bit."""
    plant.set_start_values(PARAMS)
    _, rec = open_loop(plant, U_SEQ, T, OUTPUTS)
    assert rec.states() == simulate(U_SEQ, T, **PARAMS)
    assert_no_error_logged(plant)


def test_parameters_set_after_initialization_are_refused(pyplant: FmuInstance) -> None:
    pyplant.set_start_values({"x_resolution": 1e-3})
    execution, rec = open_loop(pyplant, U_SEQ[:30], T, OUTPUTS, steps=1)
    for name, value in (("m", 1.0), ("f_c", 0.0), ("x0", 5.0), ("v0", 1.0), ("x_resolution", 0.5)):
        before = pyplant.get(name)
        pyplant.set(name, value)
        assert pyplant.get(name) == before  # the value is kept
        assert (f"parameter {name} cannot be set after initialization: {value!r} refused, "
                f"it stays {before!r}") in pyplant.messages[-1].text
        assert pyplant.messages[-1].status == FMI2_ERROR
    execution.step(29)
    x_ref, v_ref = simulate(U_SEQ[:30], T, **PARAMS)[-1]
    assert pyplant.get_many("x", "v", "x_meas") == [x_ref, v_ref, quantize(x_ref, 1e-3)]
    assert rec.states() == simulate(U_SEQ[:30], T, **PARAMS)


def test_an_output_cannot_be_set(pyplant: FmuInstance) -> None:
    pyplant.init()
    pyplant.set("x", 1.0)
    assert pyplant.get("x") == 0.0
    assert "x is an output and cannot be set: 1.0 refused" in pyplant.messages[-1].text


def test_variable_step_sizes_are_exact(plant: FmuInstance) -> None:
    """canHandleVariableCommunicationStepSize: any step size, each step exact.

    The master steps at a fixed period, so this test calls fmi2DoStep itself, with
    step sizes the master never uses."""
    plant.init()
    rng = random.Random(12)
    x, v, t = 0.0, 0.0, 0.0
    for k in range(200):
        h = rng.choice([1e-4, 0.003, 0.01, 0.0371, 0.1, 0.25])
        u = rng.choice([0.0, 125.0, -125.0, 280.0, -280.0, 140.0])
        plant.set("u", u)
        plant.fmu.doStep(t, h)
        t += h
        x, v = step(x, v, u, h, **PARAMS)
        assert plant.get_many("x", "v") == [x, v], f"step {k}, h = {h}"
    assert_no_error_logged(plant)


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
    # fmpy steps with h = t_(k+1) - t_k on its own time grid, which differs from T in
    # the last bits: measured at most 1.3e-18 m in x and 6.2e-17 m/s in v (was 1e-12).
    states = np.array(expected)
    np.testing.assert_allclose(result["x"], states[:, 0], rtol=0.0, atol=5e-18)
    np.testing.assert_allclose(result["v"], states[:, 1], rtol=0.0, atol=2e-16)
    for k, row in enumerate(result):
        assert abs(row["time"] - k * T) < 1e-12


def test_fmpy_simulate_cli_with_pulse_input(fmu_dir: Path, project_dir: Path,
                                            tmp_path: Path) -> None:
    """``fmpy simulate build/FrictionPlant.fmu ... --input-file scenarios/pulse_in.csv``."""
    (tmp_path / "build").mkdir()
    (tmp_path / "build" / "FrictionPlant.fmu").write_bytes(
        (fmu_dir / "FrictionPlant.fmu").read_bytes()
    )
    (tmp_path / "scenarios").mkdir()
    (tmp_path / "scenarios" / "pulse_in.csv").write_bytes(
        (project_dir / "scenarios" / "pulse_in.csv").read_bytes()
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
    pulse = read_csv(project_dir / "scenarios" / "pulse_in.csv")
    u_seq = [float(np.interp(k * T + T / 2, pulse["time"], pulse["u"])) for k in range(100)]
    assert set(u_seq) == {300.0, 0.0}
    expected = simulate(u_seq, T, **PARAMS)
    assert len(result) == len(expected) == 101
    for k, row in enumerate(result):
        x, v = float(row["x"]), float(row["v"])
        # fmpy's time grid (h = t_(k+1) - t_k, not exactly T) costs the last bits:
        # measured at most 8.7e-19 m in x and 1.7e-17 m/s in v (was 1e-12).
        assert abs(x - expected[k][0]) <= 5e-18 and abs(v - expected[k][1]) <= 1e-16
        assert row["stuck"] == str(v == 0.0)


# --- bad input ----------------------------------------------------------------------------------
@pytest.mark.parametrize("bad_u", [math.nan, math.inf, -math.inf])
def test_non_finite_u_is_discarded_and_nothing_lost(plant: FmuInstance, bad_u: float) -> None:
    plant.set_start_values(PARAMS)
    execution, _ = open_loop(plant, U_SEQ[:20], T, OUTPUTS, steps=2)
    before = plant.get_many("x", "v", "x_meas")
    plant.set("u", bad_u)
    with pytest.raises(FMICallException) as info:
        plant.fmu.doStep(2 * T, T)
    assert info.value.status == FMI2_DISCARD
    assert plant.get_many("x", "v", "x_meas") == before
    status, category, message = plant.messages[-1]
    assert (status, category) == (FMI2_DISCARD, "logStatusDiscard")
    assert f"u = {bad_u!r}" in message
    assert message == (f"plant: doStep(t = 0.02 s, h = 0.01 s) refused: input u = {bad_u!r} N "
                       "is not finite; the state is left as it was")
    # the master corrects the input and repeats the step: the trajectory is unchanged
    execution.step(18)
    assert plant.get_many("x", "v") == list(simulate(U_SEQ[:20], T, **PARAMS)[-1])


@pytest.mark.parametrize("h", [0.0, -0.01, math.nan, math.inf])
def test_bad_step_size_is_discarded(plant: FmuInstance, h: float) -> None:
    plant.init()
    plant.set("u", 300.0)
    plant.fmu.doStep(0.0, T)
    before = plant.get_many("x", "v")
    with pytest.raises(FMICallException) as info:
        plant.fmu.doStep(T, h)
    assert info.value.status == FMI2_DISCARD
    assert plant.get_many("x", "v") == before
    assert f"step size {h!r} s" in plant.messages[-1].text
    plant.fmu.doStep(T, T)
    assert plant.get_many("x", "v") == list(simulate([300.0, 300.0], T, **PARAMS)[-1])


@pytest.mark.parametrize(
    ("name", "value", "allowed"),
    [
        ("m", 0.0, "m = 0.0 kg: must satisfy 1e-06 <= m <= 1e+09 kg"),
        ("m", -150.0, "m = -150.0 kg: must satisfy 1e-06 <= m <= 1e+09 kg"),
        ("m", math.nan, "m = nan kg: must be a finite number"),
        ("f_c", -1.0, "f_c = -1.0 N: must satisfy 0 <= f_c <= 1e+09 N"),
        ("f_c", math.inf, "f_c = inf N: must be a finite number"),
        ("f_s", 90.0, "f_s = 90.0 N: must be >= f_c = 100.0 N"),
        ("c", -700.0, "c = -700.0 N.s/m: must satisfy 0 <= c <= 1e+09 N.s/m"),
        ("x_resolution", -1e-6, "x_resolution = -1e-06 m: must satisfy 0 <= x_resolution <= 1 m"),
        ("x_resolution", math.nan, "x_resolution = nan m: must be a finite number"),
        ("x0", math.inf, "x0 = inf m: must be a finite number"),
        ("v0", math.nan, "v0 = nan m/s: must be a finite number"),
    ],
)
def test_invalid_parameter_is_refused(pyplant: FmuInstance, name: str, value: float,
                                      allowed: str) -> None:
    """Refused when initialization ends: logged with status Error, then doStep -> Discard.

    exitInitializationMode itself returns OK: with pythonfmu 0.7.0 the only other
    outcome is fmi2Fatal, which frees the instance and aborts a libcosim host.
    """
    pyplant.init(**{name: value})
    errors = [m for m in pyplant.messages if m.status == FMI2_ERROR]
    assert len(errors) == 1
    status, category, message = errors[0]
    assert category == "logStatusError"
    assert f"parameter {name} = {value!r}" in message and allowed in message
    assert message == (f"plant: parameter {allowed}; initialization refused, doStep will "
                       "return Discard")
    pyplant.set("u", 300.0)
    with pytest.raises(FMICallException) as info:
        pyplant.fmu.doStep(0.0, T)
    assert info.value.status == FMI2_DISCARD
    assert f"parameter {name}" in pyplant.messages[-1].text
    assert f"invalid parameters: parameter {allowed}" in pyplant.messages[-1].text


def test_steps_before_initialization_and_after_terminate_are_discarded(
    pyplant: FmuInstance,
) -> None:
    with pytest.raises(FMICallException) as info:
        pyplant.fmu.doStep(0.0, T)
    assert info.value.status == FMI2_DISCARD
    assert "initialization has not ended" in pyplant.messages[-1].text
    pyplant.fmu.setupExperiment(startTime=0.0)
    pyplant.fmu.enterInitializationMode()
    pyplant.fmu.exitInitializationMode()
    pyplant.fmu.doStep(0.0, T)
    pyplant.fmu.terminate()
    with pytest.raises(FMICallException):
        pyplant.fmu.doStep(T, T)
    assert "the simulation was terminated (fmi2Terminate)" in pyplant.messages[-1].text


def test_messages_are_dropped_when_logging_is_off(pythonfmu_plant_unzipped: Path) -> None:
    quiet = FmuInstance(pythonfmu_plant_unzipped, "quiet", logging=False)
    try:
        quiet.init(m=-1.0)
        assert quiet.messages == []
        quiet.fmu.setDebugLogging(True, [])
        with pytest.raises(FMICallException):
            quiet.fmu.doStep(0.0, T)
        assert "parameter m = -1.0" in quiet.messages[-1].text
    finally:
        quiet.close()


# --- state --------------------------------------------------------------------------------------
def test_get_set_fmu_state_restores_exactly(pyplant: FmuInstance) -> None:
    pyplant.set_start_values(PARAMS)
    execution, rec = open_loop(pyplant, U_SEQ[:40], T, OUTPUTS, steps=3)
    saved_time = execution.time()
    state = pyplant.fmu.getFMUstate()
    snapshot = pyplant.fmu.serializeFMUstate(state)
    before = (pyplant.get_many("x", "v", "x_meas"), pyplant.get("stuck"))
    execution.step(37)
    first = rec.rows[3:]
    assert len(first) == 38
    assert rec.states() == simulate(U_SEQ[:40], T, **PARAMS)
    pyplant.fmu.setFMUstate(state)
    assert (pyplant.get_many("x", "v", "x_meas"), pyplant.get("stuck")) == before
    assert pyplant.fmu.serializeFMUstate(pyplant.fmu.getFMUstate()) == snapshot
    data = json.loads(snapshot)
    assert data["papwc_fmu_state"] == "FrictionPlant"
    assert data["fields"]["time"] == saved_time
    # the master continues from the restored state: the same 37 samples
    pyplant.resume_from(state)
    _, again = open_loop(pyplant, U_SEQ[3:40], T, OUTPUTS, start_time=saved_time)
    assert again.rows == first
    pyplant.fmu.freeFMUstate(state)
    assert_no_error_logged(pyplant)


def test_serialized_state_restores_exactly_in_another_instance(
    plant: FmuInstance, friction_plant_unzipped: Path
) -> None:
    plant.set_start_values({"m": 90.0, "c": 300.0, "x_resolution": 1e-5})
    execution, _ = open_loop(plant, U_SEQ[:60], T, OUTPUTS, steps=12)
    state = plant.fmu.getFMUstate()
    data = plant.fmu.serializeFMUstate(state)
    other = FmuInstance(friction_plant_unzipped, "other")
    try:
        other.init()
        other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(data))
        for name in ("x", "v", "x_meas", "m", "c", "x_resolution"):
            assert other.get(name) == plant.get(name), name
        assert other.get("stuck") == plant.get("stuck")
        # both continue from there, each in an execution of its own, with the same input
        runs = []
        for instance, resume in ((plant, state), (other, other.fmu.getFMUstate())):
            instance.resume_from(resume)
            runs.append(open_loop(instance, U_SEQ[12:60], T, OUTPUTS, start_time=0.12)[1])
        assert runs[0].rows == runs[1].rows and len(runs[0].rows) == 49
        assert runs[0].states()[-1] == simulate(U_SEQ[:60], T, m=90.0, f_c=100.0, f_s=130.0,
                                                c=300.0)[-1]
        assert_no_error_logged(other)
    finally:
        other.close()


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"not json", "the serialized state is not one of this FMU"),
        (b"[1, 2]", "the serialized state is not one of this FMU"),
        (json.dumps({"papwc_fmu_state": "PulseController", "fields": {}}).encode(),
         "the state belongs to 'PulseController', not to 'FrictionPlant'"),
        (json.dumps({"papwc_fmu_state": "FrictionPlant", "fields": {"x": 1.0}}).encode(),
         "the state does not hold this FMU's fields"),
    ],
)
def test_a_state_of_another_kind_is_refused_and_the_instance_keeps_working(
    pyplant: FmuInstance, data: bytes, reason: str
) -> None:
    pyplant.set_start_values(PARAMS)
    execution, rec = open_loop(pyplant, U_SEQ[:20], T, OUTPUTS, steps=5)
    before = pyplant.get_many("x", "v")
    pyplant.fmu.setFMUstate(pyplant.fmu.deSerializeFMUstate(data))
    errors = pyplant.logged(FMI2_ERROR)
    assert len(errors) == 1 and "setFMUstate refused" in errors[0] and reason in errors[0]
    assert pyplant.get_many("x", "v") == before
    execution.step(15)
    assert rec.states() == simulate(U_SEQ[:20], T, **PARAMS)


def test_a_state_with_a_wrong_field_type_is_refused(pyplant: FmuInstance) -> None:
    pyplant.init()
    state = json.loads(pyplant.fmu.serializeFMUstate(pyplant.fmu.getFMUstate()))
    state["fields"]["x"] = "far"
    pyplant.fmu.setFMUstate(pyplant.fmu.deSerializeFMUstate(json.dumps(state).encode()))
    assert "field x = 'far' is not a Real" in pyplant.logged(FMI2_ERROR)[-1]
    assert pyplant.get("x") == 0.0


# --- many instances -----------------------------------------------------------------------------
def test_hundred_instances_are_independent(friction_plant_fmu: Path,
                                           friction_plant_unzipped: Path) -> None:
    """One execution steps 100 plants, each driven by its own force sequence, interleaved."""
    rng = random.Random(5)
    execution = Execution(FixedStepAlgorithm(T))
    cases = []
    try:
        for i in range(100):
            f_c = rng.uniform(10.0, 120.0)
            params = {
                "m": rng.uniform(1.0, 300.0),
                "f_c": f_c,
                "f_s": f_c + rng.uniform(0.0, 50.0),
                "c": rng.uniform(0.0, 1000.0),
            }
            u_seq = [rng.choice([0.0, 1.0, -1.0, 2.5, -2.5]) * params["f_s"] for _ in range(40)]
            signal = execution.add_slave(SignalSlave({"u": u_seq}, name=f"force{i}"))
            plant = execution.add_slave(FmuSlave(friction_plant_fmu, name=f"plant{i}",
                                                 unzip_dir=friction_plant_unzipped))
            plant.set_start_values(params)
            execution.connect(signal, "u", plant, "u")
            cases.append((plant, params, u_seq, plant.watch(["x", "v"])))
        execution.initialize()
        execution.step(40)  # every instance stepped once per period, in turn
        for plant, params, u_seq, (ix, iv) in cases:
            assert (plant.values[ix], plant.values[iv]) == simulate(u_seq, T, **params)[-1]
    finally:
        execution.close()
