"""Reading an SSP 1.0 archive of FMI 2.0 Co-Simulation FMUs (:func:`read_ssp`).

:func:`read_ssp` reads an archive's ``SystemStructure.ssd`` and checks it
against the model descriptions of the FMUs it holds, before anything runs:

- every ``ssd:Component`` (``application/x-fmu-sharedlibrary``) whose
  ``source`` is an FMU in the archive;
- every ``ssd:Connection`` between two components, from an output to an input
  of the same type (Real, Integer, Boolean, String); one connection at most into an
  input, none from a component into itself; a component name without ``.`` (variables
  are named ``component.variable``);
- the parameter bindings: inline ``ssd:ParameterValues`` or an ``.ssv`` file of
  the archive, on a component (names of the FMU's variables) or on the system
  (names ``component.variable``, which take precedence), of types Real,
  Integer, Boolean and String; later bindings take precedence over earlier
  ones, as SSP 1.0 says. Unlike SSP 1.0, which ignores a name no variable
  has, a binding to a variable the FMU lacks is an error;
- the ``ssd:DefaultExperiment`` (start and stop time) and the fixed step of the
  Open Simulation Platform annotation (``osp:FixedStepAlgorithm
  baseStepSize``) or of OMSimulator's (``oms:FixedStepMaster stepSize``); two that
  differ are a conflict the run reports (unless ``--step`` decides);
- a PulseController component whose kind reads the motor encoder (``dual_loop``) has
  its input ``x_d_meas`` connected.

Every problem raises :class:`papwc.errors.SspError` naming the archive and the
SSD element. :func:`papwc.master.ssp_runner.run_ssp` runs what it returns.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from papwc.errors import SspError
from papwc.limits import input_path_problem
from papwc.master import archive as door
from papwc.model.variables import describe_value

__all__ = ["SspArchive", "SspBinding", "SspComponent", "SspConnection", "SspSystem", "read_ssp"]

_NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}
_SSD = "SystemStructure.ssd"
_FMU_TYPE = "application/x-fmu-sharedlibrary"
_TYPES = ("Real", "Integer", "Boolean", "String")
#: Largest FMU read from an SSP archive, bytes (an SSD or SSV: door.MAX_XML_BYTES).
MAX_MEMBER_BYTES = door.MAX_UNPACKED_BYTES
#: Most components of one system.
MAX_COMPONENTS = 256


@dataclass(frozen=True)
class SspBinding:
    """One bound value: ``component.variable = value`` of SSP type ``type``."""

    component: str
    variable: str
    type: str
    value: Any
    element: str


@dataclass(frozen=True)
class SspConnection:
    """``start.output -> end.input``."""

    start: str
    output: str
    end: str
    input: str
    element: str


@dataclass
class SspComponent:
    """A component: its FMU (archive member), model variables (name -> (causality, type))."""

    name: str
    source: str
    element: str
    variables: dict[str, tuple[str, str]] = field(default_factory=dict)
    start_values: dict[str, Any] = field(default_factory=dict)
    #: What its FMU unpacks to, bytes.
    unpacked_bytes: int = 0
    #: (min, max, unit) of each Integer and Real variable (an Integer's at most
    #: the range of a 32-bit fmi2Integer).
    ranges: dict[str, tuple[float, float, str]] = field(default_factory=dict)


@dataclass
class SspSystem:
    """A checked SSP system: components, connections, start values, experiment."""

    path: Path
    name: str
    components: dict[str, SspComponent]
    connections: list[SspConnection]
    start_time: float
    stop_time: float | None
    step_size: float | None
    step_source: str
    #: Two fixed steps that differ (both annotations), as a message; "" if none.
    step_conflict: str = ""

    def outputs(self) -> list[str]:
        """``component.variable`` of every output that can be recorded, in SSD order."""
        return [f"{c.name}.{name}" for c in self.components.values()
                for name, (causality, typ) in c.variables.items()
                if causality == "output" and typ != "String"]


def _tag(element: ET.Element) -> str:
    """``<ssd:Component name="plant" source="...">`` as the message names an element."""
    tag = element.tag
    for prefix, uri in _NS.items():
        tag = tag.replace("{" + uri + "}", prefix + ":")
    keys = ("name", "source", "startElement", "startConnector", "endElement", "endConnector",
            "type")
    attrs = " ".join(f'{k}="{element.get(k)}"' for k in keys if element.get(k) is not None)
    return f"<{tag}{' ' + attrs if attrs else ''}>"


def _float(text: str | None, where: str, what: str) -> float:
    try:
        value = float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise SspError(f"{where}: {what} = {text!r} is not a number") from None
    return value


#: Largest start or stop time of a DefaultExperiment, s (about 31.7 years): the
#: difference of two such times and its quotient by a step stay finite.
MAX_TIME = 1e9


def _time(text: str | None, where: str, what: str) -> float:
    """A DefaultExperiment time: a finite number within +-MAX_TIME s."""
    value = _float(text, where, what)
    if not -MAX_TIME <= value <= MAX_TIME:
        raise SspError(f"{where}: {what} = {text!r} s: must be a finite number within "
                       f"-{MAX_TIME:g}..{MAX_TIME:g} s")
    return value


def _value(typed: ET.Element, where: str) -> tuple[str, Any]:
    """The SSP type and the value of an ``ssv:Real``/``Integer``/``Boolean``/``String``."""
    kind = typed.tag.rsplit("}", 1)[-1]
    text = typed.get("value")
    if kind not in _TYPES:
        raise SspError(f"{where}: parameter type ssv:{kind} is not supported; supported: "
                       + ", ".join(f"ssv:{t}" for t in _TYPES))
    if text is None:
        raise SspError(f"{where}: ssv:{kind} has no value attribute")
    if kind == "Real":
        return kind, _float(text, where, "value")
    if kind == "Integer":
        digits = text.strip().removeprefix("-").removeprefix("+")
        if not (digits.isascii() and digits.isdigit()):
            raise SspError(f"{where}: Integer value = {describe_value(text)} is not a whole "
                           "number")
        if len(digits) > 20:  # beyond any fmi2Integer; not converted (Python caps str->int)
            raise SspError(f"{where}: Integer value = {describe_value(text)}: must satisfy "
                           f"{INT_RANGE[0]} <= value <= {INT_RANGE[1]} (an FMI 2.0 Integer)")
        return kind, int(text)
    if kind == "Boolean":
        if text not in ("true", "false", "1", "0"):
            raise SspError(f"{where}: Boolean value = {text!r}: must be true, false, 1 or 0")
        return kind, text in ("true", "1")
    return kind, text


class SspArchive:
    """The members of an SSP archive, read through :mod:`papwc.master.archive` (bounded)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        problem = input_path_problem(path)
        if problem == "no such file":
            raise SspError(f"{path}: no such SSP file")
        if problem is not None:
            raise SspError(f"{path}: {problem}; give an SSP archive (a .ssp zip file)")
        self.zip = door.open_zip(path, str(path), SspError, what="SSP archive")
        self.names = {info.filename: info for info in self.zip.infolist()}

    def member(self, name: str) -> str | None:
        """The archive name of ``name`` (relative to the root, ``./`` allowed), or None."""
        clean = str(PurePosixPath(name.removeprefix("./")))
        return clean if clean in self.names else None

    def read(self, name: str, where: str, limit: int = door.MAX_XML_BYTES) -> bytes:
        """Member ``name``'s bytes (``where`` names the SSD element that asks for it)."""
        return door.read_member(self.zip, name, where, SspError, limit)

    def close(self) -> None:
        """Close the archive file."""
        self.zip.close()


