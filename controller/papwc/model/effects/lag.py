"""Actuator lag: the applied force follows the asked force with a first-order lag.

An amplifier and motor do not apply a force step at once::

    tau_u * df_a/dt = u - f_a

(``tau_u`` the time constant, s; ``f_a`` the force applied to the mass, N,
0 at the start). With ``u`` held over a step, ``f_a`` approaches it as
``u + (f_a(0) - u)*exp(-t/tau_u)``.
"""

from __future__ import annotations

__all__ = ["ActuatorLag"]


class ActuatorLag:
    """The applied force's rate.

    Parameters
    ----------
    tau_u : float
        Time constant, s, > 0.
    """

    __slots__ = ("rate_gain", "tau_u")

    def __init__(self, tau_u: float) -> None:
        self.tau_u = tau_u
        #: 1/tau_u, 1/s.
        self.rate_gain = 1.0 / tau_u

    def rate(self, f_a: float, u: float) -> float:
        """``df_a/dt`` (N/s) with ``f_a`` applied and ``u`` asked (N)."""
        return (u - f_a) * self.rate_gain
