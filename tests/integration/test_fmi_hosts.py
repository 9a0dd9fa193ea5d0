"""The FMUs in other FMI hosts: libcosim, the project's master and ecos (pip ``ecospy``, a
C++ co-simulation engine: its Python library and its command line) run FrictionPlant.fmu
through a force pulse with non-default parameters, and ClosedLoop.ssp with its one parameter
set, and give fmpy's and the master's trajectories to 1e-12 m. Each test prints the figure it
measured (``pytest -s``: lines starting ``host matrix:``).

ecos needs Debian's ``libtbb12``; its command line is a non-Python host, so it runs with
``LD_PRELOAD`` set to this interpreter's libpython (``papwc hostenv``). Outside CI a machine
without ecos skips these tests; in CI (``CI=true``) they fail instead.
"""

from __future__ import annotations

import csv
import os
import shutil
import stat
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest

from papwc.fmubuild.ssp_writer import PARAMETER_SET, build_closed_loop_ssp
from papwc.host_environment import libpython
from papwc.master.ssp_runner import read_ssp, run_ssp

PROJECT_DIR = Path(__file__).resolve().parents[2]
PAPER = PROJECT_DIR / "scenarios" / "paper.toml"
TOL_X = 1e-12  # m
#: The force pulse and the non-default plant parameters of the plant runs.
PULSE_U, PULSE_END, STEP, STOP = 250.0, 0.04, 0.01, 0.3  # N, s, s, s
PLANT = {"m": 90.0, "f_c": 60.0, "f_s": 85.0, "c": 350.0, "x0": 0.002, "v0": 0.0,
         "x_resolution": 1e-6}
#: ecos's CSV writes reals with 6 decimals; a probe FMU (PapwcTrivial: y = u) fed through a
#: connection with this factor carries x with all its digits.
SCALE = 1e12


def report(host: str, case: str, error: float) -> None:
    """Print a measured figure of the host matrix (shown with ``pytest -s``)."""
    print(f"\nhost matrix: {host} | {case} | {error!r} m")


def max_error(a: list[float], b: list[float]) -> float:
    return max(abs(p - q) for p, q in zip(a, b, strict=False))


