"""The LuGre friction model: bristles that deflect before the mass slides (pre-sliding).

Canudas de Wit, Olsson, Astrom and Lischinsky, "A new model for control of
systems with friction", IEEE TAC 40(3), 1995. With the bristles' mean
deflection ``z`` (m)::

    dz/dt = v - sigma_0 * abs(v) * z / g(v)
    F     = sigma_0 * z + sigma_1 * dz/dt + c * v

``sigma_0`` (N/m) is the bristles' stiffness, ``sigma_1`` (N.s/m) their
damping, ``c`` the viscous friction (sigma_2 of the paper), and ``g(v)`` > 0
the steady sliding friction (the Stribeck curve, or f_c without it). At
constant velocity ``z`` settles at ``g(v)*sgn(v)/sigma_0`` and F at
``g(v)*sgn(v) + c*v``: the Stribeck curve. Below breakaway the mass creeps on
the bristles' spring instead of sticking, so there is no stick-slip switch.
"""

from __future__ import annotations

__all__ = ["LuGre"]


class LuGre:
    """The bristle state's rate and the friction force, with their partial derivatives.

    Parameters
    ----------
    sigma_0 : float
        Bristle stiffness, N/m, > 0.
    sigma_1 : float
        Bristle damping, N.s/m, >= 0.
    """

    __slots__ = ("sigma_0", "sigma_1")

    def __init__(self, sigma_0: float, sigma_1: float) -> None:
        self.sigma_0 = sigma_0
        self.sigma_1 = sigma_1

    def rate(self, v: float, z: float, g: float) -> float:
        """``dz/dt`` (m/s) at velocity ``v`` (m/s), deflection ``z`` (m), level ``g`` (N)."""
        return v - self.sigma_0 * abs(v) * z / g

    def partials(self, v: float, z: float, g: float, g_x: float, g_v: float
                 ) -> tuple[float, float, float]:
        """``d(dz/dt)`` by ``x``, ``v`` and ``z``, given ``g`` and its derivatives ``g_x``, ``g_v``.

        At v = 0 the slope of ``|v|`` is taken as 0 (the mean of its two sides).
        """
        s0 = self.sigma_0
        w = abs(v)
        sgn = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
        inv_g = 1.0 / g
        return (s0 * w * z * g_x * inv_g * inv_g,
                1.0 - s0 * z * (sgn - w * g_v * inv_g) * inv_g,
                -s0 * w * inv_g)

    def force(self, z: float, z_rate: float) -> float:
        """The bristles' force ``sigma_0*z + sigma_1*dz/dt`` (N), viscous friction apart."""
        return self.sigma_0 * z + self.sigma_1 * z_rate
