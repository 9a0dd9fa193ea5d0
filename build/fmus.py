"""Build the project's FMI 2.0 Co-Simulation FMUs with pythonfmu.

:func:`build_pythonfmu` is the generic recipe (used for every FMU of the
project): copy the model script and its project files into a fresh temporary
folder whose path has only ASCII letters, digits and ``_``, build with
``pythonfmu.FmuBuilder.build_FMU``, add units and a ``DefaultExperiment`` to the
model description (:mod:`papwc.build.model_description`), check the result with
``fmpy.validation.validate_fmu`` and move it into the output folder.

:func:`build_friction_plant` and :func:`build_trivial` apply it to
``fmu_src/FrictionPlant`` and ``fmu_src/PapwcTrivial``.
"""

from __future__ import annotations

import re
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Mapping
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
    "FRICTION_PLANT_UNITS",
    "STATE_OPTIONS",
    "build_friction_plant",
    "build_pythonfmu",
    "build_trivial",
]

#: Unit of every Real variable of FrictionPlant.fmu.
FRICTION_PLANT_UNITS: dict[str, str] = {
    "m": "kg",
    "f_c": "N",
    "f_s": "N",
    "c": "N.s/m",
    "x0": "m",
    "v0": "m/s",
    "x_resolution": "m",
    "u": "N",
    "x": "m",
    "v": "m/s",
    "x_meas": "m",
}

#: CoSimulation capability flags set on every FMU of the project.
STATE_OPTIONS: dict[str, bool] = {
    "canHandleVariableCommunicationStepSize": True,
    "canGetAndSetFMUstate": True,
    "canSerializeFMUstate": True,
}

#: Characters allowed in the path of the folder where an FMU is assembled.
_SAFE_PATH = re.compile(r"[A-Za-z0-9_/]+")


def _safe_temp_dir() -> Path:
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
            f"in {binaries}: it is the copy bundled in an FMU loaded earlier; build the "
            "FMUs before loading any pythonfmu FMU, or in a new process"
        )
    return FmuBuilder