#: SSP types of the FMI 2.0 types with a range: type -> (lowest, highest) of fmi2Integer.
INT_RANGE = (-(2**31), 2**31 - 1)


def _model_variables(data: bytes, where: str) -> tuple[dict[str, tuple[str, str]], int,
                                                       dict[str, tuple[float, float, str]]]:
    """Of an FMI 2.0 CS FMU given as bytes: name -> (causality, type), what it unpacks to,
    and name -> (min, max) of its Integer variables."""
    with door.open_zip(data, where, SspError) as fmu:
        unpacked = door.unpacked_bytes(fmu)
        text = door.read_member(fmu, "modelDescription.xml", where, SspError)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise SspError(f"{where}: modelDescription.xml is not well-formed XML: {exc}") from None
    if root.get("fmiVersion") != "2.0":
        raise SspError(f"{where}: fmiVersion = {root.get('fmiVersion')!r}; only FMI 2.0 FMUs "
                       "are supported")
    if root.find("CoSimulation") is None:
        raise SspError(f"{where}: not a Co-Simulation FMU")
    out, ranges = {}, {}
    for sv in root.iter("ScalarVariable"):
        typed = next((c for c in sv if c.tag in (*_TYPES, "Enumeration")), None)
        typ = "Integer" if typed is None or typed.tag == "Enumeration" else typed.tag
        name = sv.get("name")
        out[name] = (sv.get("causality", "local"), typ)
        if typed is not None and typ in ("Integer", "Real"):
            low = float(INT_RANGE[0]) if typ == "Integer" else -float("inf")
            high = float(INT_RANGE[1]) if typ == "Integer" else float("inf")
            for key, default in (("min", low), ("max", high)):
                try:
                    value = float(typed.get(key, default))
                except ValueError:
                    value = default
                if key == "min":
                    low = value
                else:
                    high = value
            if typ == "Integer":  # what an fmi2Integer holds, whatever is declared
                low, high = max(low, INT_RANGE[0]), min(high, INT_RANGE[1])
            ranges[name] = (low, high, typed.get("unit", ""))
    return out, unpacked, ranges


