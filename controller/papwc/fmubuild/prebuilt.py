"""The FMUs' binaries compiled when papwc is installed, so that no compiler runs later.

Compiled C in an FMU is the same bytes for the same ``sources/`` (zig compiles
reproducibly, :mod:`papwc.fmubuild.native_build`): the native FMUs (FrictionPlant,
PulseController) and the loader papwc puts in front of pythonfmu's binary
(PulseControllerPython, :func:`papwc.fmubuild.pythonfmu_build.add_loader`). When papwc is
installed (``pip install`` builds a wheel, or an editable install of a checkout), the build
backend runs :func:`compile_all` with zig, a build requirement: it writes each one's
binaries, with the digest of the ``sources/`` they were compiled from, into the package
folder ``papwc/_native/<Model>/``. ``papwc build`` then takes them (:func:`binaries`) when its
``sources/`` have that digest, and compiles with zig (the ``build`` extra) only when the FMU
sources changed since.

::

    papwc/_native/<Model>/sources.sha256     the digest of sources/ and of the compile
    papwc/_native/<Model>/<platform>/<file>   linux64/<Model>.so, win64/<Model>.dll, ...
"""

from __future__ import annotations

import hashlib
import shutil
from collections.abc import Callable, Iterator, Mapping
from contextlib import AbstractContextManager
from pathlib import Path

__all__ = ["NATIVE_DIR", "binaries", "compile_all", "sources_digest", "take"]

#: Where the installed binaries are: ``papwc/_native/`` beside this package's modules.
NATIVE_DIR = Path(__file__).resolve().parents[1] / "_native"
#: The digest file of one model's binaries.
DIGEST_FILE = "sources.sha256"

#: Further compile flags by platform folder (``compile_binaries``' ``more``).
Flags = Mapping[str, tuple[str, ...]]


def sources_digest(tree: Path, more: Flags | None = None) -> str:
    """SHA-256 (hex) of the files of ``tree/sources/`` and of how they are compiled.

    Parameters
    ----------
    tree : Path
        The folder being built: ``sources/`` holds every C file and header the binaries are
        compiled from (the generated ones included).
    more : mapping of str to tuple of str, optional
        Further compile flags by platform folder.

    Returns
    -------
    str
        The digest: file names and bytes, the compiler's flags, the targets and the zig
        version the project compiles with (:data:`~.native_build.ZIG_VERSION`).
    """
    from papwc.fmubuild.native_build import C_FLAGS, TARGETS, ZIG_VERSION

    h = hashlib.sha256()
    for path in sorted((tree / "sources").iterdir()):
        data = path.read_bytes()
        h.update(path.name.encode() + b"\0" + len(data).to_bytes(8, "little") + data)
    h.update(repr((C_FLAGS, sorted(TARGETS.items()), ZIG_VERSION,
                   sorted((more or {}).items()))).encode())
    return h.hexdigest()


def _files(tree: Path, name: str) -> dict[str, Path]:
    """``tree/binaries/<platform>/<name><suffix>`` by platform folder."""
    from papwc.fmubuild.native_build import TARGETS

    return {folder: tree / "binaries" / folder / f"{name}{suffix}"
            for folder, (_targets, suffix, _extra) in TARGETS.items()}


def take(tree: Path, name: str, native_dir: Path = NATIVE_DIR,
         more: Flags | None = None) -> bool:
    """Copy the installed binaries of ``name`` into ``tree/binaries/`` if they were compiled
    from ``tree/sources/`` as it is (and with the flags ``more``); whether they were.

    Parameters
    ----------
    tree : Path
        The folder being built (``sources/`` written).
    name : str
        The binaries' name (the model identifier).
    native_dir : Path
        The folder of installed binaries (:data:`NATIVE_DIR`).
    more : mapping of str to tuple of str, optional
        Further compile flags by platform folder.

    Returns
    -------
    bool
        True if ``tree/binaries/<platform>/`` now holds the binaries of every platform;
        False if none are installed for these sources (they must be compiled).
    """
    home = native_dir / name
    try:
        recorded = (home / DIGEST_FILE).read_text(encoding="ascii").strip()
    except OSError:
        return False
    if recorded != sources_digest(tree, more):
        return False
    files = _files(tree, name)
    # native_dir/<name>/<platform>/<file>
    installed = {folder: home / folder / path.name for folder, path in files.items()}
    if not all(path.is_file() for path in installed.values()):
        return False
    for folder, path in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(installed[folder], path)
    return True


def binaries(tree: Path, name: str, more: Flags | None = None,
             native_dir: Path = NATIVE_DIR) -> list[Path]:
    """The binaries of ``tree/sources/`` for every platform, in ``tree/binaries/``: the
    installed ones where they were compiled from these sources, else compiled by zig.

    Parameters
    ----------
    tree : Path
        The folder being built (``sources/`` written).
    name : str
        The binaries' name (the model identifier).
    more : mapping of str to tuple of str, optional
        Further compile flags by platform folder.
    native_dir : Path
        The folder of installed binaries (:data:`NATIVE_DIR`).

    Returns
    -------
    list of Path
        ``tree/binaries/<platform>/<name><suffix>``, in the order of ``TARGETS``.

    Raises
    ------
    BuildError
        If they must be compiled and zig is missing or fails.
    """
    from papwc import progress
    from papwc.fmubuild.native_build import compile_binaries

    if take(tree, name, native_dir, more):
        progress.doing(f"taking {name}'s binaries compiled when papwc was installed")
        return list(_files(tree, name).values())
    progress.doing(f"{name}'s C sources differ from those papwc was installed with: "
                   "compiling them")
    return compile_binaries(tree, name, dict(more) if more else None)


def _compiled_trees() -> Iterator[tuple[str, Callable[[], AbstractContextManager[Path]],
                                        Flags | None]]:
    """Every compiled part of the FMUs: (name, a context giving its prepared tree, flags)."""
    from papwc.fmubuild.fmus import FMUS
    from papwc.fmubuild.native_build import prepared_tree
    from papwc.fmubuild.pythonfmu_build import LOADER_FLAGS, loader_tree

    for recipe in FMUS:
        if recipe.native:
            source = recipe.native_source()
            yield source.name, (lambda source=source: prepared_tree(source)), None
        if recipe.loader:
            yield recipe.name, (lambda name=recipe.name: loader_tree(name)), LOADER_FLAGS


def compile_all(native_dir: Path, log: Callable[[str], object] = print) -> list[Path]:
    """Compile every FMU's binaries into ``native_dir`` (run when papwc is installed); those
    there that were compiled from their sources as they are now are kept.

    Parameters
    ----------
    native_dir : Path
        ``papwc/_native/`` of the package being built (replaced model by model).
    log : callable
        Called with one line per model compiled or kept.

    Returns
    -------
    list of Path
        The binaries written.
    """
    from papwc.fmubuild.native_build import TARGETS, compile_binaries

    written = []
    for name, prepared, more in _compiled_trees():
        with prepared() as tree:
            if take(tree, name, native_dir, more):
                log(f"papwc: {name}'s binaries in {native_dir} are current")
                continue
            log(f"papwc: compiling {name}'s binaries for " + ", ".join(TARGETS)
                + " (zig; a first build compiles zig's C runtimes, a few minutes)")
            home = native_dir / name
            shutil.rmtree(home, ignore_errors=True)
            for binary in compile_binaries(tree, name, dict(more) if more else None):
                target = home / binary.parent.name / binary.name
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(binary, target)
                written.append(target)
            (home / DIGEST_FILE).write_text(sources_digest(tree, more) + "\n",
                                            encoding="ascii")
    return written