def build_pythonfmu(
    script: Path,
    out_dir: Path,
    *,
    project_files: Iterable[Path | tuple[Path, str]] = (),
    units: Mapping[str, str] | None = None,
    unit_definitions: Mapping[str, Mapping[str, int]] | None = None,
    documentation: Iterable[Path] = (),
    default_experiment: tuple[float, float, float] = (0.0, 1.0, 0.01),
    options: Mapping[str, bool] | None = None,
    edit: Callable[[ET.Element], None] | None = None,
    shadowed_modules: Iterable[str] = (),
) -> Path:
    """Build one pythonfmu FMU, add units and a default experiment, validate it.

    Parameters
    ----------
    script : Path
        The model script; its ``Fmi2Slave`` class name is the model identifier.
    out_dir : Path
        Folder the ``<modelIdentifier>.fmu`` is written to (created if needed;
        an existing FMU of that name is replaced).
    project_files : iterable of Path or (Path, str)
        Files or folders bundled into ``resources/`` beside the script
        (importable by name); ``(source, name)`` bundles ``source`` as ``name``
        (e.g. a package folder under a name no other FMU uses).
    units : mapping of str to str, optional
        Variable name -> unit, see :func:`papwc.build.model_description.add_units`.
    unit_definitions : mapping, optional
        Units beyond :data:`papwc.build.model_description.UNIT_DEFINITIONS`.
    documentation : iterable of Path
        Files put into the FMU's ``documentation/`` folder.
    default_experiment : (float, float, float)
        Start time, stop time and step size (s) written if the model sets none.
    options : mapping of str to bool, optional
        CoSimulation capability flags; default :data:`STATE_OPTIONS`.
    edit : callable, optional
        ``edit(root)`` completes the model description (after the units).
    shadowed_modules : iterable of str
        Modules (with their submodules) that an FMU loaded earlier in this
        process left in ``sys.modules``; they are set aside during the build so
        that the model is built from the sources, and put back afterwards.

    Returns
    -------
    Path
        The FMU written.

    Raises
    ------
    BuildError
        If a source file is missing, pythonfmu fails, the model description
        cannot be completed, or ``fmpy`` reports a validation problem.
    """
    script = Path(script)
    bundled = [(Path(p), Path(p).name) if isinstance(p, (str, Path)) else (Path(p[0]), p[1])
               for p in project_files]
    documentation = [Path(p) for p in documentation]
    for source in (script, *documentation):
        if not source.is_file():
            raise BuildError(f"cannot build {script.stem}.fmu: source file {source} does not exist")
    for source, _ in bundled:
        if not source.exists():
            raise BuildError(f"cannot build {script.stem}.fmu: source {source} does not exist")
    builder = _pythonfmu_builder()
    out_dir = Path(out_dir)
    work = _safe_temp_dir()
    saved_path = list(sys.path)
    shadowed = tuple(shadowed_modules)
    loaded = {
        name: sys.modules.pop(name)
        for name in list(sys.modules)
        if name in shadowed or name.startswith(tuple(m + "." for m in shadowed))
    }
    saved_modules = set(sys.modules)
    try:
        src = work / "src"
        src.mkdir()
        shutil.copy2(script, src / script.name)
        for source, name in bundled:
            if source.is_dir():
                shutil.copytree(
                    source, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc")
                )
            else:
                shutil.copy2(source, src / name)
        doc_dir = None
        if documentation:
            doc_dir = work / "doc"
            doc_dir.mkdir()
            for source in documentation:
                shutil.copy2(source, doc_dir / source.name)
        built_dir = work / "fmu"
        try:
            built = builder.build_FMU(
                src / script.name,
                dest=built_dir,
                project_files=[src / name for _, name in bundled],
                documentation_folder=doc_dir,
                **dict(STATE_OPTIONS if options is None else options),
            )
        except Exception as exc:  # pythonfmu raises what the model script raises
            raise BuildError(
                f"pythonfmu could not build an FMU from {script}: {type(exc).__name__}: {exc}"
            ) from exc
        built = Path(built)
        if units:
            add_units(built, units, unit_definitions)
        if edit is not None:
            edit_model_description(built, edit)
        ensure_default_experiment(built, *default_experiment)
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
        # pythonfmu imports the model from the build folder; forget it so that an
        # FMU loaded later in this process imports its own bundled copy.
        sys.path[:] = saved_path
        for name in set(sys.modules) - saved_modules:
            module_file = getattr(sys.modules[name], "__file__", None) or ""
            if module_file.startswith(str(work)):
                del sys.modules[name]
        sys.modules.update(loaded)
        shutil.rmtree(work, ignore_errors=True)


def build_friction_plant(out_dir: Path) -> Path:
    """Build ``FrictionPlant.fmu`` (exact stick-slip plant) into ``out_dir``.

    Bundles ``fmu_src/papwc_stickslip.py`` and ``readme.md`` (as documentation);
    enables variable step sizes, getFMUstate/setFMUstate and serialization.

    Parameters
    ----------
    out_dir : Path
        Output folder, created if needed.

    Returns
    -------
    Path
        ``out_dir / "FrictionPlant.fmu"``.
    """
    model_dir = FMU_SRC_DIR / "FrictionPlant"
    return build_pythonfmu(
        model_dir / "FrictionPlant.py",
        out_dir,
        project_files=[FMU_SRC_DIR / "papwc_stickslip.py"],
        units=FRICTION_PLANT_UNITS,
        documentation=[model_dir / "readme.md"],
    )


def build_trivial(out_dir: Path) -> Path:
    """Build ``PapwcTrivial.fmu`` (input copied to output, benchmark floor) into ``out_dir``.

    Parameters
    ----------
    out_dir : Path
        Output folder, created if needed.

    Returns
    -------
    Path
        ``out_dir / "PapwcTrivial.fmu"``.
    """
    return build_pythonfmu(
        FMU_SRC_DIR / "PapwcTrivial" / "PapwcTrivial.py",
        out_dir,
        units={"u": "1", "y": "1"},
    )
