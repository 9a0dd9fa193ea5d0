"""The co-simulation master with in-process slaves: timing, open and closed loops, the
trace, noise, restarts and errors. FMUs as slaves are in tests/integration/."""

from __future__ import annotations

import csv
import dataclasses
import math

import numpy as np
import pytest
from harness import TABLE_1, Recorder, ScriptedController, open_loop

from papwc.controllers import Mode, make_controller
from papwc.controllers.settings import ControllerSettings
from papwc.errors import FmuError
from papwc.master import (
    TRACE_COLUMNS,
    ClosedLoop,
    ControllerSlave,
    Execution,
    FixedStepAlgorithm,
    Maneuver,
    PhysicsSlave,
    SignalSlave,
    run_closed_loop,
    run_controller,
    run_iteration,
)
from papwc.model.plant import PLANT_DEFAULTS
from papwc.model.stickslip import quantize, simulate
from papwc.results.summary import summarize

T = 0.01
#: Pulses above f_s both ways, coasting, a sub-stiction force, a reversal while sliding.
U_SEQ = [300.0] * 5 + [0.0] * 20 + [120.0] * 10 + [-300.0] * 5 + [0.0] * 15
U_SEQ += [250.0] * 7 + [-200.0] * 4 + [0.0] * 34


# -- timing -------------------------------------------------------------------------------
def test_delayed_timing_applies_the_force_one_step_later():
    forces = [300.0, 300.0, 0.0, 0.0, 0.0]
    traces = {}
    for timing in ("immediate", "delayed"):
        plant = PhysicsSlave()
        plant.initialize()
        traces[timing] = run_iteration(plant, ScriptedController(forces),
                                       Maneuver(duration=0.05, timing=timing))
    u_now = traces["immediate"].column("u")[:-1]
    u_late = traces["delayed"].column("u")[:-1]
    assert u_now == forces
    assert u_late == [0.0] + forces[:-1]
    assert traces["delayed"].column("x")[1] == 0.0 < traces["immediate"].column("x")[1]
    # the delayed loop is the immediate one with the forces shifted by one sample
    shifted = run_iteration(PhysicsSlave(), ScriptedController([0.0] + forces[:-1]),
                            Maneuver(duration=0.05))
    assert shifted.column("x") == traces["delayed"].column("x")


def test_algorithm_refuses_an_unknown_timing_and_a_bad_step_size():
    with pytest.raises(FmuError, match="timing 'late': must be one of immediate, delayed"):
        FixedStepAlgorithm(0.01, "late")
    for h in (0.0, -0.01, math.nan):
        with pytest.raises(FmuError, match="must be > 0"):
            FixedStepAlgorithm(h)


# -- open loop: a SignalSlave drives the plant -------------------------------------------------
@pytest.mark.parametrize(
    ("params", "resolution"),
    [(TABLE_1, 1e-4), ({"m": 20.0, "f_c": 15.0, "f_s": 40.0, "c": 5.0, "x0": -0.3, "v0": 0.2},
                       0.0)],
    ids=["table1", "other"],
)
def test_signal_slave_open_loop_of_the_physics_equals_simulate_bit_for_bit(params, resolution):
    plant = PhysicsSlave()
    plant.set_start_values({**params, "x_resolution": resolution})
    _, rec = open_loop(plant, U_SEQ, T)
    p = {**PLANT_DEFAULTS, **params}
    expected = simulate(U_SEQ, T, p["m"], p["f_c"], p["f_s"], p["c"], x0=p["x0"], v0=p["v0"])
    assert rec.states() == expected
    assert rec.column("x_meas") == [quantize(x, resolution) for x, _ in expected]
    assert rec.column("stuck") == [v == 0.0 for _, v in expected]


