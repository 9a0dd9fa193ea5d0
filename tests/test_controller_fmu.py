"""PulseController.fmu through fmpy: model description, same forces as the master, refusals,
state, and instances of both FMUs side by side in one process."""

from __future__ import annotations

import dataclasses
import math
import zipfile
from ctypes import byref
from pathlib import Path

import pytest
from fmpy import extract, read_model_description
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
from fmpy.validation import validate_fmu


from papwc.controllers import Mode, make_controller
from papwc.controllers.settings import ControllerSettings
from papwc.master import Maneuver, run_iteration
from papwc.scenario import Scenario, load_scenario
from papwc.master import FmuSlave, PhysicsSlave

PROJECT_DIR = Path(__file__).resolve().parent.parent
PAPER = PROJECT_DIR / "scenarios" / "paper.toml"


@pytest.fixture(scope="module")
def controller_unzipped(pulse_controller_fmu: Path, tmp_path_factory) -> Path:
    """PulseController.fmu extracted once for this module."""
    return Path(extract(str(pulse_controller_fmu), str(tmp_path_factory.mktemp("pc"))))


@pytest.fixture(scope="module")
def paper() -> Scenario:
    return load_scenario(PAPER)


class Controller:
    """One PulseController instance through fmpy's FMU2Slave, its log messages kept."""

    def __init__(self, unzipdir: Path, name: str = "controller") -> None:
        self.md = read_model_description(str(unzipdir))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.messages: list[tuple[int, str]] = []
        self._callbacks = fmi2CallbackFunctions()
        self._logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.logger = self._logger
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(self._callbacks))
        self.fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=str(unzipdir),
            modelIdentifier="PulseController",
            instanceName=name,
        )
        self.fmu.instantiate(callbacks=self._callbacks, loggingOn=True)

    def _log(self, component, instance, status, category, message) -> None:
        self.messages.append((status, (message or b"").decode()))

    def set(self, name: str, value) -> None:
        var = self.vars[name]
        vr = [var.valueReference]
        if var.type == "Real":
            self.fmu.setReal(vr, [float(value)])
        elif var.type == "Integer":
            self.fmu.setInteger(vr, [int(value)])
        elif var.type == "Boolean":
            self.fmu.setBoolean(vr, [bool(value)])
        else:
            self.fmu.setString(vr, [value])

    def get(self, name: str):
        var = self.vars[name]
        vr = [var.valueReference]
        if var.type == "Real":
            return self.fmu.getReal(vr)[0]
        if var.type == "Integer":
            return self.fmu.getInteger(vr)[0]
        return self.fmu.getString(vr)[0].decode()

    def init(self, settings: ControllerSettings, T: float, x_ref: float) -> None:
        """Set the settings (None -> -1), T and x_ref; run the initialization."""
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name in ControllerSettings.field_names():
            value = getattr(settings, ControllerSettings.KEY_ALIASES.get(name, name))
            self.set(name, -1.0 if value is None else value)
        self.set("T", T)
        self.set("x_ref", x_ref)
        self.fmu.exitInitializationMode()

    def sample(self, t: float, x_meas: float, h: float) -> float:
        self.set("x_meas", x_meas)
        self.fmu.doStep(t, h)
        return self.get("u")

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


def master_forces(settings: ControllerSettings, plant_params: dict, maneuver: Maneuver) -> list:
    """Forces u_k (N) of the in-process controller in one iteration, immediate timing."""
    plant = PhysicsSlave()
    plant.set_parameters(plant_params)
    plant.initialize()
    maneuver = dataclasses.replace(maneuver, iterations=1, timing="immediate")
    trace = run_iteration(plant, make_controller(settings, maneuver.T), maneuver)
    return [row[5] for row in trace.rows[:-1]]


def fmu_forces(
    controller: Controller, settings: ControllerSettings, plant_params: dict, man: Maneuver
) -> list:
    """Forces u_k (N) of the controller FMU closing the loop around PhysicsSlave."""
    controller.init(settings, man.T, man.x_ref)
    plant = PhysicsSlave()
    plant.set_parameters(plant_params)
    plant.initialize()
    forces = []
    for k in range(man.n_steps):
        t = k * man.T
        u = controller.sample(t, plant.get_outputs()[2], man.T)
        forces.append(u)
        plant.set_input(u)
        plant.do_step(t, man.T)
    return forces


#: Coarse feedback (x_ref beyond e_band), explicit optional settings, rest over 2 samples.
CUSTOM = ControllerSettings(
    kind="pwc", f_p_max=300.0, t_p_max=0.05, K_c=0.6, tolerance=1e-5, f_p_min=120.0,
    k_p=20000.0, k_d=2500.0, rest_samples=2, e_band=0.005,
)  # fmt: skip