def _ecos_missing(reason: str):
    if os.environ.get("CI") == "true":
        pytest.fail(f"ecos is required in CI: {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def ecospy():
    try:
        import ecospy as module
    except (ImportError, OSError) as exc:  # OSError: libtbb.so.12 missing
        _ecos_missing(f"ecospy cannot be imported: {exc}")
    from ecospy.lib import EcosLib

    EcosLib.set_log_level("warn")
    return module


@pytest.fixture(scope="module")
def ecos_cli(ecospy, tmp_path_factory) -> Path:
    """The ecos executable shipped in ecospy (copied and made executable if the wheel's is not)."""
    folder = Path(ecospy.__file__).parent / "binaries"
    binary = folder / "ecos"
    if not binary.is_file():
        _ecos_missing(f"no ecos executable in {folder}")
    if not os.access(binary, os.X_OK):
        copy = tmp_path_factory.mktemp("ecosbin")
        for name in ("ecos", "proxyfmu"):
            if (folder / name).is_file():
                shutil.copy(folder / name, copy / name)
                (copy / name).chmod((copy / name).stat().st_mode | stat.S_IXUSR)
        binary = copy / "ecos"
    return binary


def run_cli(ecos: Path, cwd: Path, *args: str) -> Path:
    """Run ``ecos simulate`` in ``cwd`` with LD_PRELOAD set; return the CSV it wrote."""
    env = {**os.environ, "LD_PRELOAD": str(libpython())}
    done = subprocess.run([str(ecos), "simulate", *args, "-l", "warn"], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    (path,) = cwd.glob("*.csv")
    return path


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path) as f:
        return [{k.strip(): v.strip() for k, v in row.items()}
                for row in csv.DictReader(f, skipinitialspace=True)]


def fmpy_pulse_x(fmu: Path) -> list[float]:
    """x(t_k), k = 0..n, of fmpy's ``simulate_fmu`` through the pulse."""
    import numpy as np
    from fmpy import simulate_fmu

    signal = np.array([(0.0, PULSE_U), (PULSE_END, PULSE_U), (PULSE_END, 0.0), (1.0, 0.0)],
                      dtype=[("time", np.float64), ("u", np.float64)])
    result = simulate_fmu(str(fmu), start_values=PLANT, input=signal, output_interval=STEP,
                          stop_time=STOP, output=["x"])
    return [float(x) for x in result["x"]]


def with_probe(ssp: Path, trivial_fmu: Path, target: Path, source: str) -> Path:
    """``ssp`` with a probe component fed ``source`` (``component.variable``) times SCALE."""
    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
          "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
          "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
          "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
          "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/"
                 "oms.xsd"}
    for prefix, uri in ns.items():  # ecos reads the prefixes literally
        ET.register_namespace(prefix, uri)
    with zipfile.ZipFile(ssp) as src:
        members = {name: src.read(name) for name in src.namelist()}
    root = ET.fromstring(members["SystemStructure.ssd"])
    system = root.find("ssd:System", ns)
    probe = ET.SubElement(system.find("ssd:Elements", ns), f"{{{ns['ssd']}}}Component",
                          name="probe", type="application/x-fmu-sharedlibrary",
                          source="resources/PapwcTrivial.fmu")
    connectors = ET.SubElement(probe, f"{{{ns['ssd']}}}Connectors")
    for name, kind in (("u", "input"), ("y", "output")):
        connector = ET.SubElement(connectors, f"{{{ns['ssd']}}}Connector", name=name, kind=kind)
        ET.SubElement(connector, f"{{{ns['ssc']}}}Real")
    element, variable = source.split(".")
    connection = ET.SubElement(system.find("ssd:Connections", ns), f"{{{ns['ssd']}}}Connection",
                               startElement=element, startConnector=variable,
                               endElement="probe", endConnector="u")
    ET.SubElement(connection, f"{{{ns['ssc']}}}LinearTransformation", factor=repr(SCALE),
                  offset="0.0")
    members["SystemStructure.ssd"] = ET.tostring(root, xml_declaration=True, encoding="UTF-8")
    members["resources/PapwcTrivial.fmu"] = trivial_fmu.read_bytes()
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as dst:
        for name, data in members.items():
            dst.writestr(name, data)
    return target


def plant_ssp(plant_fmu: Path, target: Path) -> Path:
    """A one-component SSP of FrictionPlant.fmu binding PLANT in the set ``params``."""
    values = "".join(f'<ssv:Parameter name="{k}"><ssv:Real value="{v!r}"/></ssv:Parameter>'
                     for k, v in PLANT.items())
    ssd = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    version="1.0" name="Pulse">
  <ssd:System name="Pulse"><ssd:Elements>
    <ssd:Component name="plant" type="application/x-fmu-sharedlibrary"
        source="resources/FrictionPlant.fmu">
      <ssd:Connectors>
        <ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>
        <ssd:Connector name="x" kind="output"><ssc:Real/></ssd:Connector>
      </ssd:Connectors>
      <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
        <ssv:ParameterSet version="1.0" name="params"><ssv:Parameters>{values}</ssv:Parameters>
        </ssv:ParameterSet>
      </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
    </ssd:Component>
  </ssd:Elements><ssd:Connections/></ssd:System>
