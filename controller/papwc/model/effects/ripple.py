"""Position-dependent friction: the friction levels vary along the travel.

Both friction levels are multiplied by::

    r(x) = 1 + a * sin(2*pi*x/lambda + phi)

(``a`` the relative amplitude, 0 <= a < 1; ``lambda`` the period, m; ``phi``
the phase, rad): the sliding friction is ``r(x)*f_c`` (with the Stribeck curve,
``r(x)*g(v)``) and the breakaway force ``r(x)*f_s``, as on a guideway whose
friction coefficient varies (preload, lubrication, a screw's lead error).
"""

from __future__ import annotations

import math

__all__ = ["Ripple"]

_sin = math.sin
_cos = math.cos


class Ripple:
    """The factor ``r(x)`` on the friction levels.

    Parameters
    ----------
    a : float
        Relative amplitude, 0 < a < 1.
    period : float
        Spatial period lambda, m, > 0.
    phase : float
        Phase phi, rad.
    """

    __slots__ = ("a", "k", "phase")

    def __init__(self, a: float, period: float, phase: float) -> None:
        self.a = a
        #: Wave number 2*pi/lambda, rad/m.
        self.k = 2.0 * math.pi / period
        self.phase = phase

    def factor(self, x: float) -> tuple[float, float]:
        """``r(x)`` and ``dr/dx`` (1/m) at position ``x`` (m)."""
        arg = self.k * x + self.phase
        return 1.0 + self.a * _sin(arg), self.a * self.k * _cos(arg)
