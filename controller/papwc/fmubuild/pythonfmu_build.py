"""Build one FMI 2.0 Co-Simulation FMU with pythonfmu, reproducibly.

:func:`build_pythonfmu` is the recipe every FMU of the project goes through:

1. assemble, in a fresh temporary folder whose path has only ASCII letters,
   digits and ``_`` (pythonfmu 0.7.0 hosts crash on other percent-encoded
   characters in the extraction path), the model script and its bundle: a
   package of the script's own name holding copies of the project's
   subpackages (``model``, ``fmi``, ``controllers``), so that FMUs loaded into
   one process never share a module;
2. build with ``pythonfmu.FmuBuilder.build_FMU``;
3. complete the model description from the variables' metadata
   (:func:`papwc.fmubuild.model_description.complete_model_description`), with
   a GUID that is a digest of everything bundled, and rewrite the archive
   reproducibly: the same sources give the same bytes;
4. with ``loader``: put pythonfmu's binary beside the loader of ``fmu_src/fmi2/
   python_loader.c`` (compiled by zig for linux64, win64 and darwin64) under the name
   ``pythonfmu-<Model>``, the loader in its place: in a host with no Python it refuses
   fmi2Instantiate in one line instead of failing to load or crashing (:func:`add_loader`);
5. check the result with ``fmpy.validation.validate_fmu`` and copy it into the
   output folder.
"""

from __future__ import annotations

import contextlib
import hashlib
import re
import shutil
import sys
import tempfile
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from papwc.errors import BuildError
from papwc.fmubuild.model_description import (
    complete_model_description,
    install_fmu,
    rewrite_fmu,
)
from papwc.model.variables import Variable

__all__ = ["PYTHON_MIN", "STATE_OPTIONS", "FmuSource", "add_loader", "build_pythonfmu", "guid",
           "loader_tree"]

#: CoSimulation capability flags set on every FMU of the project unless told otherwise.
STATE_OPTIONS: dict[str, bool] = {
    "canHandleVariableCommunicationStepSize": True,
    "canGetAndSetFMUstate": True,
    "canSerializeFMUstate": True,
}

#: Characters allowed in the path of the folder where an FMU is assembled.
_SAFE_PATH = re.compile(r"[A-Za-z0-9_/]+")
#: Files never bundled.
_IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", "*.pyo")


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


#: Oldest Python a pythonfmu FMU of the project runs in (its bundled code needs 3.10).
PYTHON_MIN = (3, 10)


def _bundle_init(name: str) -> str:
    """The bundle package's ``__init__.py``: refuses an older Python with one clear line.

    A pythonfmu FMU runs in the host's Python; an older one would fail at the first call
    that reaches code it cannot run (fmi2Fatal). The error raised here makes
    fmi2Instantiate fail with this message instead.
    """
    low = ".".join(map(str, PYTHON_MIN))
    return (
        f'"""The papwc code bundled into {name}.fmu (model layer, glue)."""\n\n'
        "import sys\n\n"
        f"if sys.version_info < {PYTHON_MIN!r}:\n"
        f"    raise ImportError(\"{name}.fmu (pythonfmu) needs Python {low} or newer in the \"\n"
        "                      \"host; this host runs Python \" + sys.version.split()[0]\n"
        f"                      + \" (papwc build's native FrictionPlant.fmu needs no \"\n"
        "                      \"Python)\")\n"
    )


def _files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file()
                  and "__pycache__" not in p.parts and p.suffix not in (".pyc", ".pyo"))