def test_model_description(pulse_controller_fmu: Path) -> None:
    assert validate_fmu(str(pulse_controller_fmu)) == []
    md = read_model_description(str(pulse_controller_fmu))
    cs = md.coSimulation
    assert cs.modelIdentifier == "PulseController"
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert not cs.canHandleVariableCommunicationStepSize
    variables = {v.name: v for v in md.modelVariables}
    settings = set(ControllerSettings.field_names())
    assert {n for n, v in variables.items() if v.causality == "parameter"} == settings | {"T"}
    assert {n for n, v in variables.items() if v.causality == "input"} == {"x_meas", "x_ref"}
    outputs = {n for n, v in variables.items() if v.causality == "output"}
    assert outputs == {"u", "b_hat", "f_c_hat", "pulses", "mode"}
    for name, var in variables.items():
        assert var.description, name
        if var.type == "Real":
            assert var.unit == PULSE_CONTROLLER_UNITS[name], name
    assert {u.name for u in md.unitDefinitions} >= {"m", "N", "s", "m/s2", "N/m", "s4"}
    assert variables["kind"].type == "String" and variables["kind"].start == "papwc"
    assert float(variables["t_p_max"].start) == math.inf
    assert variables["u"].initial == "exact" and float(variables["u"].start) == 0.0
    assert variables["mode"].start == str(Mode.PULSE)
    with zipfile.ZipFile(pulse_controller_fmu) as archive:
        names = archive.namelist()
    assert "resources/papwc_pulse_core/base.py" in names
    assert "resources/PulseController.py" in names
    assert "documentation/readme.md" in names
    assert not any(n.startswith("resources/papwc/") or "papwc_stickslip" in n for n in names)


@pytest.mark.parametrize(
    "index", [0, 1, 2, 3, None], ids=["pwc", "pwc_inf", "papwc", "papwc_inf", "custom"]
)
def test_fmu_forces_equal_in_process_controller(
    controller_unzipped: Path, paper: Scenario, index: int | None
) -> None:
    maneuver = paper.maneuver
    if index is None:
        settings = CUSTOM
        maneuver = dataclasses.replace(maneuver, x_ref=0.03)
    else:
        settings = paper.controllers[index]
    reference = master_forces(settings, paper.plant, maneuver)
    controller = Controller(controller_unzipped)
    try:
        forces = fmu_forces(controller, settings, paper.plant, maneuver)
        assert forces == reference
        assert controller.get("pulses") > 0
        in_process = make_controller(settings, maneuver.T)
        assert controller.get("kind") == settings.kind
        if index is None:
            assert max(abs(u) for u in forces) == settings.f_p_max  # coarse, saturated
            assert in_process.k_p == 20000.0 and in_process.f_p_floor == 120.0
    finally:
        controller.close()


def test_estimates_before_and_after_initialization(controller_unzipped: Path, paper) -> None:
    settings = paper.controllers[2]
    controller = Controller(controller_unzipped)
    try:
        controller.fmu.setupExperiment(startTime=0.0)
        controller.fmu.enterInitializationMode()
        controller.set("f_c_est", 60.0)
        expected = make_controller(dataclasses.replace(settings, f_c_est=60.0), 0.01).estimates()
        assert controller.get("f_c_hat") == pytest.approx(expected["f_c_hat"], rel=1e-12)
        controller.set("K_c", 3.0)  # invalid: the estimates are undefined until fixed
        assert math.isnan(controller.get("b_hat"))
    finally:
        controller.close()


def test_wrong_communication_step_is_discarded(controller_unzipped: Path, paper) -> None:
    controller = Controller(controller_unzipped)
    try:
        controller.init(paper.controllers[2], 0.01, 0.01)
        with pytest.raises(FMICallException) as info:
            controller.sample(0.0, 0.0, 0.02)
        assert info.value.status == fmi2Discard
        status, message = controller.messages[-1]
        assert status == fmi2Discard
        assert "communication step size 0.02 s differs from the sample period T = 0.01 s" in (
            message
        )
        assert controller.get("u") == 0.0 and controller.get("pulses") == 0
        # Within the relative tolerance of 1e-9 (libcosim's steps on its nanosecond grid).
        assert controller.sample(0.0, 0.0, 0.01 * (1 + 5e-10)) == 300.0
        with pytest.raises(FMICallException):
            controller.sample(0.01, math.nan, 0.01)
        assert "input x_meas = nan m is not finite" in controller.messages[-1][1]
    finally:
        controller.close()


