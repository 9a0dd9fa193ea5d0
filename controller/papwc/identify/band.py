"""The stiction band: where the breakaway force of the next stick may be drawn.

A real table does not release at one force: after each stop its breakaway force is drawn
anew (random stiction, :mod:`papwc.model.effects.stiction`: uniformly in
``f_s*(1 +- f_s_spread)``), and a friction ripple multiplies it by ``r(x)`` where it stands
(:mod:`papwc.model.effects.ripple`). The excitation's teeth (:mod:`.excitation`) break the
table away from many sticks; the fit (:mod:`.fit`) says at which force each did
(:func:`papwc.identify.fit.breakaways`), and, divided by the identified ripple's factor at
its place, that is one *draw*. From ``n`` draws :func:`band_of` gives

* the lowest and the highest seen;
* the *band for the next draws*: the prediction interval ``[x_(1) - delta*R, x_(n) + delta*R]``
  (``x_(1)``, ``x_(n)`` the lowest and highest draw, ``R`` their range) that holds the next
  :data:`NEXT_DRAWS` draws all together with probability :data:`COVERAGE` when the draws are
  uniform, as random stiction draws them: ``delta`` depends on ``n`` alone
  (:func:`prediction_factor`: the lowest and highest of ``n`` uniform draws, scaled by the
  band's width, have a distribution free of the band's place and width);
* the point estimates of ``f_s`` (the band's middle) and ``f_s_spread`` (its half-width,
  ``R/2*(n + 1)/(n - 1)``, the unbiased estimate for uniform draws, over the middle) with
  95 % intervals (``R`` over the band's width is Beta(n - 1, 2)).

Draws whose brackets all overlap (a single breakaway force, no random stiction) give
``f_s_spread = 0``.

The number of sticks the band needs (:func:`sticks_needed`) is the fewest for which the band
for the next draws is on average at most :data:`WIDTH_MAX` times as wide as the true one.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["COVERAGE", "NEXT_DRAWS", "WIDTH_MAX", "Band", "band_of", "expected_width",
           "prediction_factor", "sticks_needed"]

#: The band for the next draws holds this many ...
NEXT_DRAWS = 20
#: ... all together with this probability (uniform draws).
COVERAGE = 0.95
#: Largest expected width of that band over the true band's (it sets the sticks needed).
WIDTH_MAX = 1.35
#: Fewest draws a band is made from.
MIN_DRAWS = 3
#: Points of the quadrature over the range of the draws and over the lowest draw
#: (:func:`_coverage`).
_QUADRATURE = 400
_SUB = 64


@dataclass(frozen=True)
class Band:
    """The stiction band of :func:`band_of` (forces in N, without the ripple's factor).

    Attributes
    ----------
    draws : tuple of float
        The breakaway forces seen, the ripple's factor removed, N.
    lowest, highest : float
        The lowest and highest of them, N.
    low, high : float
        The band for the next draws (see the module), N.
    f_s, f_s_low, f_s_high : float
        The band's middle and its 95 % interval, N.
    spread, spread_low, spread_high : float
        ``f_s_spread`` (the half-width over the middle) and its 95 % interval.
    factor : float
        ``delta`` of the band for the next draws.
    single : bool
        Every draw's bracket overlaps every other's: one breakaway force.
    """

    draws: tuple[float, ...]
    lowest: float
    highest: float
    low: float
    high: float
    f_s: float
    f_s_low: float
    f_s_high: float
    spread: float
    spread_low: float
    spread_high: float
    factor: float
    single: bool

    @property
    def sticks(self) -> int:
        """Draws the band is made from."""
        return len(self.draws)


def _coverage(n: int, delta: float, m: int = NEXT_DRAWS) -> float:
    """Probability that the next ``m`` of uniform(0, 1) draws all lie in
    ``[x_(1) - delta*R, x_(n) + delta*R]`` of ``n`` draws (midpoint quadrature over the range
    R, whose density is ``n(n-1) R^(n-2) (1-R)``, and over ``x_(1)``, uniform on
    ``[0, 1-R]`` given R)."""
    import numpy as np

    r = (np.arange(_QUADRATURE) + 0.5) / _QUADRATURE
    weight = n * (n - 1) * r ** (n - 2) * (1.0 - r) / _QUADRATURE
    frac = (np.arange(_SUB) + 0.5) / _SUB
    s = frac[np.newaxis, :] * (1.0 - r)[:, np.newaxis]
    rr = r[:, np.newaxis]
    c = np.minimum(s + rr + delta * rr, 1.0) - np.maximum(s - delta * rr, 0.0)
    return float(np.sum(weight * np.mean(c**m, axis=1)))


@functools.lru_cache(maxsize=128)
def prediction_factor(n: int, coverage: float = COVERAGE, m: int = NEXT_DRAWS) -> float:
    """``delta`` of the band for the next ``m`` draws from ``n`` draws (see the module).

    Parameters
    ----------
    n : int
        Draws seen (at least 2).
    coverage : float
        Probability that the next ``m`` draws all lie in the band.
    m : int
        Draws predicted.

    Returns
    -------
    float
        The band's extension beyond the lowest and the highest draw, in units of their range.

    Examples
    --------
    >>> round(prediction_factor(14), 3)
    0.273
    """
    if n < 2:
        raise ValueError(f"a band needs at least 2 draws, not {n}")
    lo, hi = 0.0, 1.0
    while _coverage(n, hi, m) < coverage:
        lo, hi = hi, 2.0 * hi
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if _coverage(n, mid, m) < coverage:
            lo = mid
        else:
            hi = mid
    return hi


def expected_width(n: int) -> float:
    """Expected width of the band for the next draws from ``n`` draws, over the true one's."""
    return (1.0 + 2.0 * prediction_factor(n)) * (n - 1) / (n + 1)


@functools.lru_cache(maxsize=1)
def sticks_needed() -> int:
    """The fewest draws whose band for the next draws is on average at most
    :data:`WIDTH_MAX` times as wide as the true band.

    Examples
    --------
    >>> sticks_needed()
    14
    """
    n = MIN_DRAWS
    while expected_width(n) > WIDTH_MAX:
        n += 1
    return n


def band_of(draws: Sequence[float], brackets: Sequence[tuple[float, float]] | None = None,
            sticks: int | None = None) -> Band:
    """The stiction band of the breakaway forces ``draws`` (N, the ripple's factor removed).

    Parameters
    ----------
    draws : sequence of float
        One breakaway force per stick, N (at least :data:`MIN_DRAWS`).
    brackets : sequence of (float, float), optional
        For each draw the interval it is known to lie in, N: if they all overlap, the draws
        are one force (``single``) and the spread is 0.
    sticks : int, optional
        The draws that place the band (default: all): the band for the next draws is that of
        so many (where some draws are placed by others, as the fit's sliding moves are by
        the breakaways near the band).

    Returns
    -------
    Band

    Raises
    ------
    ValueError
        If fewer than :data:`MIN_DRAWS` draws are given or one is not finite and positive.
    """
    from scipy.stats import beta

    values = tuple(float(d) for d in draws)
    if len(values) < MIN_DRAWS:
        raise ValueError(f"{len(values)} breakaway(s) seen; a band needs at least {MIN_DRAWS}")
    if not all(math.isfinite(d) and d > 0.0 for d in values):
        raise ValueError("a breakaway force is not a finite positive number")
    n = len(values)
    x1, xn = min(values), max(values)
    r = xn - x1
    delta = prediction_factor(max(min(sticks or n, n), 2))
    single = bool(brackets) and max(lo for lo, _ in brackets) <= min(hi for _, hi in brackets)
    middle = 0.5 * (x1 + xn)
    if single:
        lo = max(b[0] for b in brackets)
        hi = min(b[1] for b in brackets)
        middle = 0.5 * (lo + hi)
        return Band(values, x1, xn, x1 - delta * r, xn + delta * r, middle, lo, hi, 0.0, 0.0,
                    max(middle - x1, xn - middle) / middle, delta, True)
    half = 0.5 * r * (n + 1) / (n - 1)
    # R/(b - a) ~ Beta(n - 1, 2): the true half-width lies within R/2 / quantiles.
    q_lo, q_hi = (float(beta.ppf(q, n - 1, 2)) for q in (0.025, 0.975))
    spread_low, spread_high = 0.5 * r / q_hi / middle, 0.5 * r / q_lo / middle
    # the middle: (x1 + xn)/2 is off the true middle by at most the slack of the two ends
    slack = 0.5 * r / q_lo - 0.5 * r
    return Band(values, x1, xn, x1 - delta * r, xn + delta * r, middle, middle - slack,
                middle + slack, half / middle, spread_low, spread_high, delta, False)
