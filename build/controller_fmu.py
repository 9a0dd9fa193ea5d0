"""Build ``PulseController.fmu``: the project's pulse controllers as an FMI 2.0 CS FMU.

The FMU runs the same code as the Python master: the package ``papwc.core``
(``controller/core/``, standard library only, relative imports) is copied at
build time as ``papwc_pulse_core/`` beside the model script
``fmu_src/PulseController/PulseController.py`` and bundled by pythonfmu into
``resources/``. pythonfmu FMUs import their bundled modules by name into the one
Python interpreter of the process, so the name differs from every module the
plant FMU bundles (``FrictionPlant``, ``papwc_stickslip``) and from the
project's own ``papwc``: both FMUs, and the project itself, load in one process.

After pythonfmu, the model description is completed: units
(:func:`papwc.build.model_description.add_units`), ``InitialUnknowns`` for the
outputs computed from the parameters (``b_hat``, ``f_c_hat``), and the XML
spelling ``INF`` of an infinite start value. The FMU is then checked with
``fmpy.validation.validate_fmu``.
"""

from __future__ import annotations

import re
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

from fmpy.validation import validate_fmu

from papwc.build.model_description import (
    add_units,
    edit_model_description,
    ensure_default_experiment,
)
from papwc.errors import BuildError
from papwc.fmu_src import FMU_SRC_DIR

__all__ = [
    "CONTROLLER_CORE_DIR",
    "CORE_PACKAGE",
    "PULSE_CONTROLLER_OPTIONS",
    "PULSE_CONTROLLER_UNITS",
    "build_pulse_controller",
]

#: The controller package bundled into the FMU (``papwc.core``).
CONTROLLER_CORE_DIR = Path(__file__).resolve().parent.parent / "controller" / "core"

#: Name of the bundled copy of ``papwc.core`` inside the FMU.
CORE_PACKAGE = "papwc_pulse_core"

#: Unit of every Real variable of PulseController.fmu.
PULSE_CONTROLLER_UNITS: dict[str, str] = {
    "f_p_max": "N",
    "t_p_max": "s",
    "K_c": "1",
    "tolerance": "m",
    "m_est": "kg",
    "f_c_est": "N",
    "f_p_min": "N",
    "floor_raise": "1",
    "F_inv0": "s4",
    "lambda_1": "1",
    "lambda_2": "1",
    "delta_inv": "1",
    "lambda": "1",
    "e_band": "m",
    "rest_band": "m",
    "k_p": "N/m",
    "k_d": "N.s/m",
    "T": "s",
    "x_meas": "m",
    "x_ref": "m",
    "u": "N",
    "b_hat": "m/s2",
    "f_c_hat": "N",
}

#: Units beyond :data:`papwc.build.model_description.UNIT_DEFINITIONS`.
PULSE_CONTROLLER_UNIT_DEFINITIONS: dict[str, dict[str, int]] = {
    "N/m": {"kg": 1, "s": -2},
    "s4": {"s": 4},
}

#: CoSimulation capability flags: fixed communication step T, full state handling.
PULSE_CONTROLLER_OPTIONS: dict[str, bool] = {
    "canHandleVariableCommunicationStepSize": False,
    "canGetAndSetFMUstate": True,
    "canSerializeFMUstate": True,
}

#: Outputs whose initial value is computed from the parameters.
_CALCULATED_OUTPUTS = ("b_hat", "f_c_hat")

#: Characters allowed in the path of the folder where the FMU is assembled.
_SAFE_PATH = re.compile(r"[A-Za-z0-9_/]+")


def _work_dir() -> Path:
    """Create a temporary folder whose absolute path has only ASCII letters, digits, '_'."""
    for base in (tempfile.gettempdir(), "/tmp", "/var/tmp"):
        base_path = Path(base).resolve()
        if _SAFE_PATH.fullmatch(str(base_path)) and base_path.is_dir():
            return Path(tempfile.mkdtemp(prefix="papwc", dir=base_path))
    raise BuildError(
        f"no temporary folder with a path of ASCII letters, digits and '_' only "
        f"(tried {tempfile.gettempdir()!r}, '/tmp', '/var/tmp'); set TMPDIR to such a folder"
    )


def _pythonfmu_builder():
    """pythonfmu's ``FmuBuilder``, checked to come from an installed pythonfmu.

    A pythonfmu FMU loaded into this process may have imported the copy of
    ``pythonfmu`` bundled in its ``resources/``; that copy has no binaries to
    put into a new FMU.
    """
    import pythonfmu
    from pythonfmu import FmuBuilder

    binaries = Path(pythonfmu.__file__).resolve().parent / "resources" / "binaries"
    if not any(binaries.rglob("*.so")) and not any(binaries.rglob("*.dll")):
        raise BuildError(
            f"the pythonfmu imported in this process ({pythonfmu.__file__}) has no binaries "
            f"in {binaries}: it is the copy bundled in an FMU loaded earlier; build "
            "PulseController.fmu before loading any pythonfmu FMU, or in a new process"
        )
    return FmuBuilder


