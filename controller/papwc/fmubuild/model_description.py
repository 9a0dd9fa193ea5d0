"""The ``modelDescription.xml`` of a built FMU, completed from the model layer.

pythonfmu writes the variables' names, causalities and value references. Here
every other attribute comes from the model layer's metadata
(:class:`papwc.model.variables.Variable`), so the model description says what
the variable tables say:

- ``description``, ``unit`` (with ``<UnitDefinitions>``), ``min``, ``max``,
  ``nominal`` and an exact ``start`` (``repr``, ``INF``) for every variable; every
  Real or Integer parameter has ``min`` and ``max``, an excluded bound written as
  the next double inside it, so that a host's range check accepts only values the
  FMU accepts;
- ``initial="calculated"`` outputs without a start value, listed under
  ``<InitialUnknowns>``;
- ``<Outputs>`` whose ``dependencies=""`` says an output does not depend on the
  inputs at the same communication point (no direct feedthrough).

:func:`rewrite_fmu` rewrites an archive reproducibly: members sorted, fixed
timestamps and permissions, so the same sources give the same bytes.
Every failure raises :class:`papwc.errors.BuildError` naming the FMU and the
problem.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

from papwc import __version__
from papwc.errors import BuildError, OutputError
from papwc.model.units import UNIT_DEFINITIONS
from papwc.model.variables import Variable

__all__ = [
    "MODEL_DESCRIPTION",
    "complete_model_description",
    "read_model_description",
    "rewrite_fmu",
    "xml_number",
]

#: Name of the model description inside an FMU.
MODEL_DESCRIPTION = "modelDescription.xml"

#: Order of the children of <fmiModelDescription> in the FMI 2.0 schema.
_ELEMENT_ORDER = (
    "ModelExchange",
    "CoSimulation",
    "UnitDefinitions",
    "TypeDefinitions",
    "LogCategories",
    "DefaultExperiment",
    "VendorAnnotations",
    "ModelVariables",
    "ModelStructure",
)

#: Timestamp of every member of a rewritten archive (the earliest a zip can hold).
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


def xml_number(value: float | int | bool | str) -> str:
    """A start value as the model description writes it (round-trips exactly)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isinf(value):
            return "INF" if value > 0 else "-INF"
        if math.isnan(value):
            return "NaN"
        return repr(value)
    return str(value)


def read_model_description(fmu_path: Path) -> ET.Element:
    """Parse the model description of an FMU.

    Raises
    ------
    BuildError
        If the file is not a zip archive or holds no valid ``modelDescription.xml``.
    """
    fmu_path = Path(fmu_path)
    try:
        with zipfile.ZipFile(fmu_path) as archive:
            data = archive.read(MODEL_DESCRIPTION)
    except (OSError, KeyError, zipfile.BadZipFile) as exc:
        raise BuildError(f"{fmu_path}: cannot read {MODEL_DESCRIPTION}: {exc}") from exc
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        raise BuildError(f"{fmu_path}: {MODEL_DESCRIPTION} is not well-formed XML: {exc}") from exc


def install_fmu(built: Path, out_dir: str | os.PathLike) -> Path:
    """Copy the FMU ``built`` into ``out_dir`` (created if missing); return its path there.

    It is copied to ``<name>.tmp`` and renamed, so ``out_dir`` never holds a partial FMU.

    Raises
    ------
    OutputError
        If the copy cannot be written (no partial copy is left).
    """
    out_dir = Path(out_dir)
    target = out_dir / built.name
    tmp = target.with_name(target.name + ".tmp")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built, tmp)
        tmp.chmod(0o644)
        tmp.replace(target)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)  # no partial copy left on a full disk
        raise OutputError(f"cannot write {built.name} into {out_dir}: {exc}") from exc
    return target


def rewrite_fmu(fmu_path: Path, edit: Callable[[ET.Element], None] | None = None) -> None:
    """Rewrite an FMU archive reproducibly, applying ``edit`` to its model description.

    Members are written in sorted order with a fixed timestamp and permissions;
    the archive is replaced only once the new one is complete.
    """
    fmu_path = Path(fmu_path)
    root = read_model_description(fmu_path)
    if edit is not None:
        edit(root)
    ET.indent(root, space="  ")
    xml_bytes = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    fd, tmp_name = tempfile.mkstemp(prefix=fmu_path.stem, suffix=".fmu", dir=fmu_path.parent)
    os.close(fd)
    try:
        with (
            zipfile.ZipFile(fmu_path) as source,
            zipfile.ZipFile(tmp_name, "w", zipfile.ZIP_DEFLATED) as target,
        ):
            for name in sorted(source.namelist()):
                if name.endswith("/"):
                    continue
                data = xml_bytes if name == MODEL_DESCRIPTION else source.read(name)
                info = zipfile.ZipInfo(name, date_time=_ZIP_TIME)
                info.compress_type = zipfile.ZIP_DEFLATED
                executable = name.startswith("binaries/")
                info.external_attr = (0o755 if executable else 0o644) << 16
                target.writestr(info, data)
        os.chmod(tmp_name, 0o644)
        os.replace(tmp_name, fmu_path)
    except (OSError, zipfile.BadZipFile) as exc:
        Path(tmp_name).unlink(missing_ok=True)
        raise BuildError(f"{fmu_path}: cannot rewrite the archive: {exc}") from exc


