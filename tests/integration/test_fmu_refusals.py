"""FMU states, refused calls and the master's logger, through fmpy (issue 13, groups 7 and 10;
issue 44: a step past a defined stop time, a state of a refused initialization).

The pythonfmu FMUs (PulseController and the pythonfmu FrictionPlant, ``papwc build
--backend pythonfmu``; the native FrictionPlant's refusals are in test_native_fmu.py): a
state that does not parse or does not fit is refused before anything changes and the
instance keeps stepping correctly; parameters and outputs set after initialization,
inputs and steps after fmi2Terminate are refused; the master (FmuSlave) frees every state
it takes, routes each message to the instance that logged it and takes any logger
argument, NULL included.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from fmpy.fmi1 import FMICallException
from harness import FMI2_DISCARD, FMI2_ERROR, FmuInstance, table_1

from papwc.controllers import make_controller
from papwc.controllers.settings import ControllerSettings
from papwc.errors import FmuError
from papwc.master import FmuSlave
from papwc.model.stickslip import step

T = 0.01
PLANT = table_1()


def started(unzipped: Path, name: str) -> FmuInstance:
    """An instance of the extracted FMU, initialized with its start values."""
    fmu = FmuInstance(unzipped, name)
    fmu.init()
    return fmu


def state_bytes(fmu: FmuInstance) -> bytes:
    """The instance's state, got and serialized."""
    state = fmu.fmu.getFMUstate()
    data = fmu.fmu.serializeFMUstate(state)
    fmu.fmu.freeFMUstate(state)
    return bytes(data)


def try_state(fmu: FmuInstance, data: bytes) -> str:
    """deSerializeFMUstate, setFMUstate, freeFMUstate; return the message logged."""
    before = len(fmu.messages)
    state = fmu.fmu.deSerializeFMUstate(data)
    fmu.fmu.setFMUstate(state)
    fmu.fmu.freeFMUstate(state)
    new = [m.text for m in fmu.messages[before:] if m.status == 3]
    assert len(new) == 1, fmu.messages[before:]
    return new[0]


@pytest.fixture
def instances(pythonfmu_plant_unzipped: Path, pulse_controller_python_unzipped: Path):
    """The pythonfmu builds (the native ones: test_native_fmu.py,
    test_native_controller_fmu.py)."""
    plant = started(pythonfmu_plant_unzipped, "plant")
    controller = started(pulse_controller_python_unzipped, "controller")
    yield plant, controller
    plant.close()
    controller.close()


def edited(data: bytes, **fields) -> bytes:
    state = json.loads(data)
    state["fields"].update(fields)
    return json.dumps(state).encode()


def bad_states(own: bytes, other: bytes) -> list[tuple[bytes, str]]:
    return [
        (b"{}", "it names no model"),
        (b"\x00\xff garbage", "the serialized state is not one of this FMU"),
        (b"[1, 2]", "the serialized state is not one of this FMU"),
        (other, "the state belongs to"),
        (edited(own, time=float("nan")), "field time = nan is not a finite number"),
        (edited(own, _ready="yes"), "field _ready = 'yes' is not true or false"),
        (json.dumps({**json.loads(own), "fields": {"x": 1.0}}).encode(),
         "does not hold this FMU's fields"),
    ]


def test_a_plant_state_that_does_not_fit_is_refused_and_the_plant_steps_on(instances) -> None:
    plant, controller = instances
    own, other = state_bytes(plant), state_bytes(controller)
    cases = bad_states(own, other) + [
        (edited(own, m=-1.0), "its parameters are invalid: m = -1.0 kg"),
        (edited(own, x="far"), "field x = 'far' is not a Real"),
    ]
    x, v = 0.0, 0.0
    for k, (data, words) in enumerate(cases):
        message = try_state(plant, data)
        assert "setFMUstate refused" in message and words in message, message
        assert "the instance keeps its state" in message
        u = 300.0 if k % 3 == 0 else 0.0
        plant.advance(T, u=u)
        x, v = step(x, v, u, T, PLANT["m"], PLANT["f_c"], PLANT["f_s"], PLANT["c"])
        assert (plant.get("x"), plant.get("v")) == (x, v)


