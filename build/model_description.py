"""Edit the ``modelDescription.xml`` inside a built FMI 2.0 FMU.

pythonfmu writes no units and, depending on the model class, no
``DefaultExperiment``. The functions here add them to any FMU after it is
built, rewriting the archive in place:

- :func:`add_units` writes ``<UnitDefinitions>`` (SI base-unit exponents) and a
  ``unit`` attribute on each named Real variable;
- :func:`ensure_default_experiment` adds a ``<DefaultExperiment>`` if missing;
- :func:`edit_model_description` applies any other edit and rezips.

Every failure raises :class:`papwc.errors.BuildError` naming the FMU and the
problem.
"""

from __future__ import annotations

import os
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path

from papwc.errors import BuildError

__all__ = [
    "MODEL_DESCRIPTION",
    "UNIT_DEFINITIONS",
    "add_units",
    "edit_model_description",
    "ensure_default_experiment",
    "read_model_description",
]

#: Name of the model description inside an FMU.
MODEL_DESCRIPTION = "modelDescription.xml"

#: Units the project uses, as exponents of the SI base units (FMI 2.0 ``BaseUnit``).
UNIT_DEFINITIONS: dict[str, dict[str, int]] = {
    "1": {},
    "kg": {"kg": 1},
    "m": {"m": 1},
    "s": {"s": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
}

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


def read_model_description(fmu_path: Path) -> ET.Element:
    """Parse the model description of an FMU.

    Parameters
    ----------
    fmu_path : Path
        The ``.fmu`` archive.

    Returns
    -------
    xml.etree.ElementTree.Element
        The ``<fmiModelDescription>`` root element.

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


def edit_model_description(fmu_path: Path, edit: Callable[[ET.Element], None]) -> None:
    """Apply ``edit`` to the model description of an FMU and rewrite the archive.

    The other members of the archive are copied unchanged and in order; the
    archive is replaced only once the new one is complete.

    Parameters
    ----------
    fmu_path : Path
        The ``.fmu`` archive, rewritten in place.
    edit : callable
        Called with the ``<fmiModelDescription>`` root element; changes it in place
        and raises :class:`BuildError` if it cannot.
    """
    fmu_path = Path(fmu_path)
    root = read_model_description(fmu_path)
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
            for info in source.infolist():
                if info.filename == MODEL_DESCRIPTION:
                    target.writestr(MODEL_DESCRIPTION, xml_bytes)
                else:
                    target.writestr(info, source.read(info.filename))
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


def add_units(
    fmu_path: Path,
    units: Mapping[str, str],
    definitions: Mapping[str, Mapping[str, int]] | None = None,
) -> None:
    """Add ``<UnitDefinitions>`` and ``unit`` attributes to the Real variables of an FMU.

    Parameters
    ----------
    fmu_path : Path
        The ``.fmu`` archive, rewritten in place.
    units : mapping of str to str
        Variable name -> unit name; every unit must be a key of
        :data:`UNIT_DEFINITIONS` or of ``definitions``. Only the units used
        are defined.
    definitions : mapping, optional
        Further units: unit name -> exponents of the SI base units, e.g.
        ``{"1/kg": {"kg": -1}}``.

    Raises
    ------
    BuildError
        If a unit is unknown, a variable does not exist or is not a Real, or a
        Real variable of the FMU is given no unit.
    """
    fmu_path = Path(fmu_path)
    known = {**UNIT_DEFINITIONS, **(definitions or {})}
    unknown = sorted({unit for unit in units.values() if unit not in known})
    if unknown:
        raise BuildError(f"{fmu_path}: unknown unit(s) {unknown}; known: {sorted(known)}")

    def edit(root: ET.Element) -> None:
        variables = {sv.get("name"): sv for sv in root.iter("ScalarVariable")}
        missing = sorted(set(units) - set(variables))
        if missing:
            raise BuildError(
                f"{fmu_path}: no variable named {missing}; variables: {sorted(variables)}"
            )
        for name, unit in units.items():
            real = variables[name].find("Real")
            if real is None:
                raise BuildError(f"{fmu_path}: variable {name!r} is not a Real; it takes no unit")
            real.set("unit", unit)
        without = sorted(
            name
            for name, sv in variables.items()
            if sv.find("Real") is not None and name not in units
        )
        if without:
            raise BuildError(f"{fmu_path}: Real variable(s) {without} are given no unit")
        old = root.find("UnitDefinitions")
        defined = {} if old is None else {u.get("name"): u for u in old.iter("Unit")}
        if old is not None:
            root.remove(old)
        unit_definitions = ET.Element("UnitDefinitions")
        for unit in sorted(set(units.values()) | set(defined)):
            if unit in defined:
                unit_definitions.append(defined[unit])
                continue
            element = ET.SubElement(unit_definitions, "Unit", name=unit)
            exponents = known[unit]
            if exponents:
                ET.SubElement(element, "BaseUnit", {k: str(e) for k, e in exponents.items()})
        _insert_child(root, unit_definitions)

    edit_model_description(fmu_path, edit)


def ensure_default_experiment(
    fmu_path: Path, start_time: float, stop_time: float, step_size: float
) -> None:
    """Add ``<DefaultExperiment startTime stopTime stepSize>`` (s) if the FMU has none.

    Parameters
    ----------
    fmu_path : Path
        The ``.fmu`` archive, rewritten in place if the element is missing.
    start_time, stop_time, step_size : float
        Start and stop time and communication step size of the experiment, s.
    """
    fmu_path = Path(fmu_path)
    if read_model_description(fmu_path).find("DefaultExperiment") is not None:
        return

    def edit(root: ET.Element) -> None:
        element = ET.Element(
            "DefaultExperiment",
            startTime=repr(float(start_time)),
            stopTime=repr(float(stop_time)),
            stepSize=repr(float(step_size)),
        )
        _insert_child(root, element)

    edit_model_description(fmu_path, edit)
