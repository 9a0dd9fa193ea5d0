"""The Stribeck curve: sliding friction falling from f_s at rest to f_c with speed.

Steady sliding friction at speed ``|v|``::

    g(v) = f_c + (f_s - f_c) * S(v),   S(v) = exp(-(abs(v) / v_s)**delta_s)

(``v_s`` the Stribeck velocity, m/s; ``delta_s`` >= 1 its shape exponent).
With ``delta_s >= 1`` the slope of S is finite at v = 0, so the equations of
motion stay Lipschitz where the mass starts and stops.
"""

from __future__ import annotations

import math

__all__ = ["Stribeck"]

_exp = math.exp
#: exp(-p) is exactly 0.0 in double precision beyond this exponent.
_P_ZERO = 746.0


class Stribeck:
    """The velocity shape ``S(w) = exp(-(w/v_s)**delta_s)`` of the sliding friction.

    Parameters
    ----------
    v_s : float
        Stribeck velocity, m/s, > 0.
    delta_s : float
        Shape exponent, >= 1 (2: Gaussian; 1: exponential).
    """

    __slots__ = ("delta_s", "v_s", "_w_zero")

    def __init__(self, v_s: float, delta_s: float) -> None:
        self.v_s = v_s
        self.delta_s = delta_s
        #: Speeds above which S is 0.0 exactly (and its power would only overflow).
        self._w_zero = v_s * _P_ZERO ** (1.0 / delta_s)

    def shape(self, w: float) -> tuple[float, float]:
        """``S(w)`` and ``dS/dw`` at the speed ``w`` >= 0 (m/s)."""
        if w >= self._w_zero:
            return 0.0, 0.0
        if w == 0.0:
            return 1.0, (-1.0 / self.v_s if self.delta_s == 1.0 else 0.0)
        p = (w / self.v_s) ** self.delta_s
        s = _exp(-p)
        return s, -self.delta_s * p / w * s