@dataclass(frozen=True)
class FmuSource:
    """What one pythonfmu FMU is built from.

    Attributes
    ----------
    script : Path
        The model script; its ``Fmi2Slave`` class name is the model identifier.
    variables : tuple of Variable
        Metadata of every variable the model declares.
    package : str
        Name of the bundle package in ``resources/`` (the script imports it); ""
        for none.
    bundle : dict of str to Path
        Subpackage name -> source folder, copied into ``package``.
    documentation : tuple of Path
        Files put into the FMU's ``documentation/`` folder.
    default_experiment : (float, float, float)
        Start time, stop time and step size (s) written if the model sets none.
    options : dict of str to bool
        CoSimulation capability flags.
    loader : bool
        Put papwc's loader in front of pythonfmu's binary (:func:`add_loader`).
    """

    script: Path
    variables: tuple[Variable, ...]
    package: str = ""
    bundle: dict[str, Path] = field(default_factory=dict)
    documentation: tuple[Path, ...] = ()
    default_experiment: tuple[float, float, float] = (0.0, 1.0, 0.01)
    options: dict[str, bool] = field(default_factory=lambda: dict(STATE_OPTIONS))
    loader: bool = False

    def check(self) -> None:
        """Raise BuildError if a source is missing."""
        name = Path(self.script).stem
        for source in (self.script, *self.documentation):
            if not Path(source).is_file():
                raise BuildError(f"cannot build {name}.fmu: source file {source} does not exist")
        for source in self.bundle.values():
            if not Path(source).is_dir():
                raise BuildError(f"cannot build {name}.fmu: source {source} does not exist")
        if self.bundle and not self.package:
            raise BuildError(f"cannot build {name}.fmu: a bundle needs a package name")

    def digest(self) -> str:
        """SHA-256 (hex) of everything the FMU is built from.

        Covers the script, every bundled file (by its place in the bundle), the
        documentation, the variables' metadata, the options and the pythonfmu
        version.
        """
        import pythonfmu

        h = hashlib.sha256()

        def add(label: str, data: bytes) -> None:
            h.update(label.encode() + b"\0" + len(data).to_bytes(8, "little") + data)

        add("script:" + Path(self.script).name, Path(self.script).read_bytes())
        for name, folder in sorted(self.bundle.items()):
            for path in _files(Path(folder)):
                add(f"bundle:{name}/{path.relative_to(folder).as_posix()}", path.read_bytes())
        for path in sorted(Path(p) for p in self.documentation):
            add("doc:" + path.name, path.read_bytes())
        add("extra", repr((self.package, sorted(self.options.items()), list(self.variables),
                           self.default_experiment)).encode())
        add("pythonfmu", pythonfmu.__version__.encode())
        if self.package:
            add("init", _bundle_init(Path(self.script).stem).encode())
        if self.loader:
            from papwc.fmubuild.native_build import C_FLAGS, TARGETS, ZIG_VERSION

            add("loader", _loader_source().read_bytes() + repr(
                (C_FLAGS, sorted(TARGETS.items()), ZIG_VERSION, PYTHON_MIN)).encode())
        return h.hexdigest()


def _loader_source() -> Path:
    from papwc.resources import fmu_src_dir

    return fmu_src_dir() / "fmi2" / "python_loader.c"


#: The name under which a loader finds pythonfmu's binary beside itself.
LOADER_PREFIX = "pythonfmu-"


#: Further flags of the loader's compile, by platform folder (dlopen is in libdl there).
LOADER_FLAGS = {"linux64": ("-ldl",)}


@contextlib.contextmanager
def loader_tree(model: str) -> Iterator[Path]:
    """A temporary folder whose ``sources/`` holds what the loader of ``model`` is compiled
    from: ``python_loader.c``, the FMI headers and its ``loader_config.h``; removed after."""
    from papwc.fmubuild.native_build import FMI2_HEADERS, fmi_headers_dir

    work = Path(tempfile.mkdtemp(prefix="papwc_loader_"))
    try:
        tree = work / "tree"
        sources = tree / "sources"
        sources.mkdir(parents=True)
        shutil.copyfile(_loader_source(), sources / "python_loader.c")
        headers = fmi_headers_dir()
        for header in FMI2_HEADERS:
            shutil.copyfile(headers / header, sources / header)
        major, minor = PYTHON_MIN
        (sources / "loader_config.h").write_text(
            "/* loader_config.h: generated by papwc.fmubuild.pythonfmu_build. Do not edit. */\n"
            f'#define LOADER_MODEL "{model}"\n'
            "#if defined(_WIN32)\n"
            f'#define LOADER_INNER "{LOADER_PREFIX}{model}.dll"\n'
            "#else\n"
            f'#define LOADER_INNER "{LOADER_PREFIX}{model}.so"\n'
            "#endif\n"
            f"#define LOADER_PYTHON_MAJOR {major}\n#define LOADER_PYTHON_MINOR {minor}\n",
            encoding="utf-8")
        yield tree
    finally:
        shutil.rmtree(work, ignore_errors=True)


