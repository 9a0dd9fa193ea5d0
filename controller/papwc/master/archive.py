"""The one door through which every FMU and SSP archive is opened.

Every failure of opening, unpacking, loading or reading an archive becomes one
error naming the file (and, inside an SSP, the component) and what is wrong;
what was unpacked is removed; what is unpacked is bounded before anything is
written (members, total size, the size of an XML file read into memory), and
the bound is in the message.

- :func:`open_zip`: an archive's table of contents, checked: a zip file, at most
  :data:`MAX_MEMBERS` members, no member encrypted or compressed by a method
  that cannot be read, no member name that leaves the folder, at most
  ``max_bytes`` unpacked.
- :func:`read_member`: one member's bytes, bounded, every decompression error
  turned into the error asked for.
- :func:`unpack`: an FMU unpacked into a new private temporary folder (removed
  if anything fails).
- :func:`load_library`: the FMU's shared library for this platform, loaded by
  fmpy; a missing binary, a library that does not load (a foreign or broken
  ``.so``) or lacks an FMI 2.0 function is named.

Callers say which error class to raise (:class:`~papwc.errors.FmuError` for an
FMU, :class:`~papwc.errors.SspError` for an SSP).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
import zipfile
import zlib
from pathlib import Path, PurePosixPath
from typing import Any

from papwc.errors import FmuError, PapwcError

__all__ = [
    "MAX_MEMBERS",
    "MAX_UNPACKED_BYTES",
    "MAX_XML_BYTES",
    "load_library",
    "open_zip",
    "size_text",
    "read_member",
    "read_model_description",
    "unpack",
    "unpacked_bytes",
]

#: Most members of an FMU or SSP archive.
MAX_MEMBERS = 10_000
#: Most bytes an FMU unpacks to (the sum of its members' sizes); also the most
#: the FMUs of one SSP unpack to together.
MAX_UNPACKED_BYTES = 512 * 1024 * 1024
#: Largest XML file read into memory (modelDescription.xml, an SSD, an SSV), bytes.
MAX_XML_BYTES = 64 * 1024 * 1024
#: Compression methods read (stored, deflate, bzip2, lzma).
_METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate",
            zipfile.ZIP_BZIP2: "bzip2", zipfile.ZIP_LZMA: "lzma"}
#: What reading a damaged member raises.
_READ_ERRORS = (OSError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error,
                RuntimeError, NotImplementedError, ValueError, LookupError, MemoryError)
#: Prefix of the temporary folders of unpacked FMUs.
TMP_PREFIX = "papwcfmu"


def size_text(n: int) -> str:
    for unit, size in (("GiB", 1 << 30), ("MiB", 1 << 20), ("kiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.4g} {unit}"
    return f"{n} bytes"


def _name_problem(name: str) -> str | None:
    """Why a member name cannot be unpacked (leaves the folder, a device path), or None."""
    if "\\" in name or ":" in name or "\0" in name:
        return "has a backslash, colon or NUL in its name"
    path = PurePosixPath(name)
    if path.is_absolute() or ".." in path.parts:
        return "leaves the folder it is unpacked into"
    return None


def open_zip(path: Path | bytes, where: str, error: type[PapwcError] = FmuError,
             max_bytes: int = MAX_UNPACKED_BYTES, what: str = "FMU") -> zipfile.ZipFile:
    """Open ``path`` (a file, or an archive's bytes) as a zip archive and check its table of
    contents (see the module docstring).

    ``where`` opens every message; ``what`` names the kind of archive. The
    caller closes the returned archive.
    """
    if isinstance(path, bytes):
        import io

        source: Any = io.BytesIO(path)
    elif not path.is_file():
        why = "is not a regular file" if path.exists() else "does not exist"
        raise error(f"{where}: {why}")
    else:
        source = path
    try:
        zf = zipfile.ZipFile(source)
    except zipfile.BadZipFile as exc:
        raise error(f"{where}: not a zip archive ({exc}), so not an {what}") from None
    except _READ_ERRORS as exc:
        raise error(f"{where}: cannot open the {what}: {_reason(exc)}") from None
    try:
        _check_contents(zf, where, error, max_bytes)
    except BaseException:
        zf.close()
        raise
    return zf


def unpacked_bytes(zf: zipfile.ZipFile) -> int:
    """What an archive unpacks to: the sum of its members' sizes, bytes."""
    return sum(info.file_size for info in zf.infolist())


def _check_contents(zf: zipfile.ZipFile, where: str, error: type[PapwcError],
                    max_bytes: int) -> None:
    infos = zf.infolist()
    if len(infos) > MAX_MEMBERS:
        raise error(f"{where}: {len(infos)} archive members; at most {MAX_MEMBERS} are read")
    total = 0
    for info in infos:
        problem = _name_problem(info.filename)
        if problem is None:
            problem = _kind_problem(info)
        if problem is None and info.flag_bits & 0x1:
            problem = "is encrypted"
        if problem is None and info.compress_type not in _METHODS:
            problem = (f"is compressed with method {info.compress_type}; readable: "
                       + ", ".join(f"{k} ({v})" for k, v in _METHODS.items()))
        if problem is not None:
            raise error(f"{where}: member {info.filename!r} {problem}")
        total += info.file_size
    if total > max_bytes:
        raise error(f"{where}: unpacks to {size_text(total)}; at most {size_text(max_bytes)}")


#: Unix file types a member may have (a zip written on Unix keeps the mode): the others
#: (a symbolic link, a device, a FIFO, a socket) are refused, not unpacked as files.
_UNIX_KINDS = {stat.S_IFREG: "file", stat.S_IFDIR: "folder", stat.S_IFLNK: "symbolic link",
               stat.S_IFCHR: "character device", stat.S_IFBLK: "block device",
               stat.S_IFIFO: "FIFO", stat.S_IFSOCK: "socket"}


def _kind_problem(info: zipfile.ZipInfo) -> str | None:
    """Why a member is not a file or folder (a symbolic link, a device ...), or None."""
    mode = info.external_attr >> 16
    kind = stat.S_IFMT(mode)
    if info.create_system != 3 or kind in (0, stat.S_IFREG, stat.S_IFDIR):
        return None
    return (f"is a {_UNIX_KINDS.get(kind, f'file of type {kind:#o}')}; an archive is read "
            "as regular files and folders only")


def _reason(exc: BaseException) -> str:
    if isinstance(exc, MemoryError):
        return "out of memory"
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    text = str(exc) or type(exc).__name__
    return text.splitlines()[0] if text.strip() else type(exc).__name__


def read_member(zf: zipfile.ZipFile, name: str, where: str, error: type[PapwcError] = FmuError,
                limit: int = MAX_XML_BYTES) -> bytes:
    """The bytes of member ``name`` (at most ``limit``); a damaged member raises ``error``."""
    try:
        info = zf.getinfo(name)
    except KeyError:
        raise error(f"{where}: the archive has no {name}") from None
    if info.file_size > limit:
        raise error(f"{where}: {name} is {size_text(info.file_size)}; at most {size_text(limit)} "
                    "are read")
    try:
        with zf.open(info) as f:
            data = f.read(limit + 1)
    except _READ_ERRORS as exc:
        raise error(f"{where}: cannot read {name}: {_reason(exc)}") from None
    if len(data) > limit:
        raise error(f"{where}: {name} is larger than {size_text(limit)}")
    return data


def unpack(path: Path, where: str, max_bytes: int = MAX_UNPACKED_BYTES) -> str:
    """Unpack the FMU ``path`` into a new private temporary folder; return the folder.

    Each file is created anew (never through a link); at most ``max_bytes`` are
    written. If anything fails (FmuError naming ``where`` and the member), the
    folder is removed.
    """
    zf = open_zip(path, where, FmuError, max_bytes)
    folder = tempfile.mkdtemp(prefix=TMP_PREFIX)
    try:
        with zf:
            written = 0
            for info in zf.infolist():
                target = os.path.join(folder, *PurePosixPath(info.filename).parts)
                try:
                    os.makedirs(target if info.is_dir() else os.path.dirname(target),
                                exist_ok=True)
                except OSError as exc:  # a member named as a folder another one is in
                    raise FmuError(f"{where}: cannot unpack member {info.filename!r}: "
                                   f"{_reason(exc)} (a file and a folder of one name)") from None
                if info.is_dir():
                    continue
                written += _copy_member(zf, info, target, where, written, max_bytes)
        return folder
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise


def _copy_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, target: str, where: str,
                 before: int, max_bytes: int) -> int:
    mode = 0o700 if (info.external_attr >> 16) & stat.S_IXUSR else 0o600
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    written = 0
    try:
        fd = os.open(target, flags, mode)
    except OSError as exc:
        raise FmuError(f"{where}: cannot unpack {info.filename!r}: {_reason(exc)}") from None
    try:
        with os.fdopen(fd, "wb") as out, zf.open(info) as src:
            while chunk := src.read(1 << 20):
                written += len(chunk)
                if before + written > max_bytes:
                    raise FmuError(f"{where}: unpacks to more than {size_text(max_bytes)} (at "
                                   f"{info.filename!r}); at most {size_text(max_bytes)}")
                out.write(chunk)
    except FmuError:
        raise
    except _READ_ERRORS as exc:
        raise FmuError(f"{where}: cannot unpack {info.filename!r}: {_reason(exc)}") from None
    return written


