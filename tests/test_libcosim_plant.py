"""FrictionPlant.fmu in libcosim (through libcosimpy) gives fmpy's trajectory."""

from __future__ import annotations

from pathlib import Path

import pytest
from fmpy import read_model_description
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

from papwc.model.stickslip import simulate

pytestmark = pytest.mark.libcosim

T_NS = 10_000_000  # 0.01 s in libcosim's integer nanoseconds
T = 0.01
PARAMS = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
U_SEQ = [300.0] * 5 + [0.0] * 20 + [120.0] * 10 + [-300.0] * 5 + [0.0] * 15
U_SEQ += [250.0] * 7 + [-200.0] * 4 + [0.0] * 34
TOL = 1e-12


def fmpy_trajectory(fmu: Path, u_seq: list[float]) -> list[float]:
    """Positions (m) at every step of fmpy's FMU2Slave at T with the ZOH force u_seq (N)."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipdir = extract(str(fmu))
    slave = FMU2Slave(
        guid=md.guid, unzipDirectory=unzipdir, modelIdentifier="FrictionPlant", instanceName="p"
    )
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    xs = [slave.getReal([vr["x"]])[0]]
    for k, u in enumerate(u_seq):
        slave.setReal([vr["u"]], [u])
        slave.doStep(k * T, T)
        xs.append(slave.getReal([vr["x"]])[0])
    slave.terminate()
    slave.freeInstance()
    return xs


def test_libcosim_trajectory_equals_fmpy(friction_plant_fmu: Path) -> None:
    md = read_model_description(str(friction_plant_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    execution = CosimExecution.from_step_size(T_NS)
    slave = CosimLocalSlave(fmu_path=str(friction_plant_fmu), instance_name="plant")
    index = execution.add_local_slave(slave)
    override = CosimManipulator.create_override()
    execution.add_manipulator(override)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)

    xs = [0.0]
    for k, u in enumerate(U_SEQ):
        assert override.slave_real_values(index, [vr["u"]], [u])
        assert execution.step(), f"libcosim step {k} failed: {execution.status()}"
        xs.append(observer.last_real_values(index, [vr["x"]])[0])
    assert execution.status().current_time == len(U_SEQ) * T_NS

    reference = fmpy_trajectory(friction_plant_fmu, U_SEQ)
    exact = [x for x, _ in simulate(U_SEQ, T, **PARAMS)]
    assert len(xs) == len(reference) == len(exact)
    for k, (x, x_fmpy, x_exact) in enumerate(zip(xs, reference, exact, strict=True)):
        assert abs(x - x_fmpy) <= TOL, f"step {k}"
        assert abs(x - x_exact) <= TOL, f"step {k}"


def test_libcosim_stops_with_an_error_on_a_non_finite_force(friction_plant_fmu: Path) -> None:
    """fmi2Discard on a NaN force is an error for libcosim: the step fails, no crash."""
    md = read_model_description(str(friction_plant_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    execution = CosimExecution.from_step_size(T_NS)
    index = execution.add_local_slave(CosimLocalSlave(str(friction_plant_fmu), "plant"))
    override = CosimManipulator.create_override()
    execution.add_manipulator(override)
    override.slave_real_values(index, [vr["u"]], [300.0])
    assert execution.step()
    override.slave_real_values(index, [vr["u"]], [float("nan")])
    assert not execution.step()


def test_libcosim_stops_with_an_error_on_an_invalid_parameter(friction_plant_fmu: Path) -> None:
    """An invalid parameter makes the first step fail; the host process survives."""
    md = read_model_description(str(friction_plant_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    execution = CosimExecution.from_step_size(T_NS)
    index = execution.add_local_slave(CosimLocalSlave(str(friction_plant_fmu), "plant"))
    assert execution.real_initial_value(index, vr["f_s"], 50.0)
    assert not execution.step()