def test_signal_slave_holds_its_last_value_and_has_no_inputs():
    execution = Execution(FixedStepAlgorithm(T))
    signal = execution.add_slave(SignalSlave({"u": [1.0, 2.0], "w": [5.0]}))
    rec = execution.add_observer(Recorder(signal, ["u", "w"]))
    execution.initialize()
    execution.step(4)
    # the value of step k is shown once the signal has stepped at t_k; then the last value
    assert rec.column("u") == [1.0, 1.0, 2.0, 2.0, 2.0]
    assert rec.column("w") == [5.0] * 5
    execution.restart()
    execution.step(2)
    assert rec.column("u") == [1.0, 1.0, 2.0]  # played again from the start
    assert signal.variables() == {"u": "output", "w": "output"}
    with pytest.raises(FmuError, match="a signal has no inputs"):
        signal.input_setter(["u"])
    with pytest.raises(FmuError, match="a signal has no parameters or inputs"):
        signal.set_start_values({"u": 1.0})
    with pytest.raises(FmuError, match="needs an identifier name and values"):
        SignalSlave({"u": []})
    with pytest.raises(FmuError, match="needs an identifier name and values"):
        SignalSlave({"not a name": [1.0]})


def test_open_loop_steps_on_from_where_it_stopped():
    plant = PhysicsSlave()
    plant.set_start_values(TABLE_1)
    execution, rec = open_loop(plant, U_SEQ, T, steps=30)
    execution.step(len(U_SEQ) - 30)
    assert execution.k == len(U_SEQ)
    assert execution.time() == pytest.approx(len(U_SEQ) * T, rel=1e-15)
    assert rec.states() == simulate(U_SEQ, T, **TABLE_1)


# -- the execution's assembly ----------------------------------------------------------------
def test_connections_are_checked_when_made():
    execution = Execution(FixedStepAlgorithm(T))
    plant = execution.add_slave(PhysicsSlave())
    with pytest.raises(FmuError, match="plant is not a slave of this execution"):
        execution.connect(plant, "x", PhysicsSlave(), "u")
    with pytest.raises(FmuError, match="plant has no output 'nope'"):
        execution.connect(plant, "nope", plant, "u")
    with pytest.raises(FmuError, match="plant has no input 'x'"):
        execution.connect(plant, "x_meas", plant, "x")
    controller = execution.add_slave(ControllerSlave(ScriptedController([])))
    with pytest.raises(FmuError, match="'m' is not an input of the controller"):
        controller.set_start_values({"m": 1.0})
    with pytest.raises(FmuError, match="the plant has no parameter mass"):
        plant.set_start_values({"mass": 1.0})
    with pytest.raises(FmuError, match="the plant's only input is u"):
        plant.input_setter(["x0"])
    with pytest.raises(FmuError, match="has no variable 'b'"):
        plant.watch(["b"])


def test_watched_values_and_the_time_grid():
    execution = Execution(FixedStepAlgorithm(0.1), start_time=2.0)
    plant = execution.add_slave(PhysicsSlave())
    rec = execution.add_observer(Recorder(plant, ["x", "m", "stuck"]))
    execution.initialize()
    execution.step(3)
    assert execution.k == 3 and execution.time() == 2.0 + 3 * 0.1
    assert execution.time(7) == 2.0 + 7 * 0.1  # t_k = t0 + k*h, never accumulated
    assert rec.column("m") == [150.0] * 4 and rec.column("stuck") == [True] * 4
    execution.restart()
    assert execution.k == 0 and len(rec.rows) == 1


# -- closed loops ------------------------------------------------------------------------------
@pytest.mark.parametrize("timing", ["immediate", "delayed"])
def test_iterations_restart_the_plant_and_carry_the_estimates(timing):
    plant = PhysicsSlave()
    plant.set_start_values(TABLE_1)
    result = run_controller(plant, ControllerSettings(kind="papwc", t_p_max=0.03),
                            Maneuver(duration=1.0, iterations=3, timing=timing))
    assert not result.error
    assert [tr.iteration for tr in result.traces] == [1, 2, 3]
    for tr in result.traces:
        assert tr.column("x")[0] == 0.0 and tr.column("v")[0] == 0.0  # starts at rest at 0
        assert tr.column("pulses")[0] == 1  # counted anew: the first pulse starts at t_0
    b_start = [tr.column("b_hat")[0] for tr in result.traces]
    b_end = [tr.column("b_hat")[-1] for tr in result.traces]
    assert b_start[1] == b_end[0] and b_start[2] == b_end[1]
    assert b_start[0] != b_end[0]


