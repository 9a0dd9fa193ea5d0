"""The motor loop of a flexible drive: state feedback on the spring deflection.

A motor of mass m_d on a coupling of stiffness k_t = m_d*omega**2 and damping c_t against a
stuck table: the deflection delta = x_d - x under a force held over each sample obeys
``(delta, delta')_(k+1) = Phi (delta, delta')_k + Gamma u_k`` exactly. :class:`MotorLoop`
holds that model, estimates the rate from two readings and the force between them, and
places both closed-loop poles at :data:`LOOP_POLE` (Ackermann); with a force that reaches
the drive one sample late (``delay`` 1) it acts on the state the force already sent leaves.
The dual-loop controller relaxes its drive with it between pulses
(:mod:`papwc.controllers.dual_loop`), and the drive check holds the ringing a probe leaves to
it (:mod:`papwc.controllers.drive_check`).

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math

__all__ = ["LOOP_POLE", "MotorLoop"]

#: Poles of the motor loop (z-plane, both): 0 would be deadbeat; a little above it keeps
#: the loop damped with the drive model a few percent off.
LOOP_POLE = 0.2


class MotorLoop:
    """State feedback on the spring deflection of a drive whose table is stuck.

    The deflection delta = x_d - x (m) of a motor of mass ``m_d`` on a spring of
    stiffness ``m_d*omega**2`` and damping ``c_t`` against a fixed table, under a
    force u held over each sample (zero-order hold), obeys
    ``(delta, delta')_(k+1) = Phi (delta, delta')_k + Gamma u_k``. The rate is estimated
    from two readings of delta and the force between them (exact on the model); the
    force is ``u_k = -K (delta, delta')_k`` with both closed-loop poles at ``pole``.

    Parameters
    ----------
    omega : float
        Angular frequency of the mode, rad/s (> 0).
    m_d : float
        Motor mass, kg (> 0).
    c_t : float
        Damping of the coupling, N.s/m (>= 0, below critical).
    T : float
        Sample period, s.
    pole : float
        Closed-loop pole (both), in [0, 1).
    delay : int
        Samples from a force's sample to the one it acts over (0 or 1): with 1, the force
        for the next sample is computed on the state the one already sent leaves
        (:meth:`force`), a third pole at 0.
    """

    def __init__(self, omega: float, m_d: float, c_t: float, T: float,
                 pole: float = LOOP_POLE, delay: int = 0) -> None:
        self.omega = float(omega)
        self.m_d = float(m_d)
        self.delay = int(delay)
        self.k_t = self.m_d * self.omega * self.omega
        zeta = min(float(c_t) / (2.0 * self.m_d * self.omega), 0.99)
        sigma = zeta * self.omega
        w_d = self.omega * math.sqrt(1.0 - zeta * zeta)
        decay = math.exp(-sigma * T)
        cos, sin = math.cos(w_d * T), math.sin(w_d * T)
        p11 = decay * (cos + sigma / w_d * sin)
        p12 = decay * sin / w_d
        p21 = -decay * self.omega * self.omega / w_d * sin
        p22 = decay * (cos - sigma / w_d * sin)
        self.phi = (p11, p12, p21, p22)
        g1 = (1.0 - p22 - 2.0 * sigma * p12) / (self.m_d * self.omega * self.omega)
        g2 = p12 / self.m_d
        self.gamma = (g1, g2)
        # Ackermann: K = [0 1] [Gamma, Phi Gamma]^-1 alpha(Phi), alpha(z) = (z - pole)**2
        c11, c21 = g1, g2
        c12, c22 = p11 * g1 + p12 * g2, p21 * g1 + p22 * g2
        det = c11 * c22 - c12 * c21
        # row [0 1] of the inverse of [[c11, c12], [c21, c22]]
        r1, r2 = -c21 / det, c11 / det
        a1, a0 = -2.0 * pole, pole * pole
        # alpha(Phi) = Phi**2 + a1*Phi + a0*I
        q11 = p11 * p11 + p12 * p21 + a1 * p11 + a0
        q12 = p11 * p12 + p12 * p22 + a1 * p12
        q21 = p21 * p11 + p22 * p21 + a1 * p21
        q22 = p21 * p12 + p22 * p22 + a1 * p22 + a0
        self.gain = (r1 * q11 + r2 * q21, r1 * q12 + r2 * q22)
        self.reset()

    def reset(self) -> None:
        """Forget the readings (the next one starts the estimate)."""
        self.delta = 0.0
        self.rate = 0.0
        #: Readings taken since the reset (at most 2 counted).
        self.readings = 0

    def observe(self, delta: float, u_prev: float) -> None:
        """Take the reading delta (m) after u_prev (N) acted over the last sample."""
        if self.readings == 0:
            self.delta, self.rate, self.readings = delta, 0.0, 1
            return
        self.readings = 2
        p11, p12, p21, p22 = self.phi
        g1, g2 = self.gamma
        d0 = self.delta
        rate0 = (delta - p11 * d0 - g1 * u_prev) / p12
        self.rate = p21 * d0 + p22 * rate0 + g2 * u_prev
        self.delta = delta

    def force(self, sent: float = 0.0) -> float:
        """The loop's force to send now, N: ``-K`` times the state it will act on -- the
        present one, or with ``delay`` 1 the one the force ``sent`` (N) at the last sample,
        which acts over the next, leaves."""
        k1, k2 = self.gain
        delta, rate = self.delta, self.rate
        if self.delay:
            p11, p12, p21, p22 = self.phi
            g1, g2 = self.gamma
            delta, rate = (p11 * delta + p12 * rate + g1 * sent,
                           p21 * delta + p22 * rate + g2 * sent)
        return -(k1 * delta + k2 * rate)

    def amplitude(self) -> float:
        """Force amplitude of the deflection's ringing, N:
        k_t*sqrt(delta**2 + (delta'/omega)**2)."""
        if self.readings < 2:
            return math.inf
        return self.k_t * math.hypot(self.delta, self.rate / self.omega)

    def state(self) -> list[float]:
        """delta (m), its rate (m/s), the readings (0, 1, 2)."""
        return [self.delta, self.rate, float(self.readings)]

    def set_state(self, values: list[float]) -> None:
        """Restore :meth:`state`."""
        if len(values) != 3:
            raise ValueError(f"law.motor holds {len(values)} numbers, not 3")
        self.delta, self.rate = (float(v) for v in values[:2])
        self.readings = min(max(int(values[2]), 0), 2)
