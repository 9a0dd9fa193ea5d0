"""The moves of one-sample pulses from a relaxed drive, against their push.

A drive whose motor loop has relaxed it before a pulse makes a one-sample pulse's move a
function of its push (the law's height: the spring's first peak on the stuck table) and of
where the table breaks away: nothing below the breakaway, then growing with the push --
on a table without a Stribeck curve from a jump (the spring's stored energy slides the
table on at once), on one with it from zero. :class:`MoveCurve` keeps the recent pushes
that moved the table with their moves and plans on their upper envelope (the moves made
non-decreasing in the push, piecewise linear between them): the push that moves a goal
and the move a push makes. A table whose breakaway is drawn anew at every stick scatters
the moves about it; the dual-loop controller holds its plans to the bound by the largest
recent ratio of move to plan (:meth:`~.dual_loop.DualLoopController.move_ratio`).

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["KEEP_POINTS", "MoveCurve"]

#: Pushes and moves kept, newest last.
KEEP_POINTS = 12


class MoveCurve:
    """Recent one-sample pushes (N) and their moves (m), and plans on their envelope.

    Attributes
    ----------
    points : list of (float, float)
        Push (N, > 0) and move (m, > 0) of the recent one-sample pulses that moved the
        table, oldest first.
    """

    def __init__(self) -> None:
        self.points: list[tuple[float, float]] = []

    def add(self, f: float, d: float) -> None:
        """Take a one-sample pulse of push f (N) that moved the table d (m, > 0)."""
        if f > 0.0 and d > 0.0 and math.isfinite(f) and math.isfinite(d):
            self.points = (self.points + [(f, d)])[-KEEP_POINTS:]

    @property
    def ready(self) -> bool:
        """Whether it holds two pushes or more to plan on."""
        return len({f for f, _ in self.points}) >= 2

    def envelope(self) -> list[tuple[float, float]]:
        """The points by push, each move raised to the largest at a lower push (the upper
        envelope of a move that grows with the push); of equal pushes the largest move."""
        out: list[tuple[float, float]] = []
        top = 0.0
        for f, d in sorted(self.points):
            top = max(top, d)
            if out and out[-1][0] == f:
                out[-1] = (f, top)
            else:
                out.append((f, top))
        return out

    def move(self, f: float) -> float:
        """Move (m) of a push f (N) on the envelope: interpolated between the pushes about
        it; below the lowest, that one's move (a lower push moves less, or not); above the
        highest, on the line through the two highest (NaN: not :attr:`ready`)."""
        env = self.envelope()
        if len(env) < 2:
            return math.nan
        if f <= env[0][0]:
            return env[0][1]
        for (f0, d0), (f1, d1) in zip(env, env[1:], strict=False):
            if f <= f1:
                return d0 + (d1 - d0) * (f - f0) / (f1 - f0)
        (f0, d0), (f1, d1) = env[-2], env[-1]
        return d1 + max(d1 - d0, 0.0) * (f - f1) / (f1 - f0)

    def push(self, goal: float) -> float:
        """Push (N) whose move on the envelope is ``goal`` (m): 0 below the smallest move
        it holds (nothing says where a move that small is made), the highest push it holds
        if the envelope does not grow beyond it (NaN: not :attr:`ready`)."""
        env = self.envelope()
        if len(env) < 2:
            return math.nan
        if goal < env[0][1]:
            return 0.0
        for (f0, d0), (f1, d1) in zip(env, env[1:], strict=False):
            if goal <= d1:
                return f1 if d1 == d0 else f0 + (f1 - f0) * (goal - d0) / (d1 - d0)
        (f0, d0), (f1, d1) = env[-2], env[-1]
        if not d1 > d0:
            return f1
        return f1 + (f1 - f0) * (goal - d1) / (d1 - d0)

    def state(self) -> list[float]:
        """The points, flat: push, move of each, oldest first."""
        return [v for point in self.points for v in point]

    def set_state(self, values: Sequence[float]) -> None:
        """Restore :meth:`state`."""
        flat = [float(v) for v in values]
        if len(flat) % 2 or len(flat) > 2 * KEEP_POINTS:
            raise ValueError(f"law.curve holds {len(flat)} numbers: an even number, at most "
                             f"{2 * KEEP_POINTS}")
        self.points = [(flat[i], flat[i + 1]) for i in range(0, len(flat), 2)]
