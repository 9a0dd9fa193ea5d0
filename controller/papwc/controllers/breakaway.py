"""Evidence of the breakaway: where the stuck table may break away now, and how far one
sample above that moves it.

On a table that is not Eq. (1) -- Stribeck friction, an actuator lag, pre-sliding -- a
one-sample pulse just above the breakaway force moves the table a little, not the d_min
of Eq. (20): its move ``D(eps)`` grows smoothly with the excess ``eps`` of its height
over the breakaway force. That force is drawn anew each time the table sticks (random
stiction) and follows the position (ripple), so the controller never knows it before a
pulse. It knows

* the heights that did not move the table since it last stuck: the breakaway force lies
  above the highest of them (``f_lb``) until the table moves;
* for each one-sample pulse that moved: its height ``f``, the highest height that had
  not moved the table on that stick (``lo``, a proof), the lowest breakaway it was
  planned for (``low``, at least ``lo``) and its move ``d``.

:class:`BreakawayEvidence` keeps that evidence, fits the move curve
``D(eps) = a*eps**p`` to it (:meth:`BreakawayEvidence.fit`), and gives the lowest
breakaway force still possible (:meth:`BreakawayEvidence.lowest`) and the excess that
moves the table at most a given distance if it breaks away there
(:meth:`BreakawayEvidence.plan_excess`): if it breaks away higher, the same pulse moves it
less, never more.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .budget import Ops

__all__ = ["BreakawayEvidence"]

#: One-sample moves kept (newest last), how many of the newest the curves are fitted to,
#: and how many of those nearest in length to a planned move its curve is fitted to.
KEEP = 32
FIT_MOVES = 12
LOCAL_MOVES = 6
#: Moves needed for a curve.
MIN_MOVES = 3
#: The span of the curve's scale searched (natural log).
U_SPAN = 12.0
#: Exponents of the move curve: from a table that creeps in proportion to the excess (1)
#: to an actuator lag's steep start (the force's time above breakaway grows with the
#: excess too: 3 and more); the grid over them has P_STEPS steps.
P_RANGE = (1.0, 3.5)
P_STEPS = 25
#: Curves kept: log-likelihood at most this far below the best (about 95 % for one
#: parameter).
LIKELIHOOD_DROP = 2.0
#: Before a curve, a fresh breakaway is taken to lie at most this far below the lowest
#: height seen to move (relative).
FRESH_PRIOR = 0.1
#: A fresh breakaway is never taken below this fraction of the sliding friction's
#: estimate (with pre-sliding the table creeps far below breakaway).
FLOOR = 0.05
#: Smallest margin of a fresh breakaway below the lowest one seen (relative).
FRESH_MARGIN = 0.005
#: Before a curve, the excess is this fraction of what Eq. (2) with the friction at the
#: breakaway force gives for the move.
PRIOR_SHARE = 0.5


def _upper_envelope(lines: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The lines ``(slope, intercept)`` that make the upper envelope of ``lines``, by slope:
    consecutive ones take over from each other where they cross."""
    hull: list[tuple[float, float]] = []
    for a, b in sorted(lines):
        if hull and hull[-1][0] == a:
            hull.pop()  # of equal slopes the one above (sorted: the later)
        while len(hull) >= 2:
            (a1, b1), (a2, b2) = hull[-2], hull[-1]
            if (b1 - b) * (a2 - a1) <= (b1 - b2) * (a - a1):
                hull.pop()  # the new line takes over before the last one does
            else:
                break
        hull.append((a, b))
    return hull


