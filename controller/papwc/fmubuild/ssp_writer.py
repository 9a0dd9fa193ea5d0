"""Build ``ClosedLoop.ssp``: plant and pulse controller as one SSP 1.0 system.

The archive (mode 0644) holds ``SystemStructure.ssd`` and the two FMUs in
``resources/``:

- component ``plant`` (``resources/FrictionPlant.fmu``) and component
  ``controller``: ``resources/PulseController.fmu``, the native C controller, for the kinds
  it implements (pwc, papwc, pid), else ``resources/PulseControllerPython.fmu`` (the
  pythonfmu build, every kind), so that a host with no Python runs the closed loop of the
  paper's controllers;
- connections ``plant.x_meas -> controller.x_meas`` (the encoder output: what a
  real controller sees; it equals ``x`` with the ideal encoder,
  ``x_resolution = 0``) and ``controller.u -> plant.u``; for a controller kind that reads
  the motor encoder (``dual_loop``) also ``plant.x_d_meas -> controller.x_d_meas``;
- inline parameter bindings (``ssd:ParameterValues``), in one parameter set
  named :data:`PARAMETER_SET` in both components (ecos applies one named set at
  a time; libcosim applies every binding), of types every SSP reader can set
  (Real and Integer, no String): for the plant ``m``, ``f_c``, ``f_s``, ``c``,
  ``x_resolution``, ``x0 = v0 = 0``; for the controller ``kind_code`` (the
  Integer that names the kind; the String ``kind`` keeps its start value), every
  setting the scenario's ``[[controller]]`` table gives for that kind, the
  sample period ``T`` and the reference as the parameter ``x_ref_offset``
  (an SSP 1.0 binding may set FMI 2.0 variables with ``initial = "exact"`` or
  ``"approx"``, which inputs are not, so the input ``x_ref`` is left at 0);
- a ``DefaultExperiment`` from 0 s to the maneuver's duration (``n_steps * T``,
  the samples the Python master runs), with the
  Open Simulation Platform annotation ``osp:FixedStepAlgorithm`` whose
  ``baseStepSize`` is ``T`` (libcosim), and on the system OMSimulator's
  ``oms:SimulationInformation`` with an ``oms:FixedStepMaster`` of step ``T``
  (per OMSimulator's ``schema/oms.xsd``).

A master that steps both components side by side at ``T`` (libcosim's
fixed-step algorithm) gives the plant over ``[t_k, t_(k+1)]`` the force
computed from ``x_meas(t_k - T)``: the Python master's ``timing = "delayed"``.

libcosim (``libcosimpy.CosimExecution.CosimExecution.from_ssp_file``), ecos
(``ecos simulate --parameterSet scenario``) and ``papwc cosim`` apply the
bindings. fmpy's ``fmpy.ssp.simulation.simulate_ssp`` reads the structure but
applies no bindings (they can be passed as its ``parameter_set``, names
prefixed with the component).
"""

from __future__ import annotations

import math
import os
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from papwc.controllers.settings import ControllerSettings, settings_for_kind
from papwc.errors import BuildError, OutputError, PapwcError
from papwc.fmubuild.model_description import read_model_description
from papwc.model.controller_settings import (
    CONTROLLER_INPUTS,
    CONTROLLER_OUTPUTS,
    CONTROLLER_SETTINGS,
    KIND_CODES,
    fmu_parameters,
)
from papwc.model.plant import PLANT_DEFAULTS, PLANT_INPUTS, PLANT_OUTPUTS, SCENARIO_PLANT_FIELDS
from papwc.model.units import UNIT_DEFINITIONS
from papwc.scenario import Scenario, load_scenario

__all__ = [
    "CONNECTIONS",
    "CONTROLLER",
    "MOTOR_CONNECTION",
    "PARAMETER_SET",
    "PLANT",
    "build_closed_loop_ssp",
    "closed_loop_parameters",
    "default_controller_index",
    "libcosim_step_size",
]

#: Component names in the SSP.
PLANT = "plant"
CONTROLLER = "controller"

#: Name of the one parameter set that holds every binding (ecos's ``--parameterSet``).
PARAMETER_SET = "scenario"

#: Relative tolerance written with OMSimulator's fixed-step master (it reads one; a
#: fixed-step master of FMUs that do not iterate does not use it).
_OMS_RELATIVE_TOLERANCE = 1e-4

#: ``(start component, start connector, end component, end connector)``.
CONNECTIONS: tuple[tuple[str, str, str, str], ...] = (
    (PLANT, "x_meas", CONTROLLER, "x_meas"),
    (CONTROLLER, "u", PLANT, "u"),
)
#: The connection a controller that reads the motor encoder (dual_loop) needs as well.
MOTOR_CONNECTION: tuple[str, str, str, str] = (PLANT, "x_d_meas", CONTROLLER, "x_d_meas")

