"""``papwc cosim``: run an SSP with the project's master and write a CSV and a plot.

The logic is :mod:`papwc.master.ssp_runner`; here the results are written, as they
come: ``<out>/<stem>.csv`` (``time`` and the recorded variables, floats in full
precision) is streamed row by row into its temporary file, so that the memory a
run takes does not grow with its length, and ``<out>/<stem>.png`` (one panel
per variable against time) is drawn at the end from at most
:data:`PLOT_POINTS` rows kept on the way (every row while there are few, then
every second, fourth, ... row). While the run is under way, and after Ctrl-C,
SIGTERM or an error, the folder holds ``INCOMPLETE``; the CSV then holds every
row recorded before the stop. The folder is locked while the command writes
into it.
"""

from __future__ import annotations

import contextlib
import csv
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from papwc.master.ssp_runner import SspSession, read_ssp
from papwc.output_files import (
    create_new,
    format_value,
    lock_folder,
    make_folder,
    remove_file,
    save_figure,
    write_text,
)

__all__ = ["MAX_PANELS", "PLOT_POINTS", "CosimResult", "cosim", "plot_rows"]

#: Most variables drawn in the plot (the CSV holds them all).
MAX_PANELS = 12
#: Most rows kept for the plot (the CSV holds them all).
PLOT_POINTS = 20_000
#: Name of the file that marks an output folder whose results are not all written.
INCOMPLETE = "INCOMPLETE"
#: Rows written between two flushes of the CSV to the operating system.
_FLUSH_EVERY = 4096


@dataclass
class CosimResult:
    """What ``papwc cosim`` wrote: the paths, the columns, the steps done, the error."""

    csv_path: Path
    png_path: Path
    columns: list[str]
    steps: int
    step_size: float
    error: str = ""


class _PlotRows:
    """At most ``limit`` rows of a stream, evenly spaced (every ``stride``-th), and the last."""

    def __init__(self, limit: int = PLOT_POINTS) -> None:
        self.limit = max(2, limit)
        self.rows: list[list[Any]] = []
        self.stride = 1
        self.count = 0
        self.last: list[Any] | None = None

    def add(self, row: list[Any]) -> None:
        if self.count % self.stride == 0:
            self.rows.append(row)
            if len(self.rows) > self.limit:
                self.rows = self.rows[::2]
                self.stride *= 2
        self.count += 1
        self.last = row

    def all(self) -> list[list[Any]]:
        if self.last is not None and (not self.rows or self.rows[-1] is not self.last):
            return [*self.rows, self.last]
        return list(self.rows)


