"""Writing results: every file is written whole or not at all, never through a planted link.

A file is written into ``<name>.tmp`` beside its place and renamed over it when
complete (:func:`atomic_open`), so a reader, a crash or Ctrl-C never leaves a
half-written result. The temporary file is created anew (``O_EXCL |
O_NOFOLLOW``, :func:`create_new`): a symbolic link planted in its place is
refused, never written through; a regular file left there by a killed run is
replaced. A folder a command fills inside its output folder is created by it
and not followed if it is a link (:func:`make_folder` with ``own=True``), and
a command that fills an output folder holds its lock (:func:`lock_folder`), so
that two commands never write into one folder at once. An operating-system
error (a read-only or full disk, a file or folder in the way) becomes
:class:`~papwc.errors.OutputError` naming the path and the operation; the files
written before it stay.
"""

from __future__ import annotations

import contextlib
import csv
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

from papwc.errors import OutputError

__all__ = [
    "LOCK_NAME",
    "FolderLock",
    "atomic_open",
    "create_new",
    "lock_folder",
    "format_value",
    "make_folder",
    "os_error_text",
    "refuse_link",
    "remove_file",
    "save_figure",
    "write_rows",
    "write_text",
]


def os_error_text(exc: OSError) -> str:
    """The reason of an operating-system error in words (``"Read-only file system"``)."""
    return exc.strerror or str(exc) or type(exc).__name__


def make_folder(path: str | os.PathLike, own: bool = False) -> Path:
    """Create folder ``path`` (and its parents) if missing; OutputError if that fails.

    ``own``: a folder the command fills inside its output folder (``runs/``):
    if ``path`` is a symbolic link it is refused, not followed.
    """
    path = Path(path)
    if own and path.is_symlink():
        raise OutputError(f"cannot use folder {str(path)!r}: it is a symbolic link (to "
                          f"{os.readlink(path)!r}); papwc writes only into a folder it "
                          "created: remove the link")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(f"cannot create folder {str(path)!r}: a file is in the way") from None
    except OSError as exc:
        raise OutputError(f"cannot create folder {str(path)!r}: {os_error_text(exc)}") from exc
    return path


