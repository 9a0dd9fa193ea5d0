"""Exact stick-slip motion of a mass with Coulomb, stiction and viscous friction.

The plant of the paper, Eq. (1) as corrected in the reading notes::

    m * dv/dt = u - f_c * sgn(v) - c * v      while v != 0
    v stays 0                                 while v == 0 and abs(u) <= f_s
    breakaway in the direction of u           when  v == 0 and abs(u) >  f_s

With the force ``u`` held constant over a step (zero-order hold), the motion
between velocity zero crossings has a closed form, so :func:`step` advances the
state exactly: the instant the velocity reaches zero is located inside the step,
the stiction test is applied there, and the mass either sticks (velocity exactly
``0.0``) or reverses. No numerical integration is involved.

This module is the single implementation of the physics: FrictionPlant.fmu, the
master's in-process plant and the pulse model (:mod:`papwc.model.pulse`) all
call it. It uses the Python standard library only (the FMUs bundle it).

Units are SI throughout: m in kg, forces in N, c in N.s/m, x in m, v in m/s,
times in s.
"""

from __future__ import annotations

import math

__all__ = [
    "coast_to_rest",
    "quantize",
    "simulate",
    "step",
    "stop_time",
]

_exp = math.exp
_expm1 = math.expm1
_log1p = math.log1p

#: Below this value of z = c*t/m, phi2 is summed as a series (see _phi2).
_PHI2_SERIES_BELOW = 0.05




def _phi1(z: float) -> float:
    """(1 - exp(-z)) / z, with its limit 1 at z = 0."""
    if z == 0.0:
        return 1.0
    return -_expm1(-z) / z


def _phi2(z: float) -> float:
    """(z - 1 + exp(-z)) / z**2, with its limit 1/2 at z = 0.

    For small z the closed form cancels, so its Taylor series
    sum_k (-z)**k / (k + 2)! is used there (truncation < 1e-15 relative).
    """
    if z < _PHI2_SERIES_BELOW:
        return 0.5 - z * (
            1.0 / 6.0
            - z
            * (
                1.0 / 24.0
                - z
                * (
                    1.0 / 120.0
                    - z * (1.0 / 720.0 - z * (1.0 / 5040.0 - z * (1.0 / 40320.0)))
                )
            )
        )
    return (z + _expm1(-z)) / (z * z)


def _psi(y: float) -> float:
    """log(1 + y) / y, with its limit 1 at y = 0."""
    if y == 0.0:
        return 1.0
    return _log1p(y) / y


def step(
    x: float, v: float, u: float, h: float, m: float, f_c: float, f_s: float, c: float
) -> tuple[float, float]:
    """Advance the plant exactly over one interval with a constant force.

    Implements the corrected Eq. (1). A sliding segment with constant
    ``F = u - s*f_c`` (``s`` the direction of motion) has the closed form::

        v(t) = v0*exp(-a*t) + (F/m)*t*phi1(a*t)
        x(t) = x0 + v0*t*phi1(a*t) + (F/m)*t**2*phi2(a*t),   a = c/m

    and, when it decelerates (``s*F < 0``), reaches ``v = 0`` at
    ``t* = -(m*v0/F)*log(1 - c*v0/F)/(-c*v0/F)``. There the stiction test is
    applied: the mass sticks when ``|u| <= f_s`` and otherwise slides back in
    the direction of ``u`` for the rest of the interval. Any interval therefore
    holds at most two segments.

    Parameters
    ----------
    x, v : float
        Position (m) and velocity (m/s) at the start of the interval.
    u : float
        Force (N), constant over the interval.
    h : float
        Interval length (s), > 0.
    m, f_c, f_s, c : float
        Mass (kg), Coulomb friction (N), stiction (N), viscous damping (N.s/m).

    Returns
    -------
    x, v : float
        Position (m) and velocity (m/s) at the end of the interval; ``v`` is
        exactly ``0.0`` if the mass is at rest.
    """
    if v == 0.0:
        if -f_s <= u <= f_s:
            return x, 0.0
        s = 1.0 if u > 0.0 else -1.0
        force = u - s * f_c
    else:
        s = 1.0 if v > 0.0 else -1.0
        force = u - s * f_c
        if s * force < 0.0:
            # Decelerating: the velocity reaches zero at t_star.
            y = -c * v / force
            t_star = -(m * v / force) * _psi(y)
            if t_star < h:
                z = c * t_star / m
                x += v * t_star * _phi1(z) + (force / m) * t_star * t_star * _phi2(z)
                h -= t_star
                if -f_s <= u <= f_s:
                    return x, 0.0
                # |u| > f_s >= f_c with s*u < f_c: u points backwards; reverse.
                s = -s
                force = u - s * f_c
                v = 0.0
    z = c * h / m
    p1 = _phi1(z)
    x_end = x + v * h * p1 + (force / m) * h * h * _phi2(z)
    v_end = v * _exp(-z) + (force / m) * h * p1
    if s * v_end < 0.0:
        # The zero crossing fell on the interval's end within rounding.
        v_end = 0.0
    return x_end, v_end


