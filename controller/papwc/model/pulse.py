"""The pulse model: displacement of one force pulse from rest to rest, forward and inverse.

Standard library only (bundled into PulseController.fmu). Implements, once:

- Eq. (3) (and Eq. (2), its limit c -> 0): :func:`pulse_displacement`, with the
  velocity at the end of the pulse and the time back at rest in
  :func:`pulse_response`. It is evaluated with the plant's own closed-form
  segments (:func:`papwc.model.stickslip.step` and
  :func:`~papwc.model.stickslip.coast_to_rest`), which stay well conditioned
  for every c >= 0, where the printed form ``f_p*t_p/c - (m*f_c/c**2)*log(...)``
  cancels;
- Eq. (4): :func:`b_coulomb`, the coefficient of the Coulomb-only model
  ``d = b*t_p**2``;
- the inverses of Eq. (3): the width for a displacement at a given height
  (:func:`pulse_width`) and the height for a displacement at a given width
  (:func:`pulse_amplitude`), both by bisection to the last bit
  (:func:`bisect_increasing`).

Eq. (19) and (20) are Eq. (3) at ``t_p = T`` (and ``f_p = f_s``).

The pulse acts on a mass at rest and is assumed to break it away (``|f_p| >
f_s``), so f_s does not enter; a height at or below f_c moves nothing. SI units:
N, s, kg, N.s/m, m.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from .stickslip import _exp, _phi1, _phi2, _psi, coast_to_rest, step

__all__ = [
    "b_coulomb",
    "bisect_increasing",
    "nearest_increasing",
    "pulse_amplitude",
    "pulse_displacement",
    "pulse_response",
    "pulse_width",
]

#: Longest pulse width searched by :func:`pulse_width`, s.
_WIDTH_SEARCH_MAX = 1e9


def b_coulomb(f_p: float, m: float, f_c: float) -> float:
    """Coefficient b of the Coulomb-only pulse model, Eq. (4), m/s**2.

    ``b = f_p*(f_p - f_c) / (2*m*f_c)``, so that ``d = b*t_p**2`` (Eq. (2)).

    Parameters
    ----------
    f_p : float
        Pulse height, N.
    m : float
        Mass, kg.
    f_c : float
        Coulomb friction, N (> 0).
    """
    return f_p * (f_p - f_c) / (2.0 * m * f_c)


def pulse_response(
    f_p: float, t_p: float, m: float, f_c: float, c: float
) -> tuple[float, float, float]:
    """Response of a mass at rest to one rectangular pulse, Eq. (3), then coasting to rest.

    Parameters
    ----------
    f_p : float
        Pulse height, N (either sign; the mass breaks away if ``|f_p| > f_c``).
    t_p : float
        Pulse width, s.
    m : float
        Mass, kg (> 0).
    f_c : float
        Coulomb friction, N (>= 0).
    c : float
        Viscous damping, N.s/m (>= 0).

    Returns
    -------
    d : float
        Displacement from the start of the pulse to rest, m, with the sign of
        ``f_p``; 0 when ``|f_p| <= f_c`` or ``t_p <= 0``; ``inf`` when nothing
        stops the mass (``f_c = c = 0``).
    v_end : float
        Speed at the end of the pulse, m/s (>= 0).
    t_rest : float
        Time from the start of the pulse until rest, s.
    """
    f = abs(f_p)
    if not (t_p > 0.0 and f > f_c):
        return 0.0, 0.0, 0.0
    # From rest with |u| > f_s the mass breaks away; with f_s = f_c every height
    # above f_c does, which is the setting of Eq. (3).
    x_1, v_1 = step(0.0, 0.0, f, t_p, m, f_c, f_c, c)
    d, t_coast = coast_to_rest(x_1, v_1, m, f_c, c)
    return (d if f_p > 0.0 else -d), v_1, t_p + t_coast


def pulse_displacement(f_p: float, t_p: float, m: float, f_c: float, c: float) -> float:
    """Displacement of one pulse from rest to rest, Eq. (3) (Eq. (2) at c = 0), m.

    Equals ``f_p*t_p/c - (m*f_c/c**2)*log((f_p/f_c)*(exp(c*t_p/m) - 1) + 1)``
    for ``f_p > f_c`` and ``c > 0``, without its cancellation for small c. See
    :func:`pulse_response` for the parameters.

    The two segments of :func:`pulse_response` (the pulse from rest, then the coast) written
    out with the very operations :func:`~papwc.model.stickslip.step` and
    :func:`~papwc.model.stickslip.coast_to_rest` make there, so the result is
    :func:`pulse_response`'s bit for bit (a test draws it so) in two thirds of the time: the
    controllers' fits and plans evaluate it thousands of times a pulse.
    """
    f = abs(f_p)
    if not (t_p > 0.0 and f > f_c):
        return 0.0
    # the pulse: step() from x = v = 0 with u = f, which breaks the mass away along f_p
    x = v = 0.0
    s = 1.0 if f > 0.0 else -1.0
    force = f - s * f_c
    z = c * t_p / m
    p1 = _phi1(z)
    x, v = (x + v * t_p * p1 + (force / m) * t_p * t_p * _phi2(z),
            v * _exp(-z) + (force / m) * t_p * p1)
    if s * v < 0.0:
        v = 0.0
    # the coast: coast_to_rest() from (x, v)
    if v != 0.0:
        force = -f_c if v > 0.0 else f_c
        if force == 0.0:
            x = x + v * m / c if c > 0.0 else math.copysign(math.inf, v)
        else:
            t_star = -(m * v / force) * _psi(-c * v / force)
            z = c * t_star / m
            x = x + v * t_star * _phi1(z) + (force / m) * t_star * t_star * _phi2(z)
    return x if f_p > 0.0 else -x


def bisect_increasing(
    f: Callable[[float], float], target: float, lo: float, hi: float, tol: float = 0.0
) -> tuple[float, float]:
    """Bracket of the root of ``f(x) = target`` for ``f`` non-decreasing, to adjacent floats.

    Parameters
    ----------
    f : callable
        Non-decreasing function.
    target : float
        The value sought.
    lo, hi : float
        Finite bracket with ``f(lo) < target <= f(hi)``.
    tol : float
        The halving stops once ``hi - lo <= tol`` (0: at adjacent floats). For an ``f``
        that costs a simulation, where a bracket of that width is enough.

    Returns
    -------
    (lo, hi) : (float, float)
        Floats with ``f(lo) < target <= f(hi)``, adjacent (or equal), or within tol.
    """
    for _ in range(4096):  # a float interval halves to adjacent floats in < 2100 steps
        if hi - lo <= tol:
            break
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if f(mid) < target:
            lo = mid
        else:
            hi = mid
    return lo, hi


def pulse_width(d: float, f_p: float, m: float, f_c: float, c: float) -> float:
    """Pulse width t_p (s) whose displacement, Eq. (3), is ``d`` (m): Eq. (3) inverted in t_p.

    Parameters
    ----------
    d : float
        Displacement, m (> 0).
    f_p : float
        Pulse height, N (> f_c).
    m, f_c, c : float
        Mass (kg), Coulomb friction (N), viscous damping (N.s/m).

    Returns
    -------
    float
        Width, s; ``inf`` if no width up to 1e9 s reaches ``d``.
    """

    def displacement(t_p: float) -> float:
        return pulse_displacement(f_p, t_p, m, f_c, c)

    hi = 1.0
    while displacement(hi) < d:
        hi *= 2.0
        if hi > _WIDTH_SEARCH_MAX:
            return math.inf
    lo, hi = bisect_increasing(displacement, d, 0.0, hi)
    return 0.5 * (lo + hi)


def pulse_amplitude(
    d: float, t_p: float, m: float, f_c: float, c: float, f_lo: float, f_hi: float
) -> float:
    """Pulse height that moves the mass by ``d`` in a pulse of width ``t_p``: Eq. (3) inverted.

    The displacement of Eq. (3) increases strictly with the height above f_c,
    so the root is bracketed in ``[f_lo, f_hi]`` and found by bisection to the
    last bit.

    Parameters
    ----------
    d : float
        Displacement, m (> 0).
    t_p : float
        Pulse width, s.
    m, f_c, c : float
        Model parameters (kg, N, N.s/m).
    f_lo, f_hi : float
        Bounds of the height, N (``f_lo <= f_hi``).

    Returns
    -------
    float
        Height in ``[f_lo, f_hi]``, N, whose displacement is closest to ``d``; a
        bound if ``d`` lies outside the displacements the bounds give.
    """

    return nearest_increasing(lambda f_p: pulse_displacement(f_p, t_p, m, f_c, c), d, f_lo, f_hi)


def nearest_increasing(f: Callable[[float], float], target: float, lo: float,
                       hi: float) -> float:
    """The x in ``[lo, hi]`` whose ``f(x)`` is nearest ``target``, ``f`` non-decreasing.

    ``lo`` if ``f(lo) >= target``, ``hi`` if ``f(hi) <= target``, else the nearer
    of the two adjacent floats that :func:`bisect_increasing` brackets the root
    with.
    """
    if f(lo) >= target:
        return lo
    if f(hi) <= target:
        return hi
    a, b = bisect_increasing(f, target, lo, hi)
    return a if target - f(a) <= f(b) - target else b
