"""Writing results: every file is written whole or not at all.

A file is written into ``<name>.tmp`` beside its place and renamed over it when
complete (:func:`atomic_open`), so a reader, a crash or Ctrl-C never leaves a
half-written result. An operating-system error (a read-only or full disk, a
file or folder in the way) becomes :class:`~papwc.errors.OutputError` naming
the path and the operation; the files written before it stay.
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
    "atomic_open",
    "format_value",
    "make_folder",
    "os_error_text",
    "remove_file",
    "save_figure",
    "write_rows",
    "write_text",
]


def os_error_text(exc: OSError) -> str:
    """The reason of an operating-system error in words (``"Read-only file system"``)."""
    return exc.strerror or str(exc) or type(exc).__name__


def make_folder(path: str | os.PathLike) -> Path:
    """Create folder ``path`` (and its parents) if missing; OutputError if that fails."""
    path = Path(path)
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


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, newline: str | None = None) -> Iterator[IO[str]]:
    """Open ``path`` for writing text (UTF-8); it appears only once the block ends normally.

    Raises
    ------
    OutputError
        If the file cannot be written or put in place (the path and the reason).
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    step = "write"
    try:
        with open(tmp, "w", encoding="utf-8", newline=newline) as f:
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
    try:
        fig.savefig(tmp, **kwargs)
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