def _bindings(archive: SspArchive, parent: ET.Element, where: str) -> list[tuple[str, ET.Element]]:
    """``(name, typed value element)`` of every parameter bound on ``parent``, in order."""
    found: list[tuple[str, ET.Element]] = []
    for binding in parent.findall("ssd:ParameterBindings/ssd:ParameterBinding", _NS):
        here = f"{where} {_tag(binding)}"
        if binding.find("ssd:ParameterMapping", _NS) is not None:
            raise SspError(f"{here}: ssd:ParameterMapping is not supported")
        kind = binding.get("type", "application/x-ssp-parameter-set")
        if kind != "application/x-ssp-parameter-set":
            raise SspError(f"{here}: type {kind!r} is not supported; supported: "
                           "application/x-ssp-parameter-set")
        inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", _NS)
        source = binding.get("source")
        if inline is not None:
            parameter_set = inline
        elif source:
            member = archive.member(source)
            if member is None:
                raise SspError(f"{here}: the archive has no {source}")
            try:
                parameter_set = ET.fromstring(archive.read(member, here))
            except ET.ParseError as exc:
                raise SspError(f"{here}: {source} is not well-formed XML: {exc}") from exc
        else:
            raise SspError(f"{here}: neither ssd:ParameterValues nor a source")
        prefix = binding.get("prefix", "")
        for parameter in parameter_set.findall("ssv:Parameters/ssv:Parameter", _NS):
            name = parameter.get("name", "")
            typed = next(iter(parameter), None)
            if typed is None:
                raise SspError(f"{here} {_tag(parameter)}: no value")
            if prefix:
                if not name.startswith(prefix):
                    continue
                name = name[len(prefix):]
            found.append((name, typed))
    return found


def _bind(component: SspComponent, variable: str, typed: ET.Element, where: str) -> None:
    kind, value = _value(typed, where)
    if variable not in component.variables:
        raise SspError(f"{where}: the FMU {component.source} of component {component.name!r} "
                       f"has no variable {variable!r}")
    causality, typ = component.variables[variable]
    if causality not in ("parameter", "input"):
        raise SspError(f"{where}: {component.name}.{variable} has causality {causality!r}; "
                       "a binding sets parameters and inputs")
    if kind != typ and not (kind == "Integer" and typ == "Real"):
        raise SspError(f"{where}: ssv:{kind} bound to {component.name}.{variable}, a {typ}")
    if typ in ("Integer", "Real"):
        low, high, unit = component.ranges.get(variable, (
            (float(INT_RANGE[0]), float(INT_RANGE[1]), "") if typ == "Integer"
            else (-math.inf, math.inf, "")))
        number = float(value) if typ == "Real" else value
        if not low <= number <= high:
            what = ("an FMI 2.0 Integer" if (low, high) == tuple(map(float, INT_RANGE))
                    else "the FMU's declared range")
            unit = f" {unit}" if unit else ""
            raise SspError(f"{where}: {component.name}.{variable} = {describe_value(value)}{unit}: "
                           "must "
                           f"satisfy {_bound(low, typ)} <= {variable} <= {_bound(high, typ)}{unit} "
                           f"({what})")
    component.start_values[variable] = float(value) if typ == "Real" else value


def _bound(x: float, typ: str) -> str:
    return str(int(x)) if typ == "Integer" else f"{x:g}"


def read_ssp(path: str | os.PathLike) -> SspSystem:
    """Read and check an SSP archive (see the module docstring); nothing is extracted.

    Raises
    ------
    SspError
        Naming the archive and the SSD element of the first problem found.
    """
    path = Path(path)
    archive = SspArchive(path)
    try:
        return _read_system(path, archive)
    finally:
        archive.close()