</ssd:SystemStructureDescription>"""
    with zipfile.ZipFile(target, "w") as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        archive.writestr("resources/FrictionPlant.fmu", plant_fmu.read_bytes())
    return target


@pytest.fixture(scope="module")
def closed_loop(friction_plant_fmu, pulse_controller_fmu, tmp_path_factory) -> Path:
    return build_closed_loop_ssp(tmp_path_factory.mktemp("ssp"), PAPER, friction_plant_fmu,
                                 pulse_controller_fmu)


@pytest.fixture(scope="module")
def master_loop(closed_loop) -> dict[str, list]:
    """``papwc cosim``'s run of ClosedLoop.ssp (equal to libcosim's, see test_closed_loop_ssp)."""
    run = run_ssp(read_ssp(closed_loop), ["plant.x", "controller.pulses"])
    assert not run.error
    return {"x": [r[1] for r in run.rows], "pulses": [r[2] for r in run.rows]}


# --- the plant through a force pulse -----------------------------------------------------------


def test_ecos_library_runs_the_plant_like_fmpy(ecospy, friction_plant_fmu) -> None:
    from ecospy import EcosSimulation, EcosSimulationStructure

    structure = EcosSimulationStructure()
    structure.add_model("plant", str(friction_plant_fmu))
    structure.add_parameter_set("params", {f"plant::{k}": v for k, v in PLANT.items()})
    sim = EcosSimulation(structure=structure, step_size=STEP)
    sim.init(parameter_set="params")
    xs = [sim.get_real("plant::x")]
    n = round(STOP / STEP)
    for k in range(n):
        sim.set_real("plant::u", PULSE_U if k * STEP < PULSE_END - 1e-9 else 0.0)
        sim.step()
        xs.append(sim.get_real("plant::x"))
    sim.terminate()
    reference = fmpy_pulse_x(friction_plant_fmu)
    assert len(xs) == len(reference) == n + 1 and xs[0] == PLANT["x0"]
    report("ecos 0.7.2 library (ecospy)", "plant pulse, max |x - x_fmpy|", max_error(xs, reference))
    assert max(abs(a - b) for a, b in zip(xs, reference, strict=True)) <= TOL_X
    assert xs[-1] > PLANT["x0"] + 1e-3  # the pulse moved the mass


def test_ecos_command_line_runs_the_plant_like_fmpy(ecos_cli, friction_plant_fmu, trivial_fmu,
                                                    tmp_path) -> None:
    ssp = with_probe(plant_ssp(friction_plant_fmu, tmp_path / "plain.ssp"), trivial_fmu,
                     tmp_path / "Pulse.ssp", "plant.x")
    scenario = tmp_path / "pulse.xml"
    scenario.write_text(
        '<ecos:Scenario xmlns:ecos="http://github.com/Ecos-platform/libecos/resources/schema/'
        'ScenarioConfig" name="pulse" eps="1e-6">'
        f'<ecos:action t="0"><ecos:variable id="plant::u"><ecos:real value="{PULSE_U!r}"/>'
        '</ecos:variable></ecos:action>'
        f'<ecos:action t="{PULSE_END!r}"><ecos:variable id="plant::u"><ecos:real value="0.0"/>'
        '</ecos:variable></ecos:action></ecos:Scenario>')
    run = tmp_path / "run"
    run.mkdir()
    path = run_cli(ecos_cli, run, "--path", str(ssp), "--stepSize", repr(STEP), "--stopTime",
                   repr(STOP), "--parameterSet", "params", "--scenarioConfig", str(scenario))
    rows = read_csv(path)
    # row k: after step k; the probe shows x one step late (it copies its input at its step)
    xs = [float(r["probe::y[REAL]"]) / SCALE for r in rows[1:]]
    reference = fmpy_pulse_x(friction_plant_fmu)
    assert len(xs) >= round(STOP / STEP) - 1
    report("ecos 0.7.2 command line", "plant pulse, max |x - x_fmpy|", max_error(xs, reference))
    assert max(abs(a - b) for a, b in zip(xs, reference, strict=False)) <= TOL_X
    assert xs[-1] > PLANT["x0"] + 1e-3


def test_libcosim_runs_the_plant_like_fmpy(friction_plant_fmu) -> None:
    pytest.importorskip("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_step_size(round(STEP * 1e9))
    plant = execution.add_local_slave(CosimLocalSlave(str(friction_plant_fmu), "plant"))
    vr = {v.name.decode(): v.reference for v in execution.slave_variables(plant)}
    for name, value in PLANT.items():
        assert execution.real_initial_value(plant, vr[name], value)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    manipulator = CosimManipulator.create_override()
    execution.add_manipulator(manipulator)
    n = round(STOP / STEP)
    xs = []
    for k in range(n):
        manipulator.slave_real_values(plant, [vr["u"]],
                                      [PULSE_U if k * STEP < PULSE_END - 1e-9 else 0.0])
        assert execution.step()
        if k == 0:
            xs.append(PLANT["x0"])
        xs.append(observer.last_real_values(plant, [vr["x"]])[0])
    reference = fmpy_pulse_x(friction_plant_fmu)
    assert len(xs) == len(reference)
    report("libcosim (libcosimpy)", "plant pulse, max |x - x_fmpy|", max_error(xs, reference))
    assert max_error(xs, reference) <= TOL_X and xs[-1] > PLANT["x0"] + 1e-3


def test_the_master_runs_the_plant_like_fmpy(friction_plant_fmu) -> None:
    from papwc.master import FmuSlave

    with FmuSlave(friction_plant_fmu, "plant") as plant:
        plant.set_start_values(PLANT)
        (ix,) = plant.watch(["x"])
        set_u = plant.input_setter(["u"])
        plant.initialize(0.0)
        xs = [plant.values[ix]]
        for k in range(round(STOP / STEP)):
            set_u(PULSE_U if k * STEP < PULSE_END - 1e-9 else 0.0)
            plant.do_step(k * STEP, STEP)
            xs.append(plant.values[ix])
    reference = fmpy_pulse_x(friction_plant_fmu)
    report("papwc master (FmuSlave)", "plant pulse, max |x - x_fmpy|", max_error(xs, reference))
    assert len(xs) == len(reference) and max_error(xs, reference) <= TOL_X


# --- ClosedLoop.ssp ----------------------------------------------------------------------------


@pytest.mark.slow
def test_ecos_library_runs_the_closed_loop_like_the_master(ecospy, closed_loop,
                                                           master_loop) -> None:
    from ecospy import EcosSimulation

    sim = EcosSimulation(ssp_path=str(closed_loop), step_size=0.01)
    sim.init(parameter_set=PARAMETER_SET)
    xs = [sim.get_real("plant::x")]
    for _ in range(len(master_loop["x"]) - 1):
        sim.step()
        xs.append(sim.get_real("plant::x"))
    pulses = sim.get_integer("controller::pulses")
    kind = sim.get_string("controller::kind")
    sim.terminate()
    report("ecos 0.7.2 library (ecospy)", "ClosedLoop.ssp, max |x - x_master|",
           max_error(xs, master_loop["x"]))
    assert max(abs(a - b) for a, b in zip(xs, master_loop["x"], strict=True)) <= TOL_X
    assert pulses == master_loop["pulses"][-1] > 3 and kind == "papwc"


@pytest.mark.slow
def test_ecos_command_line_runs_the_closed_loop_like_the_master(
    ecos_cli, closed_loop, master_loop, trivial_fmu, tmp_path
) -> None:
    ssp = with_probe(closed_loop, trivial_fmu, tmp_path / "ClosedLoop.ssp", "plant.x")
    run = tmp_path / "run"
    run.mkdir()
    path = run_cli(ecos_cli, run, "--path", str(ssp), "--stepSize", "0.01", "--stopTime", "2",
                   "--parameterSet", PARAMETER_SET)
    rows = read_csv(path)
    xs = [float(r["probe::y[REAL]"]) / SCALE for r in rows[1:]]
    assert len(xs) >= len(master_loop["x"]) - 2
    report("ecos 0.7.2 command line", "ClosedLoop.ssp, max |x - x_master|",
           max_error(xs, master_loop["x"]))
    assert max(abs(a - b) for a, b in zip(xs, master_loop["x"], strict=False)) <= TOL_X
    assert int(rows[-1]["controller::pulses[INT]"]) == master_loop["pulses"][-1]