def test_run_controller_is_run_closed_loop_with_a_controller_slave():
    settings = ControllerSettings(kind="pwc", t_p_max=0.03, K_c=0.5, tolerance=0.0)
    maneuver = Maneuver(duration=1.0, iterations=2)
    runs = []
    for make in (
        lambda plant: run_controller(plant, settings, maneuver, "a"),
        lambda plant: run_closed_loop(plant, ControllerSlave(make_controller(settings, T)),
                                      maneuver, settings, "a"),
    ):
        plant = PhysicsSlave()
        plant.set_start_values(TABLE_1)
        runs.append(make(plant))
    for a, b in zip(runs[0].traces, runs[1].traces, strict=True):
        assert a.columns == b.columns and a.controller == b.controller == "a"
    assert runs[0].label == "a" and runs[0].settings is settings


def test_invalid_plant_parameter_ends_the_run_before_any_trace():
    plant = PhysicsSlave()
    plant.set_start_values({"f_s": 50.0})
    result = run_controller(plant, ControllerSettings(), Maneuver(iterations=2))
    assert result.error == ("iteration 1: exitInitializationMode refused: parameter f_s = "
                            "50.0 N: must be >= f_c = 100.0 N")
    assert result.traces == []


def test_a_failing_step_ends_the_iteration_and_keeps_what_was_recorded():
    forces = [300.0] * 3 + [0.0] * 2 + [math.nan]
    trace = run_iteration(PhysicsSlave(), ScriptedController(forces), Maneuver(duration=0.2))
    assert len(trace) == 6  # samples 0..5 recorded, the 6th step was refused
    assert trace.error == "doStep at t = 0.05 s discarded: u = nan N, step size = 0.01 s"
    assert trace.column("x")[3] > 0.0  # the motion before the failure is kept
    assert trace.column("u")[:5] == forces[:5] and math.isnan(trace.column("u")[5])


def test_a_maneuver_with_noise_is_reproduced_by_its_seed():
    settings = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8, rest_band=3e-6)
    maneuver = Maneuver(duration=1.0, iterations=2, noise_std=1e-6, noise_seed=4)
    runs = []
    for seed in (4, 4, 5):
        plant = PhysicsSlave()
        plant.set_start_values(TABLE_1)
        runs.append(run_controller(plant, settings,
                                   dataclasses.replace(maneuver, noise_seed=seed)))
    a, b, c = (r.traces for r in runs)
    assert [t.columns for t in a] == [t.columns for t in b]
    assert a[0].column("x_meas") != c[0].column("x_meas")
    for tr in a:
        noise = np.array(tr.column("x_meas")) - np.array(tr.column("x"))
        assert 0.0 < np.std(noise) < 3e-6  # the noise is in x_meas only
    # each iteration draws its own noise
    assert (np.array(a[0].column("x_meas")) - a[0]["x"])[0] != (
        np.array(a[1].column("x_meas")) - a[1]["x"])[0]


def test_closed_loop_iteration_numbers_name_the_traces():
    plant = PhysicsSlave()
    plant.set_start_values(TABLE_1)
    loop = ClosedLoop(plant, ControllerSlave(make_controller(ControllerSettings(), T)),
                      Maneuver(duration=0.3), "label")
    first = loop.iteration(1)
    again = loop.iteration(2)
    assert (first.controller, first.iteration, again.iteration) == ("label", 1, 2)
    assert first.T == T and first.x_ref == 0.01


