"""What the paper's claims read from a run: its pulses, sign switches, adaptation speed,
final error and limit cycle (:class:`RunMetrics`), and the role a controller takes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from papwc.controllers import Mode
from papwc.controllers.settings import ControllerSettings
from papwc.master import RunResult, Trace
from papwc.results.summary import summarize

__all__ = ["FIRST_PULSES", "FIXED", "ROLES", "WINDOW", "RunMetrics", "adaptation_per_pulse",
           "pulse_list", "role_of", "run_metrics", "sign_switches"]

#: Pulses over which the adaptation speed is measured (from the start of iteration 1).
FIRST_PULSES = 5
#: Fraction of an iteration (its end) in which a limit cycle is looked for.
WINDOW = 0.25

#: The four controllers of the paper's Section 4.
ROLES = ("pwc_bounded", "pwc_unbounded", "papwc_bounded", "papwc_unbounded")
#: Suffix of the role of a PAPWC run without covariance update.
FIXED = "_fixed_covariance"


def pulse_list(trace: Trace) -> list[tuple[int, int, float]]:
    """The pulses of an iteration: (first sample, width in samples, height in N)."""
    u, mode = trace.column("u"), trace.column("mode")
    out: list[tuple[int, int, float]] = []
    i, n = 0, len(u)
    while i < n:
        f = u[i]
        if mode[i] == Mode.PULSE and f and not math.isnan(f):
            j = i
            while j < n and mode[j] == Mode.PULSE and u[j] == f:
                j += 1
            out.append((i, j - i, f))
            i = j
        else:
            i += 1
    return out


def sign_switches(trace: Trace) -> int:
    """How often the sign of the pulse height changes from one pulse to the next."""
    signs = [f > 0.0 for _, _, f in pulse_list(trace)]
    return sum(1 for a, b in zip(signs, signs[1:], strict=False) if a != b)


def adaptation_per_pulse(trace: Trace, n_pulses: int = FIRST_PULSES) -> float:
    """Mean ``|change of b_hat|`` per pulse over the first ``n_pulses`` pulses, m/s**2.

    The change of pulse k is b_hat when pulse k+1 starts (the estimate it was
    planned with) minus b_hat when pulse k started; after the last pulse, the
    value at the end of the iteration. NaN without pulses.
    """
    b_hat = trace.column("b_hat")
    starts = [k for k, _, _ in pulse_list(trace)]
    if not starts:
        return math.nan
    used = min(n_pulses, len(starts))
    values = [b_hat[starts[i]] if i < len(starts) else b_hat[-1] for i in range(used + 1)]
    return sum(abs(b - a) for a, b in zip(values, values[1:], strict=False)) / used


@dataclass(frozen=True)
class RunMetrics:
    """What the claims read from one controller's run (last iteration unless said).

    Attributes
    ----------
    label : str
        Controller label.
    error : str
        Why the run stopped early ("" if every iteration ran).
    iterations : int
        Iterations recorded.
    final_error_m : float
        x_ref - x at the end, m.
    signs : str
        The signs of the pulses, one character each (``+`` or ``-``).
    limit_cycle : bool
        Pulses of both signs in the last quarter of the iteration.
    cycle_p2p_m : float
        Peak-to-peak of x over that quarter, m.
    window_widths : tuple of int
        Widths (samples) of the pulses that start in that quarter, sorted, unique.
    switches : int
        Sign changes between consecutive pulses.
    b_hat : float
        Estimate at the end, m/s**2.
    adaptation : float
        Mean ``|change of b_hat|`` per pulse over the first pulses of iteration 1, m/s**2.
    """

    label: str
    error: str
    iterations: int
    final_error_m: float
    signs: str
    limit_cycle: bool
    cycle_p2p_m: float
    window_widths: tuple[int, ...]
    switches: int
    b_hat: float
    adaptation: float

    @property
    def pulses(self) -> int:
        """Pulses in the last iteration."""
        return len(self.signs)


def run_metrics(result: RunResult) -> RunMetrics:
    """The metrics of a run that the claims read."""
    if not result.traces:
        return RunMetrics(result.label, result.error or "no iteration recorded", 0, math.nan,
                          "", False, math.nan, (), 0, math.nan, math.nan)
    last = result.traces[-1]
    s = summarize(last, result.settings.tolerance, WINDOW)
    pulses = pulse_list(last)
    start = len(last) - max(2, int(len(last) * WINDOW))
    return RunMetrics(
        label=result.label,
        error=result.error,
        iterations=len(result.traces),
        final_error_m=s["final_error_m"],
        signs="".join("+" if f > 0.0 else "-" for _, _, f in pulses),
        limit_cycle=bool(s["limit_cycle"]),
        cycle_p2p_m=s["cycle_p2p_m"],
        window_widths=tuple(sorted({w for k, w, _ in pulses if k >= start})),
        switches=sign_switches(last),
        b_hat=s["b_hat"],
        adaptation=adaptation_per_pulse(result.traces[0]),
    )


def role_of(settings: ControllerSettings) -> str | None:
    """The role of a controller (``pwc_bounded``, ...), None for other kinds."""
    if settings.kind not in ("pwc", "papwc"):
        return None
    return f"{settings.kind}_{'bounded' if math.isfinite(settings.t_p_max) else 'unbounded'}"
