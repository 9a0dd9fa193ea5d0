"""What a non-Python FMI host needs to load the project's pythonfmu FMUs, for this interpreter.

The native FrictionPlant.fmu (``papwc build``'s default) needs nothing. A pythonfmu 0.7.0
FMU (PulseController.fmu, PapwcTrivial.fmu, FrictionPlant.fmu of ``papwc build --backend
pythonfmu``) embeds the Python interpreter, but its binary does not
link libpython: a Python host has the library loaded already; a C or C++ host
(ecos, fmusim, OMSimulator, the FMI Compliance Checker) must load it first:

- Linux: ``LD_PRELOAD=<libpython3.X.so.1.0>`` of an interpreter 3.10 or newer
  (without it the host fails with ``undefined symbol: _Py_NoneStruct`` or
  crashes);
- Windows: the folder of ``python3.dll`` on ``PATH``;
- macOS: pythonfmu 0.7.0 ships no macOS binary.

:func:`host_environment` finds the library of the interpreter this code runs
on, so the line it gives fits the ``papwc`` installation.
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
from pathlib import Path

from papwc.errors import PapwcError

__all__ = ["host_environment", "libpython"]


def libpython() -> Path:
    """The shared libpython of the running interpreter (Linux).

    Looked for, in order: ``LIBDIR/INSTSONAME`` of the interpreter's build, the
    multiarch library folders, and the ``ldconfig`` cache.

    Raises
    ------
    PapwcError
        If no ``libpython3.X.so.1.0`` of this interpreter's version is found.
    """
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    soname = sysconfig.get_config_var("INSTSONAME") or f"libpython{version}.so.1.0"
    if not soname.endswith(".so.1.0") and ".so" not in soname:
        soname = f"libpython{version}.so.1.0"  # a static build names its .a here
    folders = [sysconfig.get_config_var("LIBDIR"), os.path.join(sys.base_prefix, "lib")]
    multiarch = sysconfig.get_config_var("MULTIARCH")
    if multiarch:
        folders += [f"/usr/lib/{multiarch}", f"/lib/{multiarch}"]
    folders += ["/usr/lib", "/usr/lib64", "/usr/local/lib"]
    for folder in folders:
        if folder and (Path(folder) / soname).is_file():
            return Path(folder) / soname
    try:
        listing = subprocess.run(["ldconfig", "-p"], capture_output=True, text=True,
                                 timeout=10, check=False).stdout
    except (OSError, subprocess.SubprocessError):
        listing = ""
    for line in listing.splitlines():
        name, _, target = line.strip().partition(" => ")
        if name.split(" ", 1)[0] == soname and Path(target).is_file():
            return Path(target)
    raise PapwcError(
        f"no {soname} found for Python {version} ({sys.executable}): a non-Python FMI host "
        f"needs it; install a Python built with --enable-shared, or Debian's "
        f"libpython{version}"
    )


def host_environment(platform: str | None = None) -> str:
    """The shell line that lets a non-Python host load the FMUs on this machine.

    Raises
    ------
    PapwcError
        On macOS (no pythonfmu 0.7.0 binary), or if the library is not found.
    """
    platform = platform or sys.platform
    if platform.startswith("linux"):
        import shlex

        path = str(libpython())
        if any(c in path for c in " :\t\n"):
            # the dynamic loader splits LD_PRELOAD at spaces and colons, quoted or not
            raise PapwcError(f"{path!r}: LD_PRELOAD cannot hold a path with a space or colon; "
                             "link the library to a path without them and preload the link")
        return f"export LD_PRELOAD={shlex.quote(path)}"
    if platform.startswith(("win32", "cygwin")):
        folder = Path(sys.base_prefix)
        if not (folder / "python3.dll").is_file():
            raise PapwcError(f"no python3.dll in {folder}")
        return f'set "PATH={folder};%PATH%"'
    raise PapwcError(f"platform {platform!r}: pythonfmu 0.7.0 FMUs have binaries for Linux "
                     "and Windows only")


def ecos_executable() -> Path:
    """The ``ecos`` program of the ecospy wheel, executable.

    The wheel installs ``ecospy/binaries/ecos`` (and its ``proxyfmu``) without the
    run bit; they are made executable in place, or, where the package folder is
    read-only, copied into ``~/.cache/papwc/ecos-<ecospy version>/`` and made
    executable there.

    Raises
    ------
    PapwcError
        If ecospy is not installed or holds no ``ecos`` program.
    """
    import os
    import shutil
    import stat

    try:
        import ecospy
    except (ImportError, OSError) as exc:  # OSError: libtbb.so.12 missing
        raise PapwcError(f"ecos needs the ecospy package (pip install -e '.[test]', and "
                         f"Debian's libtbb12): {exc}") from None
    folder = Path(ecospy.__file__).parent / "binaries"
    names = [n for n in ("ecos", "proxyfmu") if (folder / n).is_file()]
    if "ecos" not in names:
        raise PapwcError(f"no ecos program in {folder}")
    if all(os.access(folder / n, os.X_OK) for n in names):
        return folder / "ecos"
    try:
        for name in names:
            path = folder / name
            path.chmod(path.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
        return folder / "ecos"
    except OSError:
        pass
    version = getattr(ecospy, "__version__", "unknown")
    cache = Path.home() / ".cache" / "papwc" / f"ecos-{version}"
    cache.mkdir(parents=True, exist_ok=True)
    for name in names:
        target = cache / name
        if not os.access(target, os.X_OK):
            shutil.copyfile(folder / name, target)
            target.chmod(0o755)
    return cache / "ecos"


def ecos_main(argv: list[str] | None = None) -> int:
    """The ``ecos`` console script: ecospy's ecos program, runnable, with libpython preloaded.

    ``ecos simulate --path build/ClosedLoop.ssp ...`` then works in the venv as the
    README writes it (the wheel's own program lacks the run bit, and a C++ host needs
    libpython preloaded to load the project's FMUs, see :func:`host_environment`).
    """
    import os

    try:
        program = ecos_executable()
        env = dict(os.environ)
        if sys.platform.startswith("linux"):
            lib = str(libpython())
            env["LD_PRELOAD"] = " ".join(p for p in (lib, env.get("LD_PRELOAD", "")) if p)
    except PapwcError as exc:
        print(f"ecos: error: {exc}", file=sys.stderr)
        return 2
    args = list(sys.argv[1:] if argv is None else argv)
    os.execve(program, [str(program), *args], env)
    return 0  # not reached
