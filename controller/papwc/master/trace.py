"""What one iteration of a closed loop recorded (:class:`Trace`) and its metrics.

A trace holds named columns, one value per sample t_k = k*T (SI units):

======== ======================================================================
``k``    sample number
``t``    time t_k, s
``x``    position at t_k, m
``v``    velocity at t_k, m/s
``x_meas`` position the controller saw at t_k (encoder, noise), m
``x_d``  motor (drive) position at t_k, m (``x`` on a rigid drive; NaN: the plant has none)
``x_d_meas`` the motor encoder's reading at t_k, m (NaN: the plant has none)
``u``    force applied over [t_k, t_k+1], N (NaN in the last row)
``e``    error x_ref - x, m
(then)   the controller's outputs after its sample at t_k, the model layer's
         ``CONTROLLER_OUTPUTS`` but ``u`` (:data:`papwc.controllers.OUTPUT_NAMES`):
         ``b_hat``, ``f_c_hat`` (m/s**2, N), ``pulses`` started so far, ``mode``
         (papwc.controllers.Mode), ``f_low`` (N), ``outcome``, ``outcome_reason``
         (:data:`papwc.model.settings.OUTCOMES`, ``OUTCOME_REASONS``)
======== ======================================================================

The last row is the state at the end of the iteration.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from typing import Any

from papwc.controllers import OUTPUT_NAMES, Mode
from papwc.model.settings import OUTCOME_REASONS, OUTCOMES
from papwc.output import atomic_open, format_value

__all__ = ["TRACE_COLUMNS", "Trace", "summarize"]

#: Columns of a trace, in the order of its CSV file.
TRACE_COLUMNS = ("k", "t", "x", "v", "x_meas", "x_d", "x_d_meas", "u", "e") + OUTPUT_NAMES


@dataclass
class Trace:
    """Samples of one iteration, by column name.

    Attributes
    ----------
    controller : str
        Label of the controller.
    iteration : int
        Iteration number (from 1).
    T : float
        Sample period, s.
    x_ref : float
        Reference position, m.
    columns : dict of str to list
        The samples, one list per name of :data:`TRACE_COLUMNS`.
    error : str
        Why the iteration stopped early ("" if it ran to the end).
    """

    controller: str
    iteration: int
    T: float
    x_ref: float
    columns: dict[str, list[Any]] = field(
        default_factory=lambda: {name: [] for name in TRACE_COLUMNS}
    )
    error: str = ""

    def __len__(self) -> int:
        return len(self.columns["k"])

    def column(self, name: str) -> list[Any]:
        """The samples of column ``name`` as a list."""
        return self.columns[name]

    def __getitem__(self, name: str):
        """The samples of column ``name`` as a numpy array."""
        import numpy as np

        return np.asarray(self.columns[name])

    def row(self, i: int) -> dict[str, Any]:
        """Sample ``i`` (negative counts from the end) as a dict by column name."""
        return {name: values[i] for name, values in self.columns.items()}

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write the trace as CSV (floats in full precision), columns as :data:`TRACE_COLUMNS`."""
        cols = [self.columns[name] for name in TRACE_COLUMNS]
        with atomic_open(path, newline="") as f:
            w = csv.writer(f)
            w.writerow(TRACE_COLUMNS)
            for row in zip(*cols, strict=True):
                w.writerow([format_value(v) for v in row])


def summarize(trace: Trace, tolerance: float, window: float = 0.25) -> dict[str, Any]:
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
        final window, m), ``b_hat``, ``f_c_hat``, ``outcome`` (``"settled"`` if
        the controller ended settled, else ``"stopped"``) and ``outcome_reason``
        (the controller's reason, ``"time_ended"`` if it was still active at the
        end).
    """
    n = len(trace)
    if not n:
        return {"final_error_m": math.nan, "pulses": 0, "settle_time_s": math.nan,
                "limit_cycle": False, "cycle_p2p_m": math.nan, "b_hat": math.nan,
                "f_c_hat": math.nan, "outcome": "stopped", "outcome_reason": "time_ended"}
    cols = trace.columns
    mode, t, x, u = cols["mode"], cols["t"], cols["x"], cols["u"]
    settle = math.nan
    k = n - 1
    if mode[k] == Mode.SETTLED:
        while k > 0 and mode[k - 1] == Mode.SETTLED:
            k -= 1
        settle = t[k]
    n_win = max(2, int(n * window))
    us = [f for f in u[-n_win:] if not math.isnan(f)]
    xs = x[-n_win:]
    limit_cycle = any(f > 0.0 for f in us) and any(f < 0.0 for f in us)
    return {
        "final_error_m": trace.x_ref - x[-1],
        "pulses": int(cols["pulses"][-1]),
        "settle_time_s": settle,
        "limit_cycle": bool(limit_cycle),
        "cycle_p2p_m": max(xs) - min(xs),
        "b_hat": cols["b_hat"][-1],
        "f_c_hat": cols["f_c_hat"][-1],
        **outcome_of(cols["outcome"][-1], cols["outcome_reason"][-1]),
    }


def outcome_of(outcome: int, reason: int) -> dict[str, str]:
    """``outcome`` and ``outcome_reason`` words of a maneuver from the controller's codes.

    A controller still active (coarse, pulse, wait) when the maneuver ended has
    stopped for the reason ``time_ended``; unknown codes read as that too.
    """
    try:
        word = OUTCOMES[int(outcome)]
        why = OUTCOME_REASONS[int(reason)]
    except (ValueError, IndexError, TypeError, OverflowError):
        word, why = "active", ""
    if word == "settled":
        return {"outcome": "settled", "outcome_reason": why or "within_tolerance"}
    if word == "stopped" and why:
        return {"outcome": "stopped", "outcome_reason": why}
    return {"outcome": "stopped", "outcome_reason": "time_ended"}