def remove_file(path: str | os.PathLike) -> None:
    """Remove file ``path`` if it exists; OutputError if it cannot be removed."""
    try:
        Path(path).unlink(missing_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot remove {str(path)!r}: {os_error_text(exc)}") from exc


#: The lock file of an output folder (held by the command writing into it).
LOCK_NAME = ".papwc.lock"
_NEW = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(
    os, "O_CLOEXEC", 0)


def refuse_link(path: str | os.PathLike) -> None:
    """OutputError if ``path`` is a symbolic link (where papwc would write or remove a file)."""
    path = Path(path)
    if path.is_symlink():
        raise OutputError(f"cannot write {str(path)!r}: a symbolic link is in its place (to "
                          f"{os.readlink(path)!r}); papwc does not write through links: "
                          "remove it")


def create_new(path: str | os.PathLike, mode: int = 0o644) -> int:
    """A new file ``path`` opened for writing (a file descriptor); never through a link.

    A symbolic link (or anything but a regular file) at ``path`` is refused; a
    regular file there (a killed run's temporary file) is removed first.

    Raises
    ------
    OutputError
        Naming the path and what is in the way.
    """
    path = Path(path)
    for _ in range(2):
        try:
            return os.open(path, _NEW, mode)
        except FileExistsError:
            pass
        except OSError as exc:
            raise OutputError(f"cannot write {str(path)!r}: {os_error_text(exc)}") from exc
        refuse_link(path)
        if path.is_dir() or not path.is_file():
            raise OutputError(f"cannot write {str(path)!r}: a folder or special file is in "
                              "its place")
        remove_file(path)
    raise OutputError(f"cannot write {str(path)!r}: another process keeps creating it")


class FolderLock:
    """The lock of an output folder (:func:`lock_folder`); :meth:`close` releases it."""

    def __init__(self, path: Path, file: IO[str]) -> None:
        self.path = path
        self._file = file

    def close(self) -> None:
        """Remove the lock file and release the lock (idempotent)."""
        if not self._file.closed:
            with contextlib.suppress(OSError):
                self.path.unlink()
            self._file.close()

    def __enter__(self) -> FolderLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def lock_folder(folder: str | os.PathLike, what: str) -> FolderLock:
    """Lock output folder ``folder`` for the command ``what``; return the held lock.

    The lock is ``flock`` on ``folder/.papwc.lock`` (created, or opened without
    following a link), which names its holder; it is released, and the file
    removed, by :meth:`FolderLock.close` or when the process ends (the file then
    stays, unlocked). A lock file removed by its holder while this process
    waited for it is opened anew.

    Raises
    ------
    OutputError
        If another command holds the lock (named), or the file cannot be opened.
    """
    import fcntl

    path = Path(folder) / LOCK_NAME
    for _ in range(100):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0)
                         | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as exc:
            why = ("a symbolic link is in its place" if path.is_symlink()
                   else os_error_text(exc))
            raise OutputError(f"cannot lock folder {str(folder)!r} ({LOCK_NAME}): "
                              f"{why}") from exc
        lock = os.fdopen(fd, "r+", encoding="utf-8")
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = lock.read(200).strip() or "another papwc command"
            lock.close()
            raise OutputError(f"{folder}: {holder} is writing into this folder; wait for it "
                              "to finish or use another --out") from None
        except OSError as exc:
            lock.close()
            raise OutputError(f"cannot lock folder {str(folder)!r}: "
                              f"{os_error_text(exc)}") from exc
        try:
            same = os.stat(path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
        except OSError:
            same = False
        if not same:  # its holder removed it meanwhile: lock the file now in its place
            lock.close()
            continue
        lock.seek(0)
        lock.truncate()
        lock.write(f"{what} (process {os.getpid()})\n")
        lock.flush()
        return FolderLock(path, lock)
    raise OutputError(f"cannot lock folder {str(folder)!r}: its lock file keeps changing")


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, newline: str | None = None) -> Iterator[IO[str]]:
    """Open ``path`` for writing text (UTF-8); it appears only once the block ends normally.

    Raises
    ------
    OutputError
        If the file cannot be written or put in place (the path and the reason),
        or a link is planted where its temporary file goes.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    step = "write"
    fd = create_new(tmp) if not path.is_dir() else None
    if fd is None:
        raise OutputError(f"cannot write {str(path)!r}: a folder is in the way")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline=newline) as f:
            yield f
        step = "replace"
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise _output_error(path, exc, step) from exc
        raise


def _output_error(path: Path, exc: OSError, step: str) -> OutputError:
    if step == "replace" and path.is_dir():
        return OutputError(f"cannot write {str(path)!r}: a folder is in the way")
    if step == "write" and exc.filename is not None and Path(exc.filename).parent != path.parent:
        return OutputError(f"cannot write {str(path)!r}: {os_error_text(exc)} "
                           f"({exc.filename})")
    return OutputError(f"cannot write {str(path)!r}: {os_error_text(exc)}")


def save_figure(fig: Any, path: str | os.PathLike, **kwargs: Any) -> None:
    """Save a matplotlib figure as PNG, atomically (OutputError if it cannot be written)."""
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp.png")
    step = "write"
    fd = create_new(tmp)
    try:
        with os.fdopen(fd, "wb") as f:
            fig.savefig(f, format="png", **kwargs)
        step = "replace"
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise _output_error(path, exc, step) from exc


def format_value(value: Any) -> Any:
    """A value as written in CSV files: floats in full precision (``repr``)."""
    return repr(value) if isinstance(value, float) else value


def write_rows(path: str | os.PathLike, rows: Sequence[dict],
               columns: Sequence[str] | None = None) -> None:
    """Write dictionaries as a CSV file (floats in full precision), atomically.

    ``columns`` default to the keys of the first row; keys not in ``columns``
    are left out.
    """
    if columns is None:
        columns = list(rows[0]) if rows else []
    with atomic_open(path, newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(columns), extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: format_value(v) for k, v in r.items()})


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path``, atomically."""
    with atomic_open(path) as f:
        f.write(text)