def add_loader(fmu: Path, model: str) -> None:
    """Put papwc's loader (``fmu_src/fmi2/python_loader.c``) in front of pythonfmu's binary.

    pythonfmu's ``binaries/<platform>/<model>.<so|dll>`` becomes
    ``pythonfmu-<model>.<so|dll>``; the loader, compiled for every platform of
    :data:`papwc.fmubuild.native_build.TARGETS` (darwin64 too, where pythonfmu has none;
    the binaries compiled when papwc was installed, :mod:`papwc.fmubuild.prebuilt`), takes
    its name. It loads pythonfmu's binary only where the host process has a Python
    :data:`PYTHON_MIN` or newer, and else refuses fmi2Instantiate in one line.
    """
    import zipfile

    from papwc.fmubuild.prebuilt import binaries

    with loader_tree(model) as tree:
        loaders = binaries(tree, model, LOADER_FLAGS)
        with zipfile.ZipFile(fmu) as archive:
            members = {info.filename: archive.read(info) for info in archive.infolist()
                       if not info.is_dir()}
        for loader in loaders:
            platform = loader.parent.name
            own = f"binaries/{platform}/{loader.name}"
            if own in members:  # pythonfmu's binary moves aside
                inner = f"binaries/{platform}/{LOADER_PREFIX}{model}{loader.suffix}"
                members[inner] = members.pop(own)
            members[own] = loader.read_bytes()
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)


def guid(digest: str) -> str:
    """The GUID of an FMU built from sources of digest ``digest`` (see :func:`source_digest`)."""
    return "{" + str(uuid.UUID(digest[:32])) + "}"


def build_pythonfmu(source: FmuSource, out_dir: Path) -> Path:
    """Build one pythonfmu FMU, complete its model description, validate it.

    Parameters
    ----------
    source : FmuSource
        What the FMU is built from.
    out_dir : Path
        Folder the ``<modelIdentifier>.fmu`` is written to (created if needed;
        an existing FMU of that name is replaced).

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
    from fmpy.validation import validate_fmu

    source.check()
    script = Path(source.script)
    package = source.package
    digest = source.digest()
    builder = _pythonfmu_builder()
    out_dir = Path(out_dir)
    work = _safe_temp_dir()
    saved_path = list(sys.path)
    shadowed = tuple(m for m in (script.stem, package) if m)
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
        project_files = []
        if package:
            target = src / package
            target.mkdir()
            (target / "__init__.py").write_text(_bundle_init(script.stem))
            for name, folder in sorted(source.bundle.items()):
                shutil.copytree(folder, target / name, ignore=_IGNORE)
            project_files.append(target)
        doc_dir = None
        if source.documentation:
            doc_dir = work / "doc"
            doc_dir.mkdir()
            for doc in source.documentation:
                shutil.copy2(doc, doc_dir / Path(doc).name)
        try:
            built = builder.build_FMU(
                src / script.name,
                dest=work / "fmu",
                project_files=project_files,
                documentation_folder=doc_dir,
                **source.options,
            )
        except Exception as exc:  # pythonfmu raises what the model script raises
            raise BuildError(
                f"pythonfmu could not build an FMU from {script}: {type(exc).__name__}: {exc}"
            ) from exc
        built = Path(built)
        if source.loader:
            add_loader(built, script.stem)
        rewrite_fmu(built, lambda root: complete_model_description(
            root, source.variables, guid=guid(digest),
            default_experiment=source.default_experiment, where=built.name))
        problems = validate_fmu(str(built))
        if problems:
            raise BuildError(
                f"{built.name} built from {script} is not valid: " + "; ".join(problems)
            )
        return install_fmu(built, out_dir)
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
