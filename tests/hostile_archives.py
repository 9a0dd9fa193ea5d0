"""Hostile FMU and SSP archives made from good ones (for the tests of the one door through
which papwc opens every archive, :mod:`papwc.master.archive`)."""

from __future__ import annotations

import re
import stat
import struct
import zipfile
from collections.abc import Callable
from pathlib import Path

__all__ = ["KINDS", "damage", "rezip"]


def rezip(src: Path, target: Path, keep: Callable[[str], bool] = lambda name: True,
          replace: dict[str, bytes] | None = None, extra: dict[str, bytes] | None = None,
          method: int = zipfile.ZIP_DEFLATED) -> Path:
    """A copy of the archive ``src`` without the members ``keep`` refuses, some replaced."""
    replace = replace or {}
    with zipfile.ZipFile(src) as a, zipfile.ZipFile(target, "w", method) as b:
        for info in a.infolist():
            if not keep(info.filename):
                continue
            b.writestr(info.filename, replace.get(info.filename, a.read(info.filename)))
        for name, data in (extra or {}).items():
            b.writestr(name, data)
    return target


def _patch_headers(path: Path, member: str, flag_or: int = 0, method: int | None = None
                   ) -> Path:
    """Set bits of the general-purpose flag, or the method, of ``member`` in both headers."""
    data = bytearray(path.read_bytes())
    name = member.encode()
    for signature, flag_at, method_at, name_len_at, name_at in (
            (b"PK\x03\x04", 6, 8, 26, 30), (b"PK\x01\x02", 8, 10, 28, 46)):
        start = 0
        while (i := data.find(signature, start)) >= 0:
            start = i + 4
            n = struct.unpack_from("<H", data, i + name_len_at)[0]
            if bytes(data[i + name_at:i + name_at + n]) != name:
                continue
            flags = struct.unpack_from("<H", data, i + flag_at)[0] | flag_or
            struct.pack_into("<H", data, i + flag_at, flags)
            if method is not None:
                struct.pack_into("<H", data, i + method_at, method)
    path.write_bytes(bytes(data))
    return path


def _corrupt(path: Path, member: str) -> Path:
    """Overwrite the middle of ``member``'s compressed data with garbage."""
    with zipfile.ZipFile(path) as z:
        info = z.getinfo(member)
    data = bytearray(path.read_bytes())
    n = struct.unpack_from("<HH", data, info.header_offset + 26)
    start = info.header_offset + 30 + n[0] + n[1]
    middle = start + info.compress_size // 2
    data[middle:middle + 64] = bytes(range(64))
    path.write_bytes(bytes(data))
    return path


def _first(src: Path, target: Path, first: list[tuple[zipfile.ZipInfo | str, bytes]],
           keep: Callable[[str], bool] = lambda name: True) -> Path:
    """A copy of ``src`` with the members ``first`` written before its own."""
    with zipfile.ZipFile(src) as a, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as b:
        for info, data in first:
            b.writestr(info, data)
        for info in a.infolist():
            if keep(info.filename):
                b.writestr(info.filename, a.read(info.filename))
    return target


def _symlink(name: str) -> zipfile.ZipInfo:
    """A member that is a symbolic link (as ``zip --symlinks`` stores one on Unix)."""
    info = zipfile.ZipInfo(name)
    info.create_system = 3
    info.external_attr = (stat.S_IFLNK | 0o777) << 16
    return info


def _library(fmu: Path) -> str:
    with zipfile.ZipFile(fmu) as z:
        return next(n for n in z.namelist() if n.startswith("binaries/linux64/"))


#: kind -> what its line says (a phrase the one line must hold)
KINDS = {
    "windows_only": "no binary for this platform",
    "broken_so": "cannot load binaries/linux64/",
    "foreign_so": "is not an FMI 2.0 library: undefined symbol",
    "corrupt_member": "cannot unpack",
    "encrypted_member": "is encrypted",
    "unusual_compression": "is compressed with method 9",
    "too_many_members": "archive members; at most 10000",
    "too_large": "unpacks to",
    "not_a_zip": "not a zip archive",
    "no_model_description": "modelDescription.xml",
    "path_outside": "leaves the folder",
    # issue 44
    "symlink_member": "is a symbolic link; an archive is read as regular files and folders",
    "symlink_folder": "member 'documentation' is a symbolic link",
    "file_and_folder": "(a file and a folder of one name)",
    "guid_mismatch": "fmi2Instantiate refused: GUID {00000000-0000-0000-0000-000000000000} is "
                     "not this FMU's",
}


def damage(fmu: Path, kind: str, target: Path) -> Path:
    """A copy of ``fmu`` damaged as ``kind`` (a key of :data:`KINDS`) at ``target``."""
    library = _library(fmu)
    if kind == "windows_only":
        return rezip(fmu, target, lambda n: not n.startswith("binaries/linux64/"))
    if kind == "broken_so":
        return rezip(fmu, target, replace={library: b"\x7fELF not really" * 64})
    if kind == "foreign_so":
        import ctypes.util

        libm = Path("/lib/x86_64-linux-gnu/libm.so.6")
        if not libm.exists():
            libm = Path(ctypes.util.find_library("m") or "libm.so.6")
        return rezip(fmu, target, replace={library: libm.read_bytes()})
    if kind == "corrupt_member":
        return _corrupt(rezip(fmu, target), library)
    if kind == "encrypted_member":
        return _patch_headers(rezip(fmu, target), library, flag_or=1)
    if kind == "unusual_compression":
        return _patch_headers(rezip(fmu, target), library, method=9)
    if kind == "too_many_members":
        return rezip(fmu, target, extra={f"resources/f{i}": b"" for i in range(10_001)},
                     method=zipfile.ZIP_STORED)
    if kind == "too_large":
        # 600 MiB of zeros in a member stored as deflate (about 600 kB in the archive)
        import zlib

        rezip(fmu, target)
        with zipfile.ZipFile(target, "a") as z:
            info = zipfile.ZipInfo("resources/zeros.bin")
            info.compress_type = zipfile.ZIP_DEFLATED
            with z.open(info, "w", force_zip64=True) as f:
                block = bytes(1 << 20)
                for _ in range(600):
                    f.write(block)
        del zlib
        return target
    if kind == "not_a_zip":
        target.write_bytes(b"this is not an FMU\n")
        return target
    if kind == "no_model_description":
        return rezip(fmu, target, lambda n: n != "modelDescription.xml")
    if kind == "path_outside":
        return rezip(fmu, target, extra={"../../escaped.txt": b"out"})
    if kind == "symlink_member":  # the library a link to a file of the host
        return _first(fmu, target, [(_symlink(library), b"/etc/passwd")],
                      keep=lambda n: n != library)
    if kind == "symlink_folder":  # a folder a link elsewhere, members unpacked through it
        return _first(fmu, target, [(_symlink("documentation"), b"/tmp")])
    if kind == "file_and_folder":  # a file named as the folder of other members
        return _first(fmu, target, [("documentation", b"a file")])
    if kind == "guid_mismatch":  # the model description's GUID is not the binary's
        with zipfile.ZipFile(fmu) as z:
            xml = z.read("modelDescription.xml")
        xml = re.sub(rb'guid="[^"]*"', b'guid="{00000000-0000-0000-0000-000000000000}"', xml,
                     count=1)
        return rezip(fmu, target, replace={"modelDescription.xml": xml})
    raise ValueError(kind)
