"""What a closed-loop run records, its summary metrics, and writing them as CSV."""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from papwc.core.base import Mode

#: Columns of a trace, one row per sample t_k = k*T (SI units).
TRACE_COLUMNS = (
    "k", "t", "x", "v", "x_meas", "u", "e", "mode", "pulses", "b_hat", "f_c_hat",
)  # fmt: skip


@dataclass
class Trace:
    """Samples of one iteration: state at t_k and the force u_k held over [t_k, t_k+1].

    The last row holds the state at the end of the iteration; its force is NaN.
    """

    controller: str
    iteration: int
    T: float
    x_ref: float
    rows: list[tuple] = field(default_factory=list)
    error: str = ""

    def column(self, name: str) -> list:
        i = TRACE_COLUMNS.index(name)
        return [r[i] for r in self.rows]

    def write_csv(self, path: str | os.PathLike) -> None:
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(TRACE_COLUMNS)
            for r in self.rows:
                w.writerow([repr(v) if isinstance(v, float) else v for v in r])


def summarize(trace: Trace, tolerance: float, window: float = 0.25) -> dict[str, float]:
    """Metrics of one iteration.

    Parameters
    ----------
    trace : Trace
        The recorded iteration.
    tolerance : float
        The controller's error band, m.
    window : float
        Fraction of the iteration (its end) in which a limit cycle is looked for.

    Returns
    -------
    dict
        ``final_error_m`` (x_ref - x at the end, m), ``pulses``, ``settle_time_s``
        (start of the final stretch in mode "settled", NaN if the controller is
        still active at the end), ``limit_cycle`` (pulses in both directions
        within the final window), ``cycle_p2p_m`` (peak-to-peak of x in the
        final window, m), ``b_hat``, ``f_c_hat``.
    """
    rows = trace.rows
    if not rows:
        return {"final_error_m": math.nan, "pulses": 0, "settle_time_s": math.nan,
                "limit_cycle": False, "cycle_p2p_m": math.nan, "b_hat": math.nan,
                "f_c_hat": math.nan}
    i_mode = TRACE_COLUMNS.index("mode")
    last = rows[-1]
    settle = math.nan
    k = len(rows) - 1
    if rows[k][i_mode] == Mode.SETTLED:
        while k > 0 and rows[k - 1][i_mode] == Mode.SETTLED:
            k -= 1
        settle = rows[k][1]
    n_win = max(2, int(len(rows) * window))
    tail = rows[-n_win:]
    us = [r[5] for r in tail if not math.isnan(r[5])]
    xs = [r[2] for r in tail]
    limit_cycle = any(u > 0.0 for u in us) and any(u < 0.0 for u in us)
    return {
        "final_error_m": trace.x_ref - last[2],
        "pulses": int(last[8]),
        "settle_time_s": settle,
        "limit_cycle": bool(limit_cycle),
        "cycle_p2p_m": max(xs) - min(xs),
        "b_hat": last[9],
        "f_c_hat": last[10],
    }


def write_rows(path: str | os.PathLike, rows: list[dict], columns: list[str] | None = None) -> None:
    """Write dictionaries as a CSV file (floats in full precision), atomically."""
    path = Path(path)
    columns = columns or list(rows[0]) if rows else (columns or [])
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: repr(v) if isinstance(v, float) else v for k, v in r.items()})
    os.replace(tmp, path)
