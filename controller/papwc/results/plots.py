"""Plots of runs (matplotlib, written as PNG without a display)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from papwc.master import RunResult  # noqa: E402
from papwc.output_files import save_figure  # noqa: E402


def _first_last(result: RunResult):
    traces = result.traces
    return [t for t in (traces[0], traces[-1])] if len(traces) > 1 else list(traces)


def time_panels(results: list[RunResult], column: str, ylabel: str, title: str,
                path: Path, scale: float = 1.0, hlines: dict[str, float] | None = None,
                step: bool = False) -> None:
    """One panel for the 1st and one for the last iteration; a line per controller."""
    if not results or not results[0].traces:
        return
    iterations = [t.iteration for t in _first_last(results[0])]
    fig, axes = plt.subplots(len(iterations), 1, figsize=(8, 3.2 * len(iterations)),
                             sharex=True, squeeze=False)
    for ax, it in zip(axes[:, 0], iterations, strict=True):
        for r in results:
            tr = next((t for t in r.traces if t.iteration == it), None)
            if tr is None:
                continue
            ts, ys = tr.column("t"), [y * scale for y in tr.column(column)]
            if step:
                ax.step(ts, ys, where="post", label=r.label, lw=1.2)
            else:
                ax.plot(ts, ys, label=r.label, lw=1.2)
        for name, value in (hlines or {}).items():
            ax.axhline(value * scale, color="k", ls=":", lw=1, label=name)
        ax.set_ylabel(ylabel)
        ax.set_title(f"{title}, iteration {it}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    axes[-1, 0].set_xlabel("time t (s)")
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)


def run_plots(results: list[RunResult], out: Path) -> None:
    """error.png, force.png and estimates.png for ``papwc run``."""
    time_panels(results, "e", "error e (mm)", "Position error", out / "error.png", 1e3)
    time_panels(results, "u", "force u (N)", "Force", out / "force.png", step=True)
    time_panels(results, "b_hat", "b_hat (m/s^2)", "Estimate b_hat", out / "estimates.png")