# -- the trace -----------------------------------------------------------------------------------
def test_trace_columns_rows_arrays_and_csv(tmp_path):
    plant = PhysicsSlave()
    plant.set_start_values(TABLE_1)
    trace = run_controller(plant, ControllerSettings(kind="papwc"),
                           Maneuver(duration=0.5, iterations=1)).traces[0]
    n = 51
    assert len(trace) == n
    assert tuple(trace.columns) == TRACE_COLUMNS
    assert trace.column("k") == list(range(n))
    assert trace.column("t") == [k * T for k in range(n)]
    assert trace.column("e") == [0.01 - x for x in trace.column("x")]
    assert isinstance(trace["x"], np.ndarray) and trace["x"].tolist() == trace.column("x")
    row = trace.row(-1)
    assert set(row) == set(TRACE_COLUMNS) and math.isnan(row["u"]) and row["k"] == n - 1
    assert trace.row(0)["mode"] in (Mode.PULSE, Mode.COARSE)
    path = tmp_path / "trace.csv"
    trace.to_csv(path)
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(TRACE_COLUMNS) and len(rows) == n
    assert [float(r["x"]) for r in rows] == trace.column("x")  # full precision
    assert [int(r["pulses"]) for r in rows] == trace.column("pulses")
    s = summarize(trace, 2e-5)
    assert s["final_error_m"] == 0.01 - trace.column("x")[-1]
    assert s["pulses"] == trace.column("pulses")[-1]


def test_the_in_process_plant_reads_every_output_from_the_plant_object() -> None:
    """PhysicsSlave's outputs are Plant.outputs() (papwc.model.dynamics.OUTPUTS) after every
    step, by the names of PLANT_OUTPUTS, with deviations and noisy encoders."""
    from papwc.model.dynamics import OUTPUTS
    from papwc.model.plant import PLANT_OUTPUTS

    names = [v.name for v in PLANT_OUTPUTS]
    assert list(OUTPUTS) == names
    slave = PhysicsSlave()
    slave.set_start_values({"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3,
                            "tau_u": 2e-3, "seed": 3, "noise_std": 2e-7,
                            "x_resolution": 1e-7, "x_d_noise_std": 1e-7,
                            "x_d_resolution": 1e-7})
    indexes = slave.watch(names + ["u", "m"])
    set_u = slave.input_setter(["u"])
    slave.initialize(0.0)
    for k, u in enumerate([300.0] * 5 + [0.0] * 10 + [-200.0] * 4 + [0.0] * 20):
        set_u(u)
        slave.do_step(k * 0.01, 0.01)
        expected = {**slave.plant.outputs(), "u": u, "m": 100.0}
        assert dict(zip(names + ["u", "m"], [slave.values[i] for i in indexes],
                        strict=True)) == expected, k
    assert slave.values[indexes[names.index("x_d")]] != slave.values[indexes[0]]


def test_a_step_guard_stops_a_run_between_two_steps() -> None:
    """StepGuard, an observer: past its deadline the run stops at the first look at the clock
    (every StepGuard.CLOCK_EVERY steps), and a deferred Ctrl-C stops it after the step under way."""
    import signal
    import time

    from papwc.interrupts import _INTERRUPT, RunTimeout
    from papwc.master import ClosedLoop, StepGuard

    settings = ControllerSettings(kind="papwc", t_p_max=0.03)
    guard = StepGuard(deadline=time.monotonic() - 1.0, limit=0.5)
    plant = PhysicsSlave()
    with pytest.raises(RunTimeout, match=r"took longer than 0.5 s \(stopped at t = 0.56"):
        run_controller(plant, settings, Maneuver(iterations=3), observers=[guard])
    assert guard._steps == StepGuard.CLOCK_EVERY == 256
    loop = ClosedLoop(PhysicsSlave(), ControllerSlave(make_controller(settings, 0.01)),
                      Maneuver(), observers=[StepGuard()])
    _INTERRUPT["requested"] = signal.SIGINT
    try:
        with pytest.raises(KeyboardInterrupt):
            loop.iteration(1)
    finally:
        _INTERRUPT["requested"] = 0
    assert loop.execution.k == 1
    assert len(loop.observer._plant_rows) == 2  # the initial state and the step done
