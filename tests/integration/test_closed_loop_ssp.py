"""ClosedLoop.ssp is read alike by every SSP reader: one parameter set, no String binding,
the reference as a parameter, both fixed-step annotations, mode 0644; ``papwc cosim`` runs it
as libcosim does (to 1e-12 m) and as the Python master with ``timing = "delayed"``."""

from __future__ import annotations

import dataclasses
import stat
import zipfile
from pathlib import Path

import pytest

from papwc.controllers import make_controller
from papwc.fmubuild.ssp_writer import PARAMETER_SET, build_closed_loop_ssp, closed_loop_parameters
from papwc.master import PhysicsSlave, run_iteration
from papwc.master.ssp_runner import read_ssp, run_ssp
from papwc.model.controller_settings import KIND_CODES, OUTCOME_REASONS
from papwc.scenario import load_scenario

PROJECT_DIR = Path(__file__).resolve().parents[2]
PAPER = PROJECT_DIR / "scenarios" / "paper.toml"
PAPWC_BOUNDED = 2  # scenarios/paper.toml: the first papwc table (t_p_max = 0.03 s)
TOL_X = 1e-12  # m
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}


@pytest.fixture(scope="module")
def paper():
    return load_scenario(PAPER)


@pytest.fixture(scope="module")
def ssp(friction_plant_fmu: Path, pulse_controller_fmu: Path, tmp_path_factory) -> Path:
    return build_closed_loop_ssp(tmp_path_factory.mktemp("ssp"), PAPER, friction_plant_fmu,
                                 pulse_controller_fmu)


def ssd_root(path: Path):
    import xml.etree.ElementTree as ET

    with zipfile.ZipFile(path) as archive:
        return ET.fromstring(archive.read("SystemStructure.ssd"))


def master_x(scenario, index: int) -> list[float]:
    """x(t_k), k = 0..n, of the Python master with timing "delayed" (the in-process plant)."""
    maneuver = dataclasses.replace(scenario.maneuver, iterations=1, timing="delayed")
    plant = PhysicsSlave()
    plant.set_start_values(scenario.plant)
    trace = run_iteration(plant, make_controller(scenario.controllers[index], maneuver.T),
                          maneuver)
    assert not trace.error
    return list(trace.columns["x"])


def report(host: str, case: str, error: float) -> None:
    """Print a measured figure of the host matrix (shown with ``pytest -s``)."""
    print(f"\nhost matrix: {host} | {case} | {error!r} m")


def cosim_columns(path: Path, names: list[str], **kwargs) -> dict[str, list]:
    run = run_ssp(read_ssp(path), names, **kwargs)
    assert not run.error, run.error
    return {name: [row[i] for row in run.rows] for i, name in enumerate(run.columns)}


def test_one_parameter_set_of_types_every_reader_applies(ssp: Path, paper) -> None:
    root = ssd_root(ssp)
    sets = root.findall(".//ssd:ParameterBinding/ssd:ParameterValues/ssv:ParameterSet", NS)
    assert len(sets) == 2 and {s.get("name") for s in sets} == {PARAMETER_SET}
    types = {typed.tag.rsplit("}", 1)[1] for typed in root.findall(".//ssv:Parameter/*", NS)}
    # no ssv:String: fmpy and OMSimulator cannot set one (Booleans: every reader applies them)
    assert types == {"Real", "Integer", "Boolean"}
    bound = {(c.get("name"), p.get("name")): p[0].get("value")
             for c in root.findall(".//ssd:Component", NS)
             for p in c.findall(".//ssv:Parameter", NS)}
    assert bound[("controller", "kind_code")] == str(KIND_CODES.index("papwc") + 1)
    assert bound[("controller", "x_ref_offset")] == repr(paper.maneuver.x_ref)
    assert ("controller", "x_ref") not in bound and ("controller", "kind") not in bound
    # every setting the papwc kind reads is bound, generically from the settings table
    expected = closed_loop_parameters(paper, PAPWC_BOUNDED)["controller"]
    assert {name for (c, name) in bound if c == "controller"} == set(expected)


def test_fixed_step_annotations_for_libcosim_and_omsimulator(ssp: Path) -> None:
    from fmpy.ssp.ssd import read_ssd

    read_ssd(str(ssp), validate=True)  # still valid against the SSP 1.0 schema
    root = ssd_root(ssp)
    osp = root.find("ssd:DefaultExperiment//osp:FixedStepAlgorithm", NS)
    assert float(osp.get("baseStepSize")) == 0.01
    annotation = root.find("ssd:System/ssd:Annotations/ssc:Annotation", NS)
    assert annotation.get("type") == "org.openmodelica"
    master = annotation.find("oms:Annotations/oms:SimulationInformation/oms:FixedStepMaster", NS)
    assert master.get("description") == "oms-ma" and float(master.get("stepSize")) == 0.01
    assert float(master.get("relativeTolerance")) > 0.0


def test_archive_is_world_readable(ssp: Path) -> None:
    assert stat.S_IMODE(ssp.stat().st_mode) == 0o644