def stop_time(v: float, u: float, m: float, f_c: float, c: float) -> float:
    """Time a sliding mass takes to reach v = 0 under the constant force ``u``.

    The instant ``t_star`` of :func:`step`, computed by the same expression.

    Parameters
    ----------
    v : float
        Velocity at the start, m/s.
    u : float
        Force, N, constant.
    m, f_c, c : float
        Mass (kg), Coulomb friction (N), viscous damping (N.s/m).

    Returns
    -------
    float
        Time to rest, s: 0 if ``v`` is 0, ``inf`` if the mass does not decelerate.
    """
    if v == 0.0:
        return 0.0
    s = 1.0 if v > 0.0 else -1.0
    force = u - s * f_c
    if not s * force < 0.0:
        return math.inf
    y = -c * v / force
    return -(m * v / force) * _psi(y)


def coast_to_rest(
    x: float, v: float, m: float, f_c: float, c: float
) -> tuple[float, float]:
    """Let a sliding mass coast with u = 0 until it stops.

    Parameters
    ----------
    x, v : float
        Position (m) and velocity (m/s) at the start of the coast.
    m, f_c, c : float
        Mass (kg), Coulomb friction (N, > 0 for a finite coast), damping (N.s/m).

    Returns
    -------
    x_rest : float
        Position where the mass comes to rest, m.
    t_rest : float
        Duration of the coast, s (``inf`` if f_c = 0 and v != 0).
    """
    if v == 0.0:
        return x, 0.0
    s = 1.0 if v > 0.0 else -1.0
    force = -s * f_c
    if force == 0.0:
        # No Coulomb friction: the velocity decays to zero only asymptotically.
        return (x + v * m / c if c > 0.0 else math.copysign(math.inf, v)), math.inf
    t_star = -(m * v / force) * _psi(-c * v / force)
    z = c * t_star / m
    return x + v * t_star * _phi1(z) + (force / m) * t_star * t_star * _phi2(z), t_star





def quantize(x: float, resolution: float) -> float:
    """Position as read by an encoder of the given resolution (m); 0 = ideal.

    Rounds to the nearest count, halves away from the lower count.
    """
    if resolution <= 0.0:
        return x
    q = x / resolution
    n = math.floor(q)
    # q - n is exact (Sterbenz), so ties are decided without the rounding of q + 0.5.
    return (n + 1.0 if q - n >= 0.5 else n) * resolution


def simulate(
    u_seq: list[float],
    T: float,
    m: float,
    f_c: float,
    f_s: float,
    c: float,
    x0: float = 0.0,
    v0: float = 0.0,
) -> list[tuple[float, float]]:
    """States at every sample for a zero-order-hold force sequence.

    Parameters
    ----------
    u_seq : list of float
        Force held over each sample interval, N.
    T : float
        Sample period, s.

    Returns
    -------
    list of (x, v)
        ``len(u_seq) + 1`` states, the first being ``(x0, v0)``.
    """
    states = [(x0, v0)]
    x, v = x0, v0
    for u in u_seq:
        x, v = step(x, v, u, T, m, f_c, f_s, c)
        states.append((x, v))
    return states
