"""A flexible mode: the force drives a motor mass coupled to the table by a spring and a damper.

With the motor's position and velocity ``x_d``, ``v_d`` and the table's ``x``,
``v`` (the encoder reads the table)::

    m_d * dv_d/dt = f_a - F_t
    F_t           = k_t * (x_d - x) + c_t * (v_d - v)     (force on the table)
    m   * dv/dt   = F_t - friction

With the table held by stiction the motor rings at ``sqrt(k_t/m_d)`` with the
damping ratio ``c_t / (2*sqrt(k_t*m_d))``; with the table free and no friction
the mode's angular frequency is ``sqrt(k_t*(1/m + 1/m_d))``. The spring is
relaxed at the start (``x_d = x0``, ``v_d = v0``).
"""

from __future__ import annotations

__all__ = ["FlexibleMode"]


class FlexibleMode:
    """The coupling force and the motor's acceleration.

    Parameters
    ----------
    m_d : float
        Motor (driven) mass, kg, > 0.
    k_t : float
        Coupling stiffness, N/m, > 0.
    c_t : float
        Coupling damping, N.s/m, >= 0.
    """

    __slots__ = ("c_t", "k_t", "m_d")

    def __init__(self, m_d: float, k_t: float, c_t: float) -> None:
        self.m_d = m_d
        self.k_t = k_t
        self.c_t = c_t

    def coupling(self, x: float, v: float, x_d: float, v_d: float) -> float:
        """Force of the coupling on the table, N (its reaction acts on the motor)."""
        return self.k_t * (x_d - x) + self.c_t * (v_d - v)