@pytest.mark.slow
@pytest.mark.libcosim
def test_papwc_cosim_equals_libcosim_and_the_delayed_master(ssp: Path, paper) -> None:
    pytest.importorskip("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    n = paper.maneuver.n_steps
    execution = CosimExecution.from_ssp_file(str(ssp))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    plant = execution.slave_index_from_instance_name("plant")
    controller = execution.slave_index_from_instance_name("controller")
    vr_p = {v.name.decode(): v.reference for v in execution.slave_variables(plant)}
    vr_c = {v.name.decode(): v.reference for v in execution.slave_variables(controller)}
    lib_x, lib_u = [], []
    for _ in range(n):
        assert execution.step()
        lib_x.append(observer.last_real_values(plant, [vr_p["x"]])[0])
        lib_u.append(observer.last_real_values(controller, [vr_c["u"]])[0])
    lib_pulses = observer.last_integer_values(controller, [vr_c["pulses"]])[0]

    ours = cosim_columns(ssp, ["plant.x", "controller.u", "controller.pulses"])
    assert ours["time"][-1] == pytest.approx(n * paper.maneuver.T, abs=1e-12)
    assert len(ours["plant.x"]) == n + 1
    lib_error = max(abs(a - b) for a, b in zip(ours["plant.x"][1:], lib_x, strict=True))
    report("libcosim (libcosimpy)", "ClosedLoop.ssp, max |x - x_master|", lib_error)
    assert lib_error <= TOL_X
    assert max(abs(a - b) for a, b in zip(ours["controller.u"][1:], lib_u, strict=True)) <= 1e-9
    assert ours["controller.pulses"][-1] == lib_pulses > 3
    reference = master_x(paper, PAPWC_BOUNDED)
    master_error = max(abs(a - b) for a, b in zip(ours["plant.x"], reference, strict=True))
    report("papwc cosim", "ClosedLoop.ssp vs the in-process delayed master, max |x - x_master|",
           master_error)
    assert master_error <= TOL_X
    assert abs(paper.maneuver.x_ref - ours["plant.x"][-1]) < 1e-3


@pytest.mark.slow
def test_fmpy_runs_the_bindings_passed_as_its_parameter_set(ssp: Path, paper) -> None:
    """fmpy applies no SSD binding itself; given them all (no String among them) it runs
    the same loop as ``papwc cosim``."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssd

    parameter_set = ParameterSet(name=PARAMETER_SET)
    for component in read_ssd(str(ssp)).system.elements:
        for binding in component.parameterBindings:
            for values in binding.parameterValues:
                for p in values.parameters:
                    parameter_set.parameters.append(Parameter(
                        name=f"{component.name}.{p.name}", type=p.type, value=p.value))
    result = simulate_ssp(str(ssp), stop_time=paper.maneuver.duration,
                          step_size=paper.maneuver.T, parameter_set=parameter_set)
    ours = cosim_columns(ssp, ["plant.x"])
    fmpy_x = list(result["plant.x"])
    assert len(fmpy_x) == paper.maneuver.n_steps
    error = max(abs(a - b) for a, b in zip(fmpy_x, ours["plant.x"][1:], strict=True))
    report("fmpy simulate_ssp (bindings passed)", "ClosedLoop.ssp, max |x - x_master|",
           float(error))
    assert error <= TOL_X


@pytest.mark.slow
def test_the_pwc_table_binds_its_own_settings_and_kind(friction_plant_fmu, pulse_controller_fmu,
                                                       tmp_path, paper) -> None:
    index = next(i for i, s in enumerate(paper.controllers) if s.kind == "pwc")
    ssp = build_closed_loop_ssp(tmp_path, PAPER, friction_plant_fmu, pulse_controller_fmu,
                                index)
    bound = closed_loop_parameters(paper, index)["controller"]
    assert bound["kind_code"] == KIND_CODES.index("pwc") + 1
    assert "F_inv0" in bound and "delta_inv" not in bound
    ours = cosim_columns(ssp, ["plant.x"])
    reference = master_x(paper, index)
    assert max(abs(a - b) for a, b in zip(ours["plant.x"], reference, strict=True)) <= TOL_X


def test_the_dual_loop_runs_in_closed_loop_ssp_as_in_the_delayed_master(
        friction_plant_fmu: Path, pulse_controller_fmu: Path, tmp_path: Path) -> None:
    """flexible_dual.toml's drive told its mode, one 10 mm maneuver: ClosedLoop.ssp connects
    the motor encoder (plant.x_d_meas -> controller.x_d_meas) for the dual_loop kind; papwc
    cosim (plant and controller side by side, the force one sample late) runs it as the
    Python master with timing "delayed" to 1e-12 m, and the controller acts on it: its probe
    finds the delay, no invalid_measurement, nearer the target than it started."""
    text = (PROJECT_DIR / "scenarios" / "flexible_dual.toml").read_text().split("[cases]")[0]
    scenario_path = tmp_path / "flexible_dual_plain.toml"
    scenario_path.write_text(text.replace("iterations = 3", "iterations = 1"))
    scenario = load_scenario(scenario_path)
    ssp = build_closed_loop_ssp(tmp_path / "out", scenario_path, friction_plant_fmu,
                                pulse_controller_fmu, controller_index=0)
    connections = {(c.get("startConnector"), c.get("endConnector"))
                   for c in ssd_root(ssp).findall(".//ssd:Connection", NS)}
    assert ("x_d_meas", "x_d_meas") in connections
    ours = cosim_columns(ssp, ["plant.x", "controller.outcome_reason", "controller.pulses"])
    master = master_x(scenario, 0)
    assert len(ours["plant.x"]) == len(master)
    assert max(abs(a - b) for a, b in zip(ours["plant.x"], master, strict=True)) <= TOL_X
    assert ours["controller.pulses"][-1] > 0
    invalid = OUTCOME_REASONS.index("invalid_measurement")
    assert invalid not in set(ours["controller.outcome_reason"])
    assert abs(scenario.maneuver.x_ref - ours["plant.x"][-1]) < 1e-5
