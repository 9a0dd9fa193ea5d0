"""Writing results: every file is written whole or not at all.

A file is written into ``<name>.tmp`` beside its place and renamed over it when
complete (:func:`atomic_open`), so a reader, a crash or Ctrl-C never leaves a
half-written result.
"""

from __future__ import annotations

import contextlib
import csv
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

__all__ = ["atomic_open", "format_value", "write_rows", "write_text"]


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, newline: str | None = None) -> Iterator[IO[str]]:
    """Open ``path`` for writing text (UTF-8); it appears only once the block ends normally."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "w", encoding="utf-8", newline=newline) as f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


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