def test_a_controller_state_that_does_not_fit_is_refused_and_it_controls_on(instances) -> None:
    plant, controller = instances
    own, other = state_bytes(controller), state_bytes(plant)
    cases = bad_states(own, other) + [
        (edited(own, K_c=5.0), "its parameters are invalid: K_c = 5.0"),
        (edited(own, _controller=[1.0, 2.0]), "the controller state does not fit"),
        (edited(own, _controller={"sequencer.mode": 1}), "the controller state does not fit"),
    ]
    reference = make_controller(ControllerSettings(), T)
    x_ref = 0.01
    controller.set("x_ref", x_ref)
    for k, (data, words) in enumerate(cases):
        message = try_state(controller, data)
        assert "setFMUstate refused" in message and words in message, message
        x_meas = 1e-3 * k
        controller.advance(T, x_meas=x_meas)
        assert controller.get("u") == reference.update(controller.t - T, x_meas, x_ref)


@pytest.mark.parametrize("which, parameter, output", [("plant", "m", "x"),
                                                      ("controller", "K_c", "u")])
def test_parameters_and_outputs_set_after_initialization_are_refused(
        instances, which, parameter, output) -> None:
    fmu = dict(zip(("plant", "controller"), instances, strict=True))[which]
    before = state_bytes(fmu)
    kept = fmu.get(parameter), fmu.get(output)
    for name in (parameter, output):
        count = len(fmu.messages)
        fmu.set(name, 1.5)
        (status, _, message), = fmu.messages[count:]
        assert status == 3 and name in message and "refused" in message, message
    assert (fmu.get(parameter), fmu.get(output)) == kept
    assert state_bytes(fmu) == before


def test_calls_after_terminate_are_refused(pythonfmu_plant_unzipped: Path) -> None:
    plant = started(pythonfmu_plant_unzipped, "plant")
    plant.advance(T, u=300.0)
    x = plant.get("x")
    plant.fmu.terminate()
    plant.set("u", -300.0)
    assert "input u cannot be set after fmi2Terminate" in plant.messages[-1].text
    with pytest.raises(FMICallException) as info:
        plant.fmu.doStep(plant.t, T)
    assert info.value.status == 2  # Discard
    assert "the simulation was terminated" in plant.messages[-1].text
    assert plant.get("x") == x and plant.get("u") == 300.0
    plant.fmu.freeInstance()


def test_the_master_frees_every_state_it_takes(friction_plant_fmu: Path) -> None:
    slave = FmuSlave(friction_plant_fmu)
    fmu = slave._fmu
    taken: list[object] = []
    freed: list[object] = []
    get, release = fmu.getFMUstate, fmu.freeFMUstate
    fmu.getFMUstate = lambda: taken.append(get()) or taken[-1]
    fmu.freeFMUstate = lambda state: freed.append(state) or release(state)
    slave.set_start_values(PLANT)
    slave.initialize()
    for _ in range(3):
        slave.do_step(0.0, T)
        slave.restart()
    slave.set_start_values({"c": 500.0})
    slave.initialize()
    slave.initialize()
    slave.close()
    assert len(taken) == 3 and [id(s) for s in freed] == [id(s) for s in taken]


def test_the_master_logger_takes_every_argument(pythonfmu_plant_fmu: Path) -> None:
    slave = FmuSlave(pythonfmu_plant_fmu, name="p")
    env = slave._environment
    slave._logger(env, None, 3, None, None)
    slave._logger(env, b"p", 99, b"cat", b"\xff\xfe bytes")
    slave._logger(None, None, None, None, None)
    slave._logger(env, "p", "x", "c", "str")
    # through fmpy's proxy, which formats the message as printf does
    slave._callbacks.logger(env, b"p", 1, None, b"100%% done")
    assert list(slave.log)[-4:] == ["[Error] : ", "[status 99] cat: \ufffd\ufffd bytes",
                                    "[status 'x'] c: str", "[Warning] : 100% done"]
    # A Fatal the FMU logs itself: pythonfmu passes a NULL category.
    with pytest.raises(FmuError, match="fmi2GetReal at t = 0.0 s returned Fatal"):
        slave._call("fmi2GetReal", lambda: slave._fmu.getReal([9999]))
    assert slave.log[-1].startswith("[Fatal] : ") and "[getReal]" in slave.log[-1]
    slave.close()