def _read_system(path: Path, archive: SspArchive) -> SspSystem:
    where = f"{path}: {_SSD}"
    if _SSD not in archive.names:
        raise SspError(f"{path}: the archive has no {_SSD}")
    try:
        root = ET.fromstring(archive.read(_SSD, where))
    except ET.ParseError as exc:
        raise SspError(f"{where}: not well-formed XML: {exc}") from exc
    if root.tag != f"{{{_NS['ssd']}}}SystemStructureDescription":
        raise SspError(f"{where}: the root element is not ssd:SystemStructureDescription")
    system = root.find("ssd:System", _NS)
    if system is None:
        raise SspError(f"{where}: no ssd:System")
    components: dict[str, SspComponent] = {}
    elements = system.findall("ssd:Elements/*", _NS)
    if len(elements) > MAX_COMPONENTS:
        raise SspError(f"{where}: {len(elements)} components; at most {MAX_COMPONENTS}")
    #: What each FMU of the archive holds, read once.
    fmus: dict[str, tuple[dict, int, dict]] = {}
    unpacked = 0
    for element in elements:
        here = f"{where} {_tag(element)}"
        if element.tag != f"{{{_NS['ssd']}}}Component":
            raise SspError(f"{here}: only ssd:Component elements are supported (no nested "
                           "systems or signal dictionaries)")
        name, source = element.get("name"), element.get("source")
        kind = element.get("type", _FMU_TYPE)
        if kind != _FMU_TYPE:
            raise SspError(f"{here}: type {kind!r} is not supported; supported: {_FMU_TYPE}")
        if not name or not source:
            raise SspError(f"{here}: a component needs a name and a source")
        if "." in name:
            raise SspError(f"{here}: a component name cannot hold '.' (variables are named "
                           f"component.variable, so {name}.x could not be told apart); rename "
                           "it")
        if name in components:
            raise SspError(f"{here}: a second component named {name!r}")
        member = archive.member(source)
        if member is None:
            raise SspError(f"{here}: the archive has no {source}")
        component = SspComponent(name, member, _tag(element))
        if member not in fmus:
            fmus[member] = _model_variables(archive.read(member, here, MAX_MEMBER_BYTES),
                                            f"{here}: {member}")
        variables, component.unpacked_bytes, ranges = fmus[member]
        component.variables, component.ranges = dict(variables), ranges
        unpacked += component.unpacked_bytes
        if unpacked > door.MAX_UNPACKED_BYTES:
            raise SspError(f"{here}: the FMUs of the components up to this one unpack to "
                           f"{door.size_text(unpacked)}; at most "
                           f"{door.size_text(door.MAX_UNPACKED_BYTES)} for one system")
        for connector in element.findall("ssd:Connectors/ssd:Connector", _NS):
            cname = connector.get("name")
            at = f"{here} {_tag(connector)}"
            if cname not in component.variables:
                raise SspError(f"{at}: the FMU {member} has no variable {cname!r}")
            typed = next((c for c in connector if c.tag.startswith(f"{{{_NS['ssc']}}}")), None)
            if typed is not None:
                declared = typed.tag.rsplit("}", 1)[-1]
                if declared in _TYPES and declared != component.variables[cname][1]:
                    raise SspError(f"{at}: declared ssc:{declared}, the FMU's variable is a "
                                   f"{component.variables[cname][1]}")
        for variable, typed in _bindings(archive, element, here):
            _bind(component, variable, typed, f"{here} <ssv:Parameter name=\"{variable}\">")
        components[name] = component
    if not components:
        raise SspError(f"{where}: the system has no component")
    for name, typed in _bindings(archive, system, f"{where} {_tag(system)}"):
        at = f"{where} {_tag(system)} <ssv:Parameter name=\"{name}\">"
        owner, _, variable = name.partition(".")
        if owner not in components or not variable:
            raise SspError(f"{at}: a system binding names component.variable; components: "
                           + ", ".join(components))
        _bind(components[owner], variable, typed, at)
    connections = []
    into: dict[tuple[str, str], str] = {}
    for element in system.findall("ssd:Connections/ssd:Connection", _NS):
        here = f"{where} {_tag(element)}"
        ends = []
        for side, want in (("start", ("output",)), ("end", ("input",))):
            owner, connector = element.get(f"{side}Element"), element.get(f"{side}Connector")
            if not owner:
                raise SspError(f"{here}: connections to the system's own connectors are not "
                               "supported")
            if owner not in components:
                raise SspError(f"{here}: no component named {owner!r}")
            variables = components[owner].variables
            if connector not in variables:
                raise SspError(f"{here}: the FMU {components[owner].source} of component "
                               f"{owner!r} has no variable {connector!r}")
            if variables[connector][0] not in want:
                raise SspError(f"{here}: {owner}.{connector} is a {variables[connector][0]}, "
                               f"not an {want[0]}")
            ends.append((owner, connector, variables[connector][1]))
        if element.find("ssc:LinearTransformation", _NS) is not None or element.find(
                "ssc:MapTransformation", _NS) is not None:
            raise SspError(f"{here}: connection transformations are not supported")
        (start, output, t_out), (end, input_, t_in) = ends
        if t_out != t_in:
            raise SspError(f"{here}: {start}.{output} is a {t_out}, {end}.{input_} a {t_in}: "
                           "a connection joins variables of one type")
        if start == end:
            raise SspError(f"{here}: connects component {start!r} to itself; a connection "
                           "joins two components")
        if (end, input_) in into:
            raise SspError(f"{here}: {end}.{input_} has a connection already, "
                           f"{into[(end, input_)]}; an input takes one connection")
        into[(end, input_)] = _tag(element)
        connections.append(SspConnection(start, output, end, input_, _tag(element)))
    _motor_encoder_connected(where, components, into)
    start_time, stop_time, step, step_source = 0.0, None, None, ""
    steps: list[tuple[str, float]] = []
    experiment = root.find("ssd:DefaultExperiment", _NS)
    if experiment is not None:
        here = f"{where} <ssd:DefaultExperiment>"
        if experiment.get("startTime") is not None:
            start_time = _time(experiment.get("startTime"), here, "startTime")
        if experiment.get("stopTime") is not None:
            stop_time = _time(experiment.get("stopTime"), here, "stopTime")
        osp = experiment.find(".//osp:FixedStepAlgorithm", _NS)
        if osp is not None and osp.get("baseStepSize") is not None:
            steps.append(("osp:FixedStepAlgorithm baseStepSize", _float(
                osp.get("baseStepSize"), f"{here} <osp:FixedStepAlgorithm>", "baseStepSize")))
    oms = system.find("ssd:Annotations//oms:FixedStepMaster", _NS)
    if oms is not None and oms.get("stepSize") is not None:
        steps.append(("oms:FixedStepMaster stepSize",
                      _float(oms.get("stepSize"), f"{where} <oms:FixedStepMaster>", "stepSize")))
    conflict = ""
    if steps:
        step_source, step = steps[0]
        if any(value != step for _, value in steps[1:]):
            conflict = (f"{where}: the fixed step is given twice and differently, "
                        + " and ".join(f"{source} = {value!r} s" for source, value in steps)
                        + "; make them equal or give --step")
    return SspSystem(path, system.get("name") or root.get("name") or path.stem, components,
                     connections, start_time, stop_time, step, step_source, conflict)