def plot_rows(rows: list[list[Any]], columns: list[str], title: str, path: Path) -> None:
    """One panel per recorded variable (at most :data:`MAX_PANELS`) against time, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = columns[1:MAX_PANELS + 1]
    n = max(len(names), 1)
    fig, axes = plt.subplots(n, 1, figsize=(8, 1.6 + 1.4 * n), sharex=True, squeeze=False)
    t = [row[0] for row in rows]
    for i, name in enumerate(names):
        ax = axes[i][0]
        ax.plot(t, [float(row[i + 1]) for row in rows], drawstyle="steps-post", lw=1.2)
        ax.set_ylabel(name, rotation=0, ha="right", fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[-1][0].set_xlabel("t (s)")
    more = len(columns) - 1 - len(names)
    if more > 0:
        title += f" ({more} more variables in the CSV)"
    axes[0][0].set_title(title, fontsize=9)
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=100)
    finally:
        plt.close(fig)


class _CsvStream:
    """``<out>/<stem>.csv`` written row by row into ``<stem>.csv.tmp`` (created anew)."""

    def __init__(self, path: Path, columns: list[str]) -> None:
        self.path = path
        self.tmp = path.with_name(path.name + ".tmp")
        self.rows = 0
        self.file: IO[str] = os.fdopen(create_new(self.tmp), "w", encoding="utf-8",
                                       newline="")
        self.writer = csv.writer(self.file)
        self.writer.writerow(columns)

    def write(self, row: list[Any]) -> None:
        self.writer.writerow([format_value(v) for v in row])
        self.rows += 1
        if self.rows % _FLUSH_EVERY == 0:
            self.file.flush()

    def close(self) -> None:
        """Flush, close, put the file in its place."""
        if not self.file.closed:
            self.file.close()
            os.replace(self.tmp, self.path)


def cosim(
    ssp: str | os.PathLike,
    out: str | os.PathLike,
    variables: Sequence[str] | None = None,
    step: float | None = None,
    stop: float | None = None,
) -> CosimResult:
    """Check and run ``ssp``, stream ``<out>/<stem>.csv``, draw ``<stem>.png``.

    Nothing is written before the SSP has been read, checked and initialized;
    a run that stops at a failed step keeps the rows before it (exit 1 from the
    command); Ctrl-C or SIGTERM stop it between two steps, the rows recorded
    before it kept in the CSV and ``INCOMPLETE`` saying so (the exception
    propagates).

    Raises
    ------
    PapwcError
        :class:`~papwc.errors.SspError` for an SSP or option that does not fit,
        :class:`~papwc.errors.FmuError` for an FMU that cannot be loaded or
        refuses its parameters, :class:`~papwc.errors.OutputError` if the folder
        cannot be written or another command writes into it.
    """
    from papwc.interrupts import Terminated, deferred_interrupt, interrupt_requested, interruption

    system = read_ssp(ssp)
    session = SspSession(system, variables, step=step, stop=stop)
    out = Path(out)
    stem = Path(ssp).stem
    csv_path, png_path = out / f"{stem}.csv", out / f"{stem}.png"
    with deferred_interrupt(), session:
        session.initialize()
        if interrupt_requested():
            raise interruption()
        make_folder(out)
        lock = lock_folder(out, "papwc cosim")
        try:
            for name in (png_path.name, INCOMPLETE):
                remove_file(out / name)
            _mark(out, f"papwc cosim started at {time.strftime('%Y-%m-%d %H:%M:%S')} and has "
                       f"not finished (or was stopped): {csv_path.name} and {png_path.name} "
                       "are missing")
            stream = _CsvStream(csv_path, session.columns)
            plot = _PlotRows()

            def record(row: list[Any]) -> None:
                stream.write(row)
                plot.add(row)
                if interrupt_requested():
                    raise interruption()

            try:
                for row in session.pending:
                    record(row)
                session.pending.clear()
                session.sink = record
                error = session.run()
            except BaseException as exc:
                with contextlib.suppress(OSError):
                    stream.close()
                why = ("terminated (SIGTERM)" if isinstance(exc, Terminated)
                       else "interrupted (Ctrl-C)" if isinstance(exc, KeyboardInterrupt)
                       else f"stopped by an error: {exc}")
                last = plot.last[0] if plot.last is not None else None
                with contextlib.suppress(OSError):
                    _mark(out, f"papwc cosim was {why} at t = {last!r} s: {csv_path.name} holds "
                               f"every row recorded before ({stream.rows} rows, "
                               f"{stream.rows - 1} of {session.steps} steps); {png_path.name} "
                               "was not drawn")
                import sys

                print(f"papwc cosim: kept {stream.rows - 1} of {session.steps} steps in "
                      f"{csv_path}; see {out / INCOMPLETE}", file=sys.stderr)
                raise
            stream.close()
            title = f"{system.path.name}: {stream.rows - 1} steps of {session.step_size!r} s"
            if plot.stride > 1:
                title += f", every {plot.stride}th drawn"
            if error:
                title += " - stopped early"
            plot_rows(plot.all(), session.columns, title, png_path)
            remove_file(out / INCOMPLETE)
        finally:
            lock.close()
    return CosimResult(csv_path, png_path, session.columns, stream.rows - 1,
                       session.step_size, error)


def _mark(out: Path, text: str) -> None:
    write_text(out / INCOMPLETE, f"This folder is incomplete: {text}.\n")