def read_model_description(source: str | Path, where: str) -> Any:
    """fmpy's model description of an unpacked FMU folder (FmuError naming ``where``)."""
    from fmpy import read_model_description as fmpy_read

    xml = Path(source) / "modelDescription.xml"
    if not xml.is_file():
        raise FmuError(f"{where}: cannot read modelDescription.xml: the archive has none")
    if xml.stat().st_size > MAX_XML_BYTES:
        raise FmuError(f"{where}: modelDescription.xml is {size_text(xml.stat().st_size)}; at "
                       f"most {size_text(MAX_XML_BYTES)} are read")
    try:
        md = fmpy_read(str(source))
    except MemoryError:
        raise FmuError(f"{where}: cannot read modelDescription.xml: out of memory") from None
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain Exceptions for broken files
        text = "; ".join(str(p) for p in getattr(exc, "problems", [])[:3]) or _reason(exc)
        raise FmuError(f"{where}: cannot read modelDescription.xml: {text}") from None
    if getattr(md, "fmiVersion", None) != "2.0":
        raise FmuError(f"{where}: fmiVersion = {getattr(md, 'fmiVersion', None)!r}; only FMI "
                       "2.0 FMUs are supported")
    if md.coSimulation is None:
        raise FmuError(f"{where}: not a Co-Simulation FMU")
    return md


