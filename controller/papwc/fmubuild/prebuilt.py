"""The native FMUs' binaries compiled when papwc is installed, so that no compiler runs later.

A native FMU's binaries are the same bytes for the same ``sources/`` (zig compiles
reproducibly, :mod:`papwc.fmubuild.native_build`). When papwc is installed (``pip install``
builds a wheel, or an editable install of a checkout), the build backend runs
:func:`compile_all` with zig, a build requirement: it writes each native FMU's binaries,
with the digest of the ``sources/`` they were compiled from, into the package folder
``papwc/_native/<Model>/``. ``papwc build`` then takes them (:func:`take`) when its
``sources/`` have that digest, and compiles with zig (the ``build`` extra) only when the FMU
sources changed since.

::

    papwc/_native/<Model>/sources.sha256     the digest of sources/ and of the compile
    papwc/_native/<Model>/<platform>/<file>   linux64/<Model>.so, win64/<Model>.dll, ...
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

__all__ = ["NATIVE_DIR", "compile_all", "sources_digest", "take"]

#: Where the installed binaries are: ``papwc/_native/`` beside this package's modules.
NATIVE_DIR = Path(__file__).resolve().parents[1] / "_native"
#: The digest file of one model's binaries.
DIGEST_FILE = "sources.sha256"


def sources_digest(tree: Path) -> str:
    """SHA-256 (hex) of the files of ``tree/sources/`` and of how they are compiled.

    Parameters
    ----------
    tree : Path
        The FMU's folder being built: ``sources/`` holds every C file and header the
        binaries are compiled from (the generated ones included).

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
    h.update(repr((C_FLAGS, sorted(TARGETS.items()), ZIG_VERSION)).encode())
    return h.hexdigest()


def take(tree: Path, name: str, native_dir: Path = NATIVE_DIR) -> bool:
    """Copy the installed binaries of model ``name`` into ``tree/binaries/`` if they were
    compiled from ``tree/sources/`` as it is; whether they were.

    Parameters
    ----------
    tree : Path
        The FMU's folder being built (``sources/`` written).
    name : str
        Model identifier.
    native_dir : Path
        The folder of installed binaries (:data:`NATIVE_DIR`).

    Returns
    -------
    bool
        True if ``tree/binaries/<platform>/`` now holds the binaries of every platform;
        False if none are installed for these sources (they must be compiled).
    """
    from papwc.fmubuild.native_build import TARGETS

    home = native_dir / name
    try:
        recorded = (home / DIGEST_FILE).read_text(encoding="ascii").strip()
    except OSError:
        return False
    if recorded != sources_digest(tree):
        return False
    files = {folder: home / folder / f"{name}{suffix}"
             for folder, (_targets, suffix, _extra) in TARGETS.items()}
    if not all(path.is_file() for path in files.values()):
        return False
    for folder, path in files.items():
        (tree / "binaries" / folder).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, tree / "binaries" / folder / path.name)
    return True


def compile_all(native_dir: Path, log=print) -> list[Path]:
    """Compile every native FMU's binaries into ``native_dir`` (run when papwc is installed);
    a model whose binaries there were compiled from its sources as they are is kept.

    Parameters
    ----------
    native_dir : Path
        ``papwc/_native/`` of the package being built (replaced model by model).
    log : callable
        Called with one line per model and platform compiled.

    Returns
    -------
    list of Path
        The binaries written.
    """
    from papwc.fmubuild.fmus import FMUS
    from papwc.fmubuild.native_build import prepared_tree

    written = []
    for recipe in FMUS:
        if not recipe.native:
            continue
        source = recipe.native_source()
        with prepared_tree(source) as tree:
            if take(tree, source.name, native_dir):
                log(f"papwc: {source.name}'s binaries in {native_dir} are current")
                continue
            log(f"papwc: compiling {source.name}'s binaries for "
                + ", ".join(source_targets()) + " (zig; a first build compiles zig's C "
                "runtimes, a few minutes)")
            from papwc.fmubuild.native_build import compile_binaries

            compile_binaries(tree, source.name)
            home = native_dir / source.name
            shutil.rmtree(home, ignore_errors=True)
            for binary in sorted((tree / "binaries").rglob("*")):
                if binary.is_file():
                    target = home / binary.relative_to(tree / "binaries")
                    target.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(binary, target)
                    written.append(target)
            (home / DIGEST_FILE).write_text(sources_digest(tree) + "\n", encoding="ascii")
    return written


def source_targets() -> list[str]:
    """The FMI platform folders the binaries are compiled for."""
    from papwc.fmubuild.native_build import TARGETS

    return list(TARGETS)