@pytest.mark.parametrize(
    "name, value, expected",
    [
        ("K_c", 2.5, "parameter K_c = 2.5: must satisfy 0 < K_c < 2 (Eq. (6))"),
        ("kind", "bogus", "parameter kind = 'bogus': must be one of"),
        ("k_p", -5.0, "parameter k_p = -5.0: must be > 0 N/m; -1 selects the default"),
        ("T", 0.0, "parameter T = 0.0 s: must be a finite number > 0 s"),
        ("rest_samples", 0, "parameter rest_samples = 0: must be a whole number >= 1"),
    ],
)
def test_invalid_settings_are_refused(
    controller_unzipped: Path, paper, name: str, value, expected: str
) -> None:
    controller = Controller(controller_unzipped)
    try:
        controller.fmu.setupExperiment(startTime=0.0)
        controller.fmu.enterInitializationMode()
        controller.set(name, value)
        controller.fmu.exitInitializationMode()  # fmi2OK: the refusal is logged
        errors = [m for s, m in controller.messages if s == fmi2Error]
        assert len(errors) == 1 and expected in errors[0], controller.messages
        assert "initialization refused" in errors[0]
        with pytest.raises(FMICallException) as info:
            controller.sample(0.0, 0.0, 0.01)
        assert info.value.status == fmi2Discard
        assert expected in controller.messages[-1][1]
        assert controller.get("u") == 0.0
    finally:
        controller.close()


def test_state_get_set_and_serialization(controller_unzipped: Path, paper) -> None:
    settings = paper.controllers[2]
    T = 0.01
    controller = Controller(controller_unzipped, "a")
    other = Controller(controller_unzipped, "b")
    try:
        controller.init(settings, T, 0.01)
        plant = PhysicsSlave()
        plant.set_parameters(paper.plant)
        plant.initialize()

        def run(ctrl: Controller, k0: int, n: int, x: float, v: float) -> list[float]:
            plant.x, plant.v = x, v
            out = []
            for k in range(k0, k0 + n):
                u = ctrl.sample(k * T, plant.get_outputs()[2], T)
                plant.set_input(u)
                plant.do_step(k * T, T)
                out.append((u, ctrl.get("pulses"), ctrl.get("mode"), ctrl.get("b_hat")))
            return out

        run(controller, 0, 40, 0.0, 0.0)
        x, v = plant.x, plant.v
        state = controller.fmu.getFMUstate()
        data = controller.fmu.serializeFMUstate(state)
        first = run(controller, 40, 80, x, v)
        assert len({row[1] for row in first}) > 1  # pulses happen after the snapshot
        controller.fmu.setFMUstate(state)
        assert run(controller, 40, 80, x, v) == first
        # A fresh instance with different parameters takes the serialized state whole.
        other.init(paper.controllers[0], 0.02, 0.5)
        restored = other.fmu.deSerializeFMUstate(data)
        other.fmu.setFMUstate(restored)
        assert other.get("T") == T and other.get("kind") == "papwc"
        assert run(other, 40, 80, x, v) == first
        controller.fmu.freeFMUstate(state)
        other.fmu.freeFMUstate(restored)
    finally:
        controller.close()
        other.close()


def test_instances_of_both_fmus_run_independently(
    controller_unzipped: Path, friction_plant_fmu: Path, paper
) -> None:
    """Two plant FMUs and two controller FMUs, stepped interleaved in one process."""
    T = 0.01
    cases = [
        (paper.controllers[2], {**paper.plant}, 0.01),
        (paper.controllers[0], {**paper.plant, "f_c": 90.0, "x_resolution": 1e-6}, -0.006),
    ]
    plants, controllers, forces = [], [], []
    try:
        for i, (settings, params, x_ref) in enumerate(cases):
            plant = FmuSlave(friction_plant_fmu, instance_name=f"plant{i}")
            plant.set_parameters(params)
            plant.initialize(0.0)
            plants.append(plant)
            controller = Controller(controller_unzipped, f"controller{i}")
            controller.init(settings, T, x_ref)
            controllers.append(controller)
            forces.append([])
        for k in range(paper.maneuver.n_steps):
            for plant, controller, out in zip(plants, controllers, forces, strict=True):
                u = controller.sample(k * T, plant.get_outputs()[2], T)
                out.append(u)
                plant.set_input(u)
                plant.do_step(k * T, T)
        for (settings, params, x_ref), out in zip(cases, forces, strict=True):
            maneuver = dataclasses.replace(paper.maneuver, x_ref=x_ref)
            assert out == master_forces(settings, params, maneuver)
        assert forces[0] != forces[1]
    finally:
        for plant in plants:
            plant.close()
        for controller in controllers:
            controller.close()