def load_library(md: Any, unzip_dir: str, instance_name: str, where: str) -> Any:
    """fmpy's FMU2Slave of the unpacked FMU: its library for this platform, loaded.

    The working folder is kept (fmpy changes into the library's folder to load it).
    """
    from fmpy import platform, sharedLibraryExtension
    from fmpy.fmi2 import FMU2Slave

    identifier = md.coSimulation.modelIdentifier
    relative = f"binaries/{platform}/{identifier}{sharedLibraryExtension}"
    library = Path(unzip_dir, "binaries", platform, identifier + sharedLibraryExtension)
    if not library.is_file():
        binaries = Path(unzip_dir, "binaries")
        found = sorted(p.name for p in binaries.iterdir() if p.is_dir()) if (
            binaries.is_dir()) else []
        has = ("it has binaries for " + ", ".join(found) if found
               else "it has no binaries (a source-only FMU)")
        raise FmuError(f"{where}: no binary for this platform ({relative}); {has}")
    cwd = os.getcwd()
    try:
        return FMU2Slave(guid=md.guid, unzipDirectory=unzip_dir, modelIdentifier=identifier,
                         instanceName=instance_name)
    except AttributeError as exc:
        raise FmuError(f"{where}: {relative} is not an FMI 2.0 library: "
                       f"{_reason(exc).split(': ', 1)[-1]}") from None
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain Exceptions; ctypes OSError
        text = _reason(exc).replace(str(library), relative)
        text = text.removeprefix(f"Failed to load shared library {relative}. ")
        text = text.removeprefix(f"{relative}: ")
        raise FmuError(f"{where}: cannot load {relative}: {text}") from None
    finally:
        with contextlib.suppress(OSError):
            os.chdir(cwd)