def _complete_model_description(root: ET.Element) -> None:
    """Add ``InitialUnknowns`` for the calculated outputs; write infinite starts as ``INF``."""
    variables = list(root.iter("ScalarVariable"))
    for sv in variables:
        for typed in sv:
            start = typed.get("start")
            if start in ("inf", "-inf", "nan"):
                typed.set("start", {"inf": "INF", "-inf": "-INF", "nan": "NaN"}[start])
    index = {sv.get("name"): i + 1 for i, sv in enumerate(variables)}
    structure = root.find("ModelStructure")
    if structure is None:
        raise BuildError("PulseController.fmu: the model description has no <ModelStructure>")
    outputs = structure.find("Outputs")
    if outputs is None:
        raise BuildError("PulseController.fmu: the model description lists no outputs")
    old = structure.find("InitialUnknowns")
    if old is not None:
        structure.remove(old)
    unknowns = ET.Element("InitialUnknowns")
    for position in sorted(index[name] for name in _CALCULATED_OUTPUTS):
        ET.SubElement(unknowns, "Unknown", index=str(position))
    # Order of <ModelStructure>: Outputs, Derivatives, InitialUnknowns.
    structure.append(unknowns)


def build_pulse_controller(out_dir: Path) -> Path:
    """Build ``PulseController.fmu`` (adaptive PWC/PAPWC controller) into ``out_dir``.

    Bundles ``controller/core/`` as the package ``papwc_pulse_core`` and
    ``fmu_src/PulseController/readme.md`` as documentation; the FMU supports
    getFMUstate/setFMUstate and serialization and requires the communication
    step to be the sample period ``T``.

    Parameters
    ----------
    out_dir : Path
        Output folder, created if needed; an existing ``PulseController.fmu``
        there is replaced.

    Returns
    -------
    Path
        ``out_dir / "PulseController.fmu"``.

    Raises
    ------
    BuildError
        If a source is missing, pythonfmu fails, the model description cannot
        be completed, or ``fmpy`` reports a validation problem.
    """
    model_dir = FMU_SRC_DIR / "PulseController"
    script = model_dir / "PulseController.py"
    readme = model_dir / "readme.md"
    for source in (script, readme, CONTROLLER_CORE_DIR / "__init__.py"):
        if not source.is_file():
            raise BuildError(f"cannot build PulseController.fmu: {source} does not exist")
    builder = _pythonfmu_builder()
    out_dir = Path(out_dir)
    work = _work_dir()
    saved_path = list(sys.path)
    # A PulseController FMU loaded earlier in this process left its modules in
    # sys.modules; set them aside so that the model is built from the sources.
    loaded = {
        name: sys.modules.pop(name)
        for name in list(sys.modules)
        if name in (script.stem, CORE_PACKAGE) or name.startswith(CORE_PACKAGE + ".")
    }
    saved_modules = set(sys.modules)
    try:
        src = work / "src"
        src.mkdir()
        shutil.copy2(script, src / script.name)
        package = src / CORE_PACKAGE
        shutil.copytree(
            CONTROLLER_CORE_DIR, package, ignore=shutil.ignore_patterns("__pycache__", "*.pyc")
        )
        doc_dir = work / "doc"
        doc_dir.mkdir()
        shutil.copy2(readme, doc_dir / readme.name)
        try:
            built = builder.build_FMU(
                src / script.name,
                dest=work / "fmu",
                project_files=[package],
                documentation_folder=doc_dir,
                **PULSE_CONTROLLER_OPTIONS,
            )
        except Exception as exc:  # pythonfmu raises what the model script raises
            raise BuildError(
                f"pythonfmu could not build PulseController.fmu from {script}: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        built = Path(built)
        add_units(built, PULSE_CONTROLLER_UNITS, PULSE_CONTROLLER_UNIT_DEFINITIONS)
        edit_model_description(built, _complete_model_description)
        ensure_default_experiment(built, 0.0, 1.0, 0.01)
        problems = validate_fmu(str(built))
        if problems:
            raise BuildError(
                f"{built.name} built from {script} is not valid: " + "; ".join(problems)
            )
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
            target = out_dir / built.name
            shutil.copyfile(built, target)
        except OSError as exc:
            raise BuildError(f"cannot write {built.name} into {out_dir}: {exc}") from exc
        return target
    finally:
        # pythonfmu imports the model from the build folder; forget it so that the
        # FMU, once loaded in this process, imports its own bundled copy.
        sys.path[:] = saved_path
        for name in set(sys.modules) - saved_modules:
            module_file = getattr(sys.modules[name], "__file__", None) or ""
            if module_file.startswith(str(work)):
                del sys.modules[name]
        sys.modules.update(loaded)
        shutil.rmtree(work, ignore_errors=True)