def _insert_child(root: ET.Element, element: ET.Element) -> None:
    """Insert ``element`` into ``root`` at its place in the FMI 2.0 schema order."""
    rank = _ELEMENT_ORDER.index(element.tag)
    position = len(root)
    for i, child in enumerate(root):
        if child.tag in _ELEMENT_ORDER and _ELEMENT_ORDER.index(child.tag) > rank:
            position = i
            break
    root.insert(position, element)


def _needs_start(var: Variable) -> bool:
    return var.causality in ("parameter", "input") or var.initial != "calculated"


def complete_model_description(
    root: ET.Element,
    variables: Sequence[Variable],
    *,
    guid: str | None = None,
    default_experiment: tuple[float, float, float] | None = None,
    where: str = "the FMU",
) -> None:
    """Complete a pythonfmu model description from the variables' metadata, in place.

    Parameters
    ----------
    root : Element
        ``<fmiModelDescription>``.
    variables : sequence of Variable
        Every variable of the FMU (names must match the model description's).
    guid : str, optional
        The GUID to write (a digest of the sources, for a reproducible build).
    default_experiment : (start, stop, step), optional
        Written as ``<DefaultExperiment>`` if the model has none, s.
    where : str
        Names the FMU in errors.
    """
    meta = {v.name: v for v in variables}
    scalars = list(root.iter("ScalarVariable"))
    names = [sv.get("name") for sv in scalars]
    missing = sorted(set(names) ^ set(meta))
    if missing:
        raise BuildError(f"{where}: the model description and the variable table differ in "
                         f"{missing}")
    if guid is not None:
        root.set("guid", guid)
    root.attrib.pop("generationDateAndTime", None)
    root.set("version", __version__)
    units: set[str] = set()
    for sv in scalars:
        var = meta[sv.get("name")]
        sv.set("description", var.description)
        typed = next(iter(sv))
        if typed.tag != var.type:
            raise BuildError(f"{where}: variable {var.name} is a {typed.tag}, the table says "
                             f"{var.type}")
        if var.causality == "output":
            sv.set("initial", var.initial or "exact")
        for key in ("start", "unit", "min", "max", "nominal"):
            typed.attrib.pop(key, None)
        if _needs_start(var):
            typed.set("start", xml_number(var.fmi_start))
        if var.type == "Real" and var.unit:
            typed.set("unit", var.unit)
            units.add(var.unit)
        if var.type in ("Real", "Integer") and var.causality == "parameter":
            low, high = var.fmi_min, var.fmi_max
            if low is not None:
                typed.set("min", xml_number(float(low) if var.type == "Real" else int(low)))
            if high is not None:
                typed.set("max", xml_number(float(high) if var.type == "Real" else int(high)))
        if var.type == "Real" and var.nominal is not None:
            typed.set("nominal", xml_number(float(var.nominal)))
    _write_units(root, units, where)
    _write_structure(root, scalars, meta)
    if default_experiment is not None and root.find("DefaultExperiment") is None:
        start, stop, step = default_experiment
        _insert_child(root, ET.Element("DefaultExperiment", startTime=xml_number(float(start)),
                                       stopTime=xml_number(float(stop)),
                                       stepSize=xml_number(float(step))))


def _write_units(root: ET.Element, units: set[str], where: str) -> None:
    unknown = sorted(units - set(UNIT_DEFINITIONS))
    if unknown:
        raise BuildError(f"{where}: unknown unit(s) {unknown}; known: {sorted(UNIT_DEFINITIONS)}")
    old = root.find("UnitDefinitions")
    if old is not None:
        root.remove(old)
    if not units:
        return
    definitions = ET.Element("UnitDefinitions")
    for unit in sorted(units):
        element = ET.SubElement(definitions, "Unit", name=unit)
        exponents = UNIT_DEFINITIONS[unit]
        if exponents:
            ET.SubElement(element, "BaseUnit", {k: str(e) for k, e in exponents.items()})
    _insert_child(root, definitions)


def _write_structure(root: ET.Element, scalars: list[ET.Element],
                     meta: dict[str, Variable]) -> None:
    """``<Outputs>`` with their dependencies and ``<InitialUnknowns>``."""
    index = {sv.get("name"): i + 1 for i, sv in enumerate(scalars)}
    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    structure = ET.Element("ModelStructure")
    outputs = [meta[sv.get("name")] for sv in scalars if meta[sv.get("name")].causality == "output"]
    inputs = [index[n] for n, v in meta.items() if v.causality == "input"]
    if outputs:
        node = ET.SubElement(structure, "Outputs")
        for var in outputs:
            unknown = ET.SubElement(node, "Unknown", index=str(index[var.name]))
            unknown.set("dependencies", " ".join(str(i) for i in sorted(inputs))
                        if var.feedthrough else "")
    calculated = [v for v in outputs if v.initial == "calculated"]
    if calculated:
        node = ET.SubElement(structure, "InitialUnknowns")
        for var in sorted(calculated, key=lambda v: index[v.name]):
            ET.SubElement(node, "Unknown", index=str(index[var.name]))
    _insert_child(root, structure)