def test_each_message_reaches_the_instance_that_logged_it(friction_plant_fmu: Path) -> None:
    a = FmuSlave(friction_plant_fmu, name="a")
    b = FmuSlave(friction_plant_fmu, name="b")
    a.set_start_values({"m": -1.0})
    with pytest.raises(FmuError, match=r"a: fmi2ExitInitializationMode .* refused the "
                                       r"parameters: \[Error\] logStatusError: a: parameter "
                                       r"m = -1.0 kg"):
        a.initialize()
    b.initialize()
    assert not any("parameter m" in m for m in b.log)
    a.close()
    b.close()


def test_a_percent_in_a_logged_value_is_shown_not_executed(pulse_controller_fmu: Path) -> None:
    code = textwrap.dedent(f"""
        from papwc.errors import FmuError
        from papwc.master import FmuSlave
        c = FmuSlave({str(pulse_controller_fmu)!r}, name="c%n%n")
        c.set_start_values({{"kind": "%s%s%s%n%n%n 100%"}})
        try:
            c.initialize()
        except FmuError as exc:
            print(exc)
        c.close()
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "parameter kind = '%s%s%s%n%n%n 100%': must be one of" in done.stdout
    assert "c%n%n: parameter" in done.stdout


def test_pulse_controller_refusals_are_not_silent(pulse_controller_python_fmu: Path, capfd,
                                                  monkeypatch) -> None:
    """Issue 27: pythonfmu returns fmi2OK for a refused set or setFMUstate (it cannot return
    fmi2Error); PulseControllerPython.fmu writes the refusal to stderr as well as logging it
    with status Error, and the master raises on it as on fmi2Error."""
    monkeypatch.setenv("PAPWC_FMU_STDERR", "1")
    with FmuSlave(pulse_controller_python_fmu, name="controller") as controller:
        controller.initialize()
        capfd.readouterr()
        with pytest.raises(FmuError, match=r"controller: setting K_c at t = 0.0 s was refused: "
                                           r"\[Error\] .*parameter K_c cannot be set after "
                                           r"initialization: 0.5 refused"):
            controller._set_now({"K_c": 0.5})
        err = capfd.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(
            "PulseControllerPython controller: parameter K_c cannot be set after "
            "initialization"), err
        assert "pythonfmu returns fmi2OK for this call" in err[0]


#: Both builds of FrictionPlant.fmu (the fixtures of their extracted copies) and the status
#: of a refused step: the native glue returns fmi2Error where FMI 2.0 asks for it; pythonfmu
#: 0.7.0 can return only fmi2Discard from doStep (the message is logged with status Error).
BUILDS = [("friction_plant_unzipped", FMI2_ERROR), ("pythonfmu_plant_unzipped", FMI2_DISCARD)]


@pytest.mark.parametrize("build, status", BUILDS, ids=["native", "pythonfmu"])
def test_a_step_past_the_defined_stop_time_is_refused(build, status, request, capfd,
                                                      monkeypatch) -> None:
    """Issue 44: with stopTimeDefined, stop 0.05 s, doStep(0, 1.0) returned fmi2OK."""
    monkeypatch.setenv("PAPWC_FMU_STDERR", "1")  # (papwc cosim and identify set it to 0)
    unzipped = request.getfixturevalue(build)
    fmu = FmuInstance(unzipped, "plant")
    fmu.fmu.setupExperiment(startTime=0.0, stopTime=0.05)
    fmu.fmu.enterInitializationMode()
    fmu.fmu.exitInitializationMode()
    with pytest.raises(FMICallException) as info:
        fmu.fmu.doStep(0.0, 1.0)
    assert info.value.status == status
    refused = fmu.logged(FMI2_ERROR)
    assert len(refused) == 1 and "doStep(t = 0.0 s, h = 1.0 s) refused: the step ends at t = " \
        "1.0 s, past the stop time 0.05 s that fmi2SetupExperiment defined" in refused[0]
    assert "past the stop time 0.05 s" in capfd.readouterr().err  # told with logging off too
    # Up to the stop time the plant steps (5 x 10 ms ends at 0.05 s within rounding) ...
    for _ in range(5):
        fmu.advance(T, u=300.0)
    x = fmu.get("x")
    assert x > 0.0
    # ... and not one step further; the state is left as it was.
    with pytest.raises(FMICallException) as info:
        fmu.fmu.doStep(fmu.t, T)
    assert info.value.status == status and fmu.get("x") == x
    assert "past the stop time 0.05 s" in fmu.logged(FMI2_ERROR)[-1]
    fmu.close()


@pytest.mark.parametrize("build", [b for b, _ in BUILDS], ids=["native", "pythonfmu"])
def test_a_stop_time_before_the_start_time_is_refused(build, request) -> None:
    fmu = FmuInstance(request.getfixturevalue(build), "plant")
    try:  # the native glue returns fmi2Error; pythonfmu returns fmi2OK and logs the refusal
        fmu.fmu.setupExperiment(startTime=1.0, stopTime=0.5)
    except FMICallException as exc:
        assert exc.status == FMI2_ERROR and "pythonfmu" not in build
    else:
        assert "pythonfmu" in build
    assert fmu.logged(FMI2_ERROR) == ["plant: fmi2SetupExperiment refused: stop time 0.5 s must "
                                      "be a finite number >= the start time 1.0 s"]
    fmu.fmu.freeInstance()


@pytest.mark.parametrize("build", [b for b, _ in BUILDS], ids=["native", "pythonfmu"])
def test_no_state_of_an_instance_whose_initialization_was_refused(build, request, capfd,
                                                                   monkeypatch) -> None:
    """Issue 44: a state taken from an instance whose initialization was refused was
    accepted by getFMUstate and setFMUstate, and the next doStep failed with no message."""
    monkeypatch.setenv("PAPWC_FMU_STDERR", "1")
    unzipped = request.getfixturevalue(build)
    bad = FmuInstance(unzipped, "bad", logging=False)
    bad.fmu.setupExperiment(startTime=0.0)
    bad.fmu.enterInitializationMode()
    bad.set("m", -1.0)
    try:
        bad.fmu.exitInitializationMode()  # native: fmi2Error; pythonfmu: logged
    except FMICallException:
        pass
    capfd.readouterr()
    good = started(unzipped, "good")
    if "pythonfmu" in build:  # pythonfmu cannot refuse getFMUstate: it refuses the state
        state = bad.fmu.getFMUstate()
        good.fmu.setFMUstate(state)
        assert "setFMUstate refused: the state was taken from an instance whose " \
               "initialization was refused (parameter m = -1.0 kg" in good.messages[-1].text
    else:
        with pytest.raises(FMICallException) as info:
            bad.fmu.getFMUstate()
        assert info.value.status == FMI2_ERROR
    err = capfd.readouterr().err
    assert ("FMUstate refused: fmi2ExitInitializationMode refused this instance's parameters "
            "(parameter m = -1.0 kg") in err, err
    good.advance(T, u=300.0)  # the instance that was given the state steps on
    assert good.get("x") == step(0.0, 0.0, 300.0, T, *PLANT.values())[0]
    good.close()
    bad.close()


@pytest.mark.parametrize("build", [b for b, _ in BUILDS], ids=["native", "pythonfmu"])
def test_a_step_after_a_state_of_initialization_mode_says_why(build, request, capfd,
                                                              monkeypatch) -> None:
    """A state taken in initialization mode (before it ended) and set into a stepping
    instance: the next doStep is refused and says so on stderr, logging off or not."""
    monkeypatch.setenv("PAPWC_FMU_STDERR", "1")
    unzipped = request.getfixturevalue(build)
    early = FmuInstance(unzipped, "early")
    early.fmu.setupExperiment(startTime=0.0)
    early.fmu.enterInitializationMode()
    state = early.fmu.getFMUstate()
    good = FmuInstance(unzipped, "good", logging=False)
    good.init()
    good.fmu.setFMUstate(state)
    capfd.readouterr()
    with pytest.raises(FMICallException):
        good.fmu.doStep(0.0, T)
    err = capfd.readouterr().err
    assert "good: doStep(t = 0.0 s, h = 0.01 s) refused: " in err, err
    assert "initialization" in err.split("refused: ", 1)[1]
    early.fmu.freeFMUstate(state)
    good.close(terminate=False)
    early.close(terminate=False)