class BreakawayEvidence:
    """Breakaway force bounds and the move curve of one-sample pulses near breakaway.

    Parameters
    ----------
    f_c : float
        Estimate of the sliding friction, N: the breakaway force lies above it.
    m : float
        Estimate of the mass, kg (the curve before one is fitted).
    T : float
        Sample period, s.
    ops : Ops, optional
        The operations counter of the controller's update (:mod:`papwc.controllers.budget`).

    Attributes
    ----------
    smooth : bool
        A one-sample pulse that moved showed a smooth breakaway (far less motion than
        Eq. (3) predicts for it): this evidence plans the pulses near breakaway.
    f_lb : float
        Highest height that did not move the table since it last moved, N (0: none).
    moves : list of (f, lo, low, d)
        One-sample pulses that moved (see the module): N, N, N, m.
    held : bool
        A one-sample pulse did not move the table (it sticks: not pre-sliding alone).
    fresh : float
        Lowest breakaway force a fresh stick may have, N (0: no evidence), from the moves
        (:meth:`update_fresh`).
    """

    FIELDS = ("smooth", "f_lb", "moves", "fresh", "held")

    def __init__(self, f_c: float, m: float, T: float, ops: Ops | None = None) -> None:
        self.ops = ops if ops is not None else Ops()
        self.f_c = float(f_c)
        self.m = float(m)
        self.T = float(T)
        self.smooth = False
        self.f_lb = 0.0
        self.moves: list[tuple[float, float, float, float]] = []
        self.fresh = 0.0
        self.held = False
        #: The curves of :meth:`fit` by ``f_lb`` and the moves they were fitted to (derived,
        #: emptied whenever the moves change): a plan asks for them more than once.
        self._fits: dict[tuple, list[tuple[float, float, float]]] = {}

    # -- the breakaway ------------------------------------------------------------------
    def table_moved(self) -> None:
        """The table moved (and stuck again): the heights that did not move prove nothing."""
        self.f_lb = 0.0

    @staticmethod
    def breakaways(moves: list[tuple[float, float, float, float]], a: float, p: float
                   ) -> list[float]:
        """Where each of the moves broke away on the curve (a, p), N: between the proof
        ``lo`` and its height."""
        return [min(max(f - (d / a) ** (1.0 / p), lo), f) for f, lo, _, d in moves]

    def update_fresh(self) -> None:
        """The lowest breakaway force a fresh stick may have, from the moves.

        The shorter half of the recent moves (their breakaway depends least on the curve)
        on their most likely curve: below the lowest of their breakaways by the spread of
        those over their number (the expected gap below the least of n uniform draws), at
        least ``FRESH_MARGIN`` of it. Before a curve, ``FRESH_PRIOR`` below the lowest
        height seen to move. Never below ``FLOOR`` of the sliding friction's estimate.
        """
        recent = self.moves[-FIT_MOVES:]
        short = sorted(recent, key=lambda move: move[3])[:max(MIN_MOVES, (len(recent) + 1) // 2)]
        found = self.fit(short)
        if not found:
            self.fresh = (max((1.0 - FRESH_PRIOR) * min(f for f, _, _, _ in self.moves),
                              self.f_c) if self.moves else 0.0)
            return
        _, a, p = max(found)
        seen = self.breakaways(short, a, p)
        low = min(seen)
        spread = max(seen) - low
        self.fresh = max(low - max(spread / len(seen), FRESH_MARGIN * low), FLOOR * self.f_c)

    def lowest(self) -> float:
        """Lowest breakaway force still possible now, N (0: no evidence)."""
        return max(self.f_lb, self.fresh)

    # -- the move curve -----------------------------------------------------------------
    def plan_excess(self, goal: float) -> float:
        """Excess (N) over the lowest breakaway that moves the table at most ``goal`` (m).

        The least excess any curve kept needs for it. Before a curve, ``PRIOR_SHARE`` of
        Eq. (2) with the friction at the breakaway force throughout and the mass m
        (``eps*T**2/(2*m)`` per newton of excess), and no more than a straight line through
        a move planned for a lowest breakaway says.
        """
        if not goal > 0.0:
            return 0.0
        recent = self.moves[-FIT_MOVES:]
        near = sorted(recent, key=lambda move: abs(math.log(max(move[3], 1e-300) / goal)))
        eps = math.inf
        for chosen in (recent, near[:LOCAL_MOVES]):
            # on the curves of all recent moves and of those nearest the goal in length:
            # the least excess any of them needs
            found = self.fit(chosen)
            if found:
                best = max(found)[0]
                eps = min(eps, min((goal / a) ** (1.0 / p) for ll, a, p in found
                                   if ll >= best - LIKELIHOOD_DROP))
        if math.isfinite(eps):
            return eps
        eps = PRIOR_SHARE * goal * 2.0 * self.m / self.T**2
        for f, _, low, d in self.moves:
            if 0.0 < low < f and d > 0.0:
                eps = min(eps, (f - low) * goal / d)
        return eps

    def farthest(self) -> float:
        """Farthest of the moves the curves are fitted to (the ``FIT_MOVES`` newest), m (0:
        none): beyond it a curve extrapolates."""
        return max((d for _, _, _, d in self.moves[-FIT_MOVES:]), default=0.0)

    def observe(self, f: float, d: float, moved: bool, low: float = 0.0) -> None:
        """Take a one-sample pulse of height f (N) that moved the table d (m, along f):
        visibly (``moved``), or not; ``low`` the lowest breakaway it was planned for (N,
        0: it was not)."""
        if not (math.isfinite(f) and math.isfinite(d) and f > 0.0):
            return
        if not moved:
            self.f_lb = max(self.f_lb, f)
            self.held = True
            return
        lo = self.f_lb if self.f_lb < f else 0.0
        low = max(low, lo) if low < f else lo
        self.f_lb = 0.0
        self.moves = (self.moves + [(f, lo, low, max(d, 0.0))])[-KEEP:]
        self._fits.clear()
        self.update_fresh()

    @property
    def fitted(self) -> bool:
        """Whether the moves are enough for a curve."""
        return sum(1 for move in self.moves[-FIT_MOVES:] if move[3] > 0.0) >= MIN_MOVES

    def fit(self, chosen: list[tuple[float, float, float, float]]
            ) -> list[tuple[float, float, float]]:
        """The curves ``D(eps) = a*eps**p`` most likely to have given the moves ``chosen``:
        ``(log-likelihood, a, p)`` for each exponent of the grid (empty: too few moves).

        Each move's breakaway ``b_i = f_i - (d_i/a)**(1/p)`` must lie above the highest
        height that did not move before it on its stick (``lo_i``); the breakaway forces
        are taken as drawn uniformly over ``[min b_i, max(b_i, heights that did not
        move)]``, so the log-likelihood of the moves is ``-n*log(width) - sum(log
        D'(eps_i))`` (the second term the change of variables from breakaway to move).
        Pulses of different heights that broke away near one force identify the curve.
        For each exponent of a grid over ``P_RANGE`` the most likely scale is found exactly
        (:meth:`_most_likely_scale`: the likelihood is a piecewise linear function's in
        disguise), within ``exp(-U_SPAN)`` of the largest the proofs allow. Without
        ``MIN_MOVES`` moves there is no curve.
        """
        key = (self.f_lb, *chosen)  # the fit reads f_lb too
        if key not in self._fits:
            self._fits[key] = self._fit(chosen)
        return self._fits[key]

    def _fit(self, chosen: list[tuple[float, float, float, float]]
             ) -> list[tuple[float, float, float]]:
        moves = [(f, lo, d) for f, lo, _, d in chosen if d > 0.0]
        if len(moves) < MIN_MOVES:
            return []
        n = len(moves)
        still = max([self.f_lb] + [lo for _, lo, _ in moves])
        fs = [f for f, _, _ in moves]
        log_d = [math.log(d) for _, _, d in moves]
        found = []
        for k in range(P_STEPS + 1):
            p = P_RANGE[0] + (P_RANGE[1] - P_RANGE[0]) * k / P_STEPS
            cs = [d ** (1.0 / p) for _, _, d in moves]
            # u = a**(-1/p): eps_i = u*c_i; b_i >= lo_i (and > 0) bounds u above
            u_max = min((f - lo) / c if lo > 0.0 else f / c
                        for (f, lo, _), c in zip(moves, cs, strict=True))
            if not 0.0 < u_max < math.inf:
                continue
            log_u = self._most_likely_scale(fs, cs, still, u_max)
            u = math.exp(log_u)
            bs = [f - u * c for f, c in zip(fs, cs, strict=True)]
            width = max(max(bs), still) - min(bs)
            if not width > 0.0:
                continue
            # log D'(eps) = log(a*p) + (p - 1)*log(eps), a = u**-p, eps = u*c
            log_slope = n * (math.log(p) - p * log_u) + (p - 1.0) * (n * log_u + sum(log_d) / p)
            ll = -n * math.log(width) - log_slope
            if math.isfinite(ll):
                found.append((ll, math.exp(-p * log_u), p))
        return found

    def _most_likely_scale(self, fs: list[float], cs: list[float], still: float,
                           u_max: float) -> float:
        """log u of the most likely curve of one exponent (see :meth:`fit`), exactly.

        The log-likelihood is ``-n*log(width(u)/u) - n*log(p) - (p - 1)*sum(log(c_i))``, so
        the most likely u makes ``width(u)/u`` least; with ``w = 1/u`` that is
        ``H(w) = max(max_i(f_i*w - c_i), still*w) - min_i(f_i*w - c_i)``, convex and
        piecewise linear in w: its least value over ``u`` in ``[u_max*exp(-U_SPAN), u_max]``
        lies at an end or where a line takes over the upper or the lower envelope. Those
        points (at most 2n + 2) are found from the envelopes and H is bisected over them
        (convex: it falls, then rises): a dozen evaluations of H, each counted as one of
        the likelihood (:mod:`.budget`).
        """
        w_lo, w_hi = 1.0 / u_max, math.exp(U_SPAN) / u_max
        lines = [(f, -c) for f, c in zip(fs, cs, strict=True)]
        corners = [w_lo, w_hi]
        for hull in (_upper_envelope(lines + [(still, 0.0)]),
                     _upper_envelope([(-a, -b) for a, b in lines])):
            corners += [w for (a1, b1), (a2, b2) in zip(hull, hull[1:], strict=False)
                        if w_lo < (w := (b1 - b2) / (a2 - a1)) < w_hi]
        corners.sort()

        values: dict[int, float] = {}

        def h(i: int) -> float:
            if i not in values:
                self.ops.likelihood += 1
                w = corners[i]
                ys = [f * w - c for f, c in zip(fs, cs, strict=True)]
                values[i] = max(max(ys), still * w) - min(ys)
            return values[i]

        lo, hi = 0, len(corners) - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if h(mid) <= h(mid + 1):
                hi = mid
            else:
                lo = mid + 1
        w = corners[lo]
        return -math.log(w) if w > 0.0 else math.log(u_max)

    # -- state ---------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The state by name (``moves`` flat: f, lo, low, d of each, oldest first)."""
        return {"smooth": int(self.smooth), "f_lb": self.f_lb,
                "moves": [float(v) for move in self.moves for v in move], "fresh": self.fresh,
                "held": int(self.held)}

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state` (ValueError if it does not fit)."""
        flat = [float(v) for v in values["moves"]]
        if len(flat) % 4 or len(flat) > 4 * KEEP:
            raise ValueError(f"breakaway.moves holds {len(flat)} numbers: a multiple of 4, "
                             f"at most {4 * KEEP}")
        self.smooth = bool(values["smooth"])
        self.f_lb = float(values["f_lb"])
        self.moves = [(flat[i], flat[i + 1], flat[i + 2], flat[i + 3])
                      for i in range(0, len(flat), 4)]
        self.fresh = float(values["fresh"])
        self.held = bool(values["held"])
        self._fits.clear()
