"""``papwc cosim``: run an SSP with the project's master and write a CSV and a plot.

The logic is :mod:`papwc.master.ssp`; here the results are written:
``<out>/<stem>.csv`` (``time`` and the recorded variables, floats in full
precision) and ``<out>/<stem>.png`` (one panel per variable against time).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from papwc.errors import PapwcError
from papwc.master.ssp import SspRun, read_ssp, run_ssp
from papwc.output import atomic_open, format_value

__all__ = ["MAX_PANELS", "cosim", "plot_run", "write_csv"]

#: Most variables drawn in the plot (the CSV holds them all).
MAX_PANELS = 12


def write_csv(run: SspRun, path: Path) -> None:
    """The recorded rows as CSV, atomically (``time`` first; floats with ``repr``)."""
    import csv

    with atomic_open(path, newline="") as f:
        writer = csv.writer(f)
        writer.writerow(run.columns)
        for row in run.rows:
            writer.writerow([format_value(v) for v in row])


def plot_run(run: SspRun, path: Path) -> None:
    """One panel per recorded variable (at most :data:`MAX_PANELS`) against time, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = run.columns[1:MAX_PANELS + 1]
    n = max(len(names), 1)
    fig, axes = plt.subplots(n, 1, figsize=(8, 1.6 + 1.4 * n), sharex=True, squeeze=False)
    t = [row[0] for row in run.rows]
    for i, name in enumerate(names):
        ax = axes[i][0]
        ax.plot(t, [float(row[i + 1]) for row in run.rows], drawstyle="steps-post", lw=1.2)
        ax.set_ylabel(name, rotation=0, ha="right", fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[-1][0].set_xlabel("t (s)")
    more = len(run.columns) - 1 - len(names)
    title = f"{run.system.path.name}: {len(run.rows) - 1} steps of {run.step_size!r} s"
    if more > 0:
        title += f" ({more} more variables in the CSV)"
    if run.error:
        title += " - stopped early"
    axes[0][0].set_title(title, fontsize=9)
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    os.replace(tmp, path)


def cosim(
    ssp: str | os.PathLike,
    out: str | os.PathLike,
    variables: Sequence[str] | None = None,
    step: float | None = None,
    stop: float | None = None,
) -> tuple[SspRun, Path, Path]:
    """Check and run ``ssp``, write ``<out>/<stem>.csv`` and ``.png``; return the run and paths.

    Nothing is written before the SSP has been read, checked and initialized;
    a run that stops at a failed step writes the rows before it.

    Raises
    ------
    PapwcError
        :class:`~papwc.errors.SspError` for an SSP or option that does not fit,
        :class:`~papwc.errors.FmuError` for an FMU that cannot be loaded or
        refuses its parameters.
    """
    system = read_ssp(ssp)
    run = run_ssp(system, variables, step=step, stop=stop)
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PapwcError(f"cannot create the output folder {out}: {exc}") from exc
    stem = Path(ssp).stem
    csv_path, png_path = out / f"{stem}.csv", out / f"{stem}.png"
    write_csv(run, csv_path)
    plot_run(run, png_path)
    return run, csv_path, png_path