def _motor_encoder_connected(where: str, components: dict[str, SspComponent],
                             into: dict[tuple[str, str], str]) -> None:
    """Refuse a PulseController component whose kind reads the motor encoder (the dual loop)
    with its input ``x_d_meas`` unconnected: it would read 0 m and stop without a word."""
    from papwc.controllers import CONTROLLER_KINDS
    from papwc.model.controller_settings import CONTROLLER_SETTINGS, kind_from_code

    defaults = {v.name: v.default for v in CONTROLLER_SETTINGS}
    for name, component in components.items():
        variables = component.variables
        if not {"kind", "kind_code", "x_d_meas"} <= set(variables) or (
                variables["x_d_meas"][0] != "input"):
            continue  # not a PulseController
        bound = component.start_values
        kind, _ = kind_from_code(str(bound.get("kind", defaults["kind"])),
                                 int(bound.get("kind_code", 0)), "kind" in bound)
        reads = getattr(CONTROLLER_KINDS.get(kind), "reads_x_d_meas", False)
        if reads and (name, "x_d_meas") not in into:
            raise SspError(f"{where} {component.element}: kind {kind!r} reads the motor "
                           f"encoder, but {name}.x_d_meas has no ssd:Connection (it would read "
                           f"0 m); connect the plant's x_d_meas to {name}.x_d_meas")