#: Connectors declared per component: name -> (kind, type, unit), from the model layer.
#: The controller's input ``x_ref`` is not declared: it is not connected (the reference
#: is the bound parameter ``x_ref_offset``), and fmpy's SSP reader would wire an
#: unconnected input connector to the source of the connector before it.
_CONNECTORS: dict[str, dict[str, tuple[str, str, str | None]]] = {
    component: {v.name: (v.causality, v.type, v.unit if v.type == "Real" else None)
                for v in signals}
    for component, signals in (
        (PLANT, PLANT_INPUTS + PLANT_OUTPUTS),
        (CONTROLLER, CONTROLLER_INPUTS[:1] + CONTROLLER_OUTPUTS),
    )
}

_NAMESPACES = {
    "xmlns:ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "xmlns:ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "xmlns:ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "xmlns:osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "xmlns:oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}


def default_controller_index(scenario: Scenario) -> int:
    """Index of the first ``kind = "papwc"`` table of ``scenario``, else 0."""
    for i, settings in enumerate(scenario.controllers):
        if settings.kind == "papwc":
            return i
    return 0


def libcosim_step_size(T: float) -> float:
    """The number to write as libcosim's ``baseStepSize`` for a sample period ``T`` (s).

    libcosim converts seconds to whole nanoseconds by truncation; the value
    returned is ``T`` or the next larger double, whichever truncates to
    ``round(T * 1e9)`` ns.

    Raises
    ------
    BuildError
        If ``T`` is not a whole number of nanoseconds (to a relative 1e-9).
    """
    ns = round(T * 1e9)
    if ns < 1 or abs(ns * 1e-9 - T) > 1e-9 * T:
        raise BuildError(
            f"sample period T = {T!r} s is not a whole number of nanoseconds; libcosim "
            "steps in whole nanoseconds and the controller refuses any other step"
        )
    value = T
    while int(value * 1e9) < ns:
        value = math.nextafter(value, math.inf)
    return value


def closed_loop_parameters(
    scenario: Scenario, controller_index: int
) -> dict[str, dict[str, float | int | str]]:
    """Parameter values of both components for one controller of ``scenario``.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario.
    controller_index : int
        Index of the ``[[controller]]`` table (0-based).

    Returns
    -------
    dict
        ``{"plant": {...}, "controller": {...}}``: variable name -> value, in SI
        units, for the settings the controller's kind reads
        (:func:`papwc.model.controller_settings.fmu_parameters`: a ``None`` setting
        and an infinite ``t_p_max`` are left out, the FMU's start values select them;
        a given one binds the Real and its Boolean ``<name>_given`` true). The kind is
        given as the Integer ``kind_code`` (fmpy and OMSimulator cannot set
        Strings), the reference as the parameter ``x_ref_offset``.
    """
    if not 0 <= controller_index < len(scenario.controllers):
        raise BuildError(
            f"{scenario.source}: controller_index = {controller_index!r}: the scenario has "
            f"{len(scenario.controllers)} [[controller]] table(s), index 0 to "
            f"{len(scenario.controllers) - 1}"
        )
    settings: ControllerSettings = scenario.controllers[controller_index]
    plant: dict[str, float | int | str] = {
        name: type(PLANT_DEFAULTS[name])(scenario.plant[name]) for name in SCENARIO_PLANT_FIELDS
    }
    plant["x0"] = 0.0
    plant["v0"] = 0.0
    read = set(settings_for_kind(settings.kind))
    types = {v.name: v.type for v in CONTROLLER_SETTINGS}
    controller: dict[str, float | int | str] = {}
    given = fmu_parameters({name: settings.get(name) for name in read})
    for name, value in given.items():
        if name == "kind":
            controller["kind_code"] = KIND_CODES.index(value) + 1
        elif types.get(name, "Boolean") == "Boolean":
            controller[name] = bool(value)
        elif types[name] == "Integer":
            controller[name] = int(value)
        elif types[name] == "String":
            controller[name] = str(value)
        else:
            controller[name] = float(value)
    controller["T"] = float(scenario.maneuver.T)
    controller["x_ref_offset"] = float(scenario.maneuver.x_ref)
    return {PLANT: plant, CONTROLLER: controller}


def _check_fmu(path: Path, component: str, names: set[str]) -> None:
    """Raise BuildError unless the FMU at ``path`` has every variable in ``names``."""
    if not path.is_file():
        raise BuildError(f"cannot build ClosedLoop.ssp: {component} FMU {path} does not exist")
    root = read_model_description(path)
    have = {sv.get("name") for sv in root.iter("ScalarVariable")}
    missing = sorted(names - have)
    if missing:
        raise BuildError(
            f"cannot build ClosedLoop.ssp: {path} ({component}) has no variable(s) {missing}"
        )


def _identifier(path: Path) -> str:
    """The model identifier of the FMU at ``path`` (its name if it has none)."""
    cs = read_model_description(path).find("CoSimulation")
    return (cs.get("modelIdentifier") if cs is not None else None) or path.stem


def _controller_for(kind: str, controller_fmu: Path) -> Path:
    """The controller FMU that runs ``kind``: ``controller_fmu``, or where that is the native
    PulseController.fmu and the kind is not one of it, PulseControllerPython.fmu beside it.

    Raises
    ------
    BuildError
        If the native FMU cannot run ``kind`` and no PulseControllerPython.fmu lies beside it.
    """
    from papwc.fmubuild.fmus import controller_fmu_name

    if not controller_fmu.is_file():
        return controller_fmu  # refused by _check_fmu with the component's name
    wanted = controller_fmu_name(kind)
    if _identifier(controller_fmu) != "PulseController" or wanted == "PulseController":
        return controller_fmu
    python = controller_fmu.with_name(f"{wanted}.fmu")
    if not python.is_file():
        raise BuildError(f"cannot build ClosedLoop.ssp: kind {kind!r} is not in the native "
                         f"{controller_fmu} (pwc, papwc, pid); it is in {python.name}, which "
                         f"papwc build writes beside it: {python} does not exist")
    return python


def _number(value: float) -> str:
    """``value`` as an XML double that parses back to the same float."""
    return repr(float(value))


def _ssd(
    scenario: Scenario, controller_index: int, parameters: dict, sources: dict[str, str]
) -> ET.Element:
    """The ``ssd:SystemStructureDescription`` element of the closed loop."""
    settings = scenario.controllers[controller_index]
    label = scenario.labels[controller_index]
    root = ET.Element(
        "ssd:SystemStructureDescription",
        {**_NAMESPACES, "version": "1.0", "name": "ClosedLoop"},
    )
    system = ET.SubElement(
        root,
        "ssd:System",
        name="ClosedLoop",
        description=(
            f"FrictionPlant under PulseController ({settings.kind}, {label}) of scenario "
            f"{scenario.name!r}: x_ref = {scenario.maneuver.x_ref!r} m, "
            f"T = {scenario.maneuver.T!r} s"
        ),
    )
    from papwc.controllers import CONTROLLER_KINDS

    motor = CONTROLLER_KINDS[settings.kind].reads_x_d_meas
    wired = CONNECTIONS + ((MOTOR_CONNECTION,) if motor else ())
    declared = {component: dict(_CONNECTORS[component]) for component in (PLANT, CONTROLLER)}
    if motor:
        declared[CONTROLLER]["x_d_meas"] = next(
            (v.causality, v.type, v.unit) for v in CONTROLLER_INPUTS if v.name == "x_d_meas")
    elements = ET.SubElement(system, "ssd:Elements")
    units_used: set[str] = set()
    for component in (PLANT, CONTROLLER):
        element = ET.SubElement(
            elements,
            "ssd:Component",
            name=component,
            type="application/x-fmu-sharedlibrary",
            source=sources[component],
        )
        connectors = ET.SubElement(element, "ssd:Connectors")
        for name, (kind, typ, unit) in declared[component].items():
            connector = ET.SubElement(connectors, "ssd:Connector", name=name, kind=kind)
            typed = ET.SubElement(connector, f"ssc:{typ}")
            if unit is not None:
                typed.set("unit", unit)
                units_used.add(unit)
        bindings = ET.SubElement(element, "ssd:ParameterBindings")
        binding = ET.SubElement(bindings, "ssd:ParameterBinding")
        values = ET.SubElement(binding, "ssd:ParameterValues")
        parameter_set = ET.SubElement(
            values, "ssv:ParameterSet", version="1.0", name=PARAMETER_SET
        )
        params = ET.SubElement(parameter_set, "ssv:Parameters")
        for name, value in parameters[component].items():
            parameter = ET.SubElement(params, "ssv:Parameter", name=name)
            if isinstance(value, str):
                ET.SubElement(parameter, "ssv:String", value=value)
            elif isinstance(value, bool):
                ET.SubElement(parameter, "ssv:Boolean", value="true" if value else "false")
            elif isinstance(value, int):
                ET.SubElement(parameter, "ssv:Integer", value=str(value))
            else:
                ET.SubElement(parameter, "ssv:Real", value=_number(value))
    connections = ET.SubElement(system, "ssd:Connections")
    for start_element, start_connector, end_element, end_connector in wired:
        ET.SubElement(
            connections,
            "ssd:Connection",
            startElement=start_element,
            startConnector=start_connector,
            endElement=end_element,
            endConnector=end_connector,
        )
    step = _number(scenario.maneuver.T)
    system_annotations = ET.SubElement(system, "ssd:Annotations")
    oms = ET.SubElement(system_annotations, "ssc:Annotation", type="org.openmodelica")
    oms_annotations = ET.SubElement(oms, "oms:Annotations")
    information = ET.SubElement(oms_annotations, "oms:SimulationInformation")
    ET.SubElement(information, "oms:FixedStepMaster", description="oms-ma", stepSize=step,
                  relativeTolerance=_number(_OMS_RELATIVE_TOLERANCE))
    units = ET.SubElement(root, "ssd:Units")
    for unit in sorted(units_used):
        element = ET.SubElement(units, "ssc:Unit", name=unit)
        exponents = {k: str(e) for k, e in UNIT_DEFINITIONS[unit].items()}
        ET.SubElement(element, "ssc:BaseUnit", exponents)
    experiment = ET.SubElement(
        root,
        "ssd:DefaultExperiment",
        startTime="0.0",
        stopTime=_number(scenario.maneuver.n_steps * scenario.maneuver.T),
    )
    annotations = ET.SubElement(experiment, "ssd:Annotations")
    annotation = ET.SubElement(annotations, "ssc:Annotation", type="com.opensimulationplatform")
    algorithm = ET.SubElement(annotation, "osp:Algorithm")
    ET.SubElement(
        algorithm,
        "osp:FixedStepAlgorithm",
        baseStepSize=_number(libcosim_step_size(scenario.maneuver.T)),
    )
    return root


def build_closed_loop_ssp(
    out_dir: Path,
    scenario_path: Path,
    plant_fmu: Path,
    controller_fmu: Path,
    controller_index: int | None = None,
) -> Path:
    """Write ``ClosedLoop.ssp``: FrictionPlant under PulseController for one scenario.

    Parameters
    ----------
    out_dir : Path
        Output folder, created if needed; an existing ``ClosedLoop.ssp`` there
        is replaced.
    scenario_path : Path
        Scenario file (TOML); its ``[plant]`` and ``[maneuver]`` tables and one
        ``[[controller]]`` table give the parameter bindings.
    plant_fmu, controller_fmu : Path
        ``FrictionPlant.fmu`` and ``PulseController.fmu``, copied into the
        archive's ``resources/``; for a kind the native PulseController.fmu does not
        implement (exact, dual_loop, hybrid), ``PulseControllerPython.fmu`` beside it.
    controller_index : int, optional
        Index (0-based) of the ``[[controller]]`` table; default: the first
        table of kind ``"papwc"`` (in ``scenarios/paper.toml``, PAPWC with
        ``t_p_max = 0.03`` s), or the first table if there is none.

    Returns
    -------
    Path
        ``out_dir / "ClosedLoop.ssp"``.

    Raises
    ------
    BuildError
        If the scenario is invalid, the index out of range, an FMU missing or
        without the variables bound or connected, or the archive cannot be
        written.
    """
    plant_fmu = Path(plant_fmu)
    controller_fmu = Path(controller_fmu)
    try:
        scenario = load_scenario(scenario_path)
    except PapwcError as exc:
        raise BuildError(f"cannot build ClosedLoop.ssp: {exc}") from exc
    if controller_index is None:
        controller_index = default_controller_index(scenario)
    parameters = closed_loop_parameters(scenario, controller_index)
    controller_fmu = _controller_for(scenario.controllers[controller_index].kind, controller_fmu)
    fmus = {PLANT: plant_fmu, CONTROLLER: controller_fmu}
    for component, path in fmus.items():
        names = set(parameters[component]) | set(_CONNECTORS[component])
        _check_fmu(path, component, names)
    sources = {PLANT: "resources/FrictionPlant.fmu",
               CONTROLLER: f"resources/{_identifier(controller_fmu)}.fmu"}
    root = _ssd(scenario, controller_index, parameters, sources)
    ET.indent(root, space="  ")
    ssd_bytes = ET.tostring(root, encoding="UTF-8", xml_declaration=True)

    out_dir = Path(out_dir)
    target = out_dir / "ClosedLoop.ssp"
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix="ClosedLoop", suffix=".ssp", dir=out_dir)
        os.close(fd)
    except OSError as exc:
        raise OutputError(f"cannot write ClosedLoop.ssp into {out_dir}: {exc}") from exc
    try:
        with zipfile.ZipFile(tmp_name, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("SystemStructure.ssd", ssd_bytes)
            for component, path in fmus.items():
                archive.write(path, sources[component])
        os.chmod(tmp_name, 0o644)
        os.replace(tmp_name, target)
    except OSError as exc:
        Path(tmp_name).unlink(missing_ok=True)
        raise OutputError(f"cannot write {target}: {exc}") from exc
    return target
