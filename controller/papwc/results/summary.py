"""What an iteration achieved, read off its trace: the metrics of ``summary.csv``."""

from __future__ import annotations

import math
from typing import Any

from papwc.controllers import Mode
from papwc.master.trace import Trace
from papwc.model.controller_settings import OUTCOME_REASONS, OUTCOMES

#: The end of an iteration in which a settled controller must hold the table, s (issue 46:
#: no hunting after it settles, the last 0.5 s of the trace).
HUNT_WINDOW_S = 0.5


def settled_span(trace: Trace, window_s: float = HUNT_WINDOW_S) -> float:
    """How far the table moved after the controller called it settled, at the end of an
    iteration: the span (max - min, m) of the true position x over the last ``window_s``
    seconds, from the first sample there at which the outcome is ``settled`` on; NaN if the
    outcome is ``settled`` at no sample of that stretch (the controller still worked or
    gave up)."""
    cols = trace.columns
    n = len(trace)
    k0 = max(0, n - max(1, int(round(window_s / trace.T))))
    settled = OUTCOMES.index("settled")
    outcome = cols["outcome"]
    for k in range(k0, n):
        if outcome[k] == settled:
            xs = cols["x"][k:]
            return max(xs) - min(xs)
    return math.nan


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
        the controller ended settled, else ``"stopped"``), ``outcome_reason``
        (the controller's reason, ``"time_ended"`` if it was still active at the
        end) and ``settled_span_m`` (:func:`settled_span`).
    """
    n = len(trace)
    if not n:
        return {"final_error_m": math.nan, "pulses": 0, "settle_time_s": math.nan,
                "limit_cycle": False, "cycle_p2p_m": math.nan, "b_hat": math.nan,
                "f_c_hat": math.nan, "outcome": "stopped", "outcome_reason": "time_ended",
                "settled_span_m": math.nan}
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
        "settled_span_m": settled_span(trace),
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
