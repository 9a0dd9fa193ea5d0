"""The drive model checked against the motor encoder before a controller acts on it.

:class:`DriveCheck` reads the motor encoder's answer to a probe -- one sample of force below
the friction that holds the table -- at a controller's first samples: the sample the force
reaches the drive (the master's timing), the mode of the free ringing
(:class:`~.mode_id.ModeIdentifier`) and the motor mass its amplitude implies, against the
drive model the controller is told. The dual-loop controller builds its motor loop only on a
model the check accepts, and refuses every maneuver on one it contradicts.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ..model.controller_settings import F_MODE_MAX_T
from .mode_id import ModeIdentifier
from .motor_loop import MotorLoop

__all__ = ["MAX_DELAY", "MODE_AGREE", "MOTOR_FOLLOWS", "M_D_AGREE", "DriveCheck"]

#: A mode told more than this share of the mode the ringing shows off it is contradicted. The
#: motor loop is built on the mode the ringing shows; told more than about 15 % high, a loop
#: built on the mode told would not be stable on the drive (it pushed the table 0.09 m past
#: a 10 mm target on a 20 Hz drive told 24 Hz).
MODE_AGREE = 0.1
#: The ringing's amplitude over the model's beyond ``1 + M_D_AGREE`` or below its inverse
#: contradicts the motor mass told: a loop built on a mass 1.5 times the true one feeds the
#: drive instead of relaxing it.
M_D_AGREE = 0.3
#: Least fraction of a free motor's move over the probe's sample that its encoder must show.
MOTOR_FOLLOWS = 0.1
#: Largest delay of a force (samples) the check looks for: 1, a master stepping plant and
#: controller side by side.
MAX_DELAY = 1


class DriveCheck:
    """The drive model checked against the motor encoder before the controller acts on it.

    At the controller's first sample a probe of one sample of ``probe`` N acts on the motor
    (below the friction that holds the table: the spring's first peak is at most twice it).
    The readings that follow tell

    * which sample the force reaches the drive (:attr:`delay`, samples): the first reading
      whose deflection has moved by at least :data:`MOTOR_FOLLOWS` of the move of a free
      motor of mass ``m_d`` over one sample, ``probe*T**2/(2*m_d)`` (0 with the force
      applied over the sample it was computed for, 1 for a master that steps plant and
      controller side by side, ``timing = "delayed"``); none within :data:`MAX_DELAY` + 1
      readings: the motor encoder does not follow the force (not connected);
    * the mode of the free ringing (:class:`ModeIdentifier`, the readings after the probe);
      a mode told (``f_told`` > 0) that the ringing contradicts -- more than
      :data:`MODE_AGREE` of the mode seen off it, or no ringing of a mode within
      ``max_samples`` readings -- is refused;
    * the motor mass: the ringing's amplitude at the probe's end (read back from the last
      two readings with the decay seen) over the one the model -- the mode and decay seen,
      the mass ``m_d`` told -- gives one sample of the probe (:attr:`mass_ratio`, about
      ``m_d`` told over the true one); beyond :data:`M_D_AGREE` either way the mass told is
      contradicted. An actuator's lag spreads the probe's force over a longer time and
      lowers the ratio by up to ``1 - 1/sqrt(1 + (omega*tau_u)**2)`` (15 % at 20 Hz and
      5 ms).

    Parameters
    ----------
    T : float
        Sample period, s.
    resolution : float
        Resolution of the readings, m.
    f_told : float
        The mode the controller is told, Hz (0: none, the mode is identified).
    m_d : float
        Motor mass the controller is told, kg (> 0).
    probe : float
        Height of the probe, N (> 0).
    max_samples : int
        Readings after the probe within which the mode must be identified.

    Attributes
    ----------
    identifier : ModeIdentifier
        The fit of the ringing.
    k : int
        Readings taken.
    delta0 : float
        Deflection at the first reading, m.
    delay : int
        Samples from a force's sample to the one it acts over (-1: not known yet).
    verdict : int
        :attr:`PENDING`, :attr:`ACCEPTED` (:attr:`f_mode` the mode seen), :attr:`CONTRADICTED`,
        :attr:`NOT_SEEN` or :attr:`NOT_FOLLOWING`.
    mass_ratio : float
        The ringing's amplitude over the model's (0 until a mode is seen).
    """

    PENDING, ACCEPTED, CONTRADICTED, NOT_SEEN, NOT_FOLLOWING = range(5)

    def __init__(self, T: float, resolution: float, f_told: float, m_d: float, probe: float,
                 max_samples: int) -> None:
        self.T = float(T)
        self.f_told = float(f_told)
        self.probe = abs(float(probe))
        self.m_d = float(m_d)
        self.max_samples = int(max_samples)
        #: Least move of the deflection at the reading the probe reached, m.
        self.follows = MOTOR_FOLLOWS * self.probe * self.T * self.T / (2.0 * float(m_d))
        self.identifier = ModeIdentifier(T, resolution)
        self.restart()

    def restart(self) -> None:
        """Forget the readings (a new probe follows)."""
        self.identifier.__init__(self.T, self.identifier.resolution)
        self.k = 0
        self.delta0 = 0.0
        self.delay = -1
        self.verdict = self.PENDING
        self.mass_ratio = 0.0

    @property
    def f_mode(self) -> float:
        """The mode the ringing shows, Hz (0: none yet)."""
        return self.identifier.f_mode

    def observe(self, delta: float, x: float) -> int:
        """Take the reading of a sample, deflection delta and table x (m); the verdict."""
        k = self.k
        self.k += 1
        if self.verdict != self.PENDING:
            return self.verdict
        if k == 0:
            self.delta0 = delta
            self.identifier.observe(delta, x, 0.0, math.inf)
            return self.verdict
        if self.delay < 0:
            if abs(delta - self.delta0) >= self.follows:
                self.delay = k - 1
            elif k > MAX_DELAY:
                if self.f_told > 0.0:
                    self.verdict = self.NOT_FOLLOWING
                    return self.verdict
        # the force over the interval that ends here: the probe's, if this reading is the
        # one it reached (not known yet: taken as forced)
        forced = self.delay < 0 or k - 1 == self.delay
        # while the probe rings the drive, friction holds the table (the probe is below it):
        # its reading wanders by noise alone, whose band is not known yet
        self.identifier.observe(delta, x, self.probe if forced else 0.0, math.inf)
        f = self.identifier.f_mode
        if f > 0.0:
            self.mass_ratio = self._mass_ratio(k)
            if self.f_told > 0.0 and abs(self.f_told - f) > MODE_AGREE * f:
                self.verdict = self.CONTRADICTED
            elif f * self.T > F_MODE_MAX_T:
                self.verdict = self.CONTRADICTED if self.f_told > 0.0 else self.NOT_SEEN
            elif not 1.0 / (1.0 + M_D_AGREE) <= self.mass_ratio <= 1.0 + M_D_AGREE:
                self.verdict = self.CONTRADICTED
            else:
                self.verdict = self.ACCEPTED
        elif k > self.max_samples:
            self.verdict = self.NOT_SEEN
        return self.verdict

    def _mass_ratio(self, k: int) -> float:
        """The ringing's amplitude at the probe's end over the model's, the reading k the
        last of the fit's run (see the class)."""
        found = self.identifier.ringing()
        recent = self.identifier.recent
        if found is None or len(recent) != 2:
            return 0.0
        f, two_sigma = found
        sigma = 0.5 * two_sigma
        omega = 2.0 * math.pi * f
        w_d = math.sqrt(max(omega * omega - sigma * sigma, 0.0))
        if not w_d > 0.0:
            return 0.0
        # the free ringing delta = a*exp(-sigma*t)*cos(w_d*t + phi) through the last two
        # readings: its amplitude at reading k, then at the probe's end
        c, s = math.cos(w_d * self.T), math.sin(w_d * self.T)
        d_prev, d_now = recent
        a_k = math.hypot(d_now, (d_prev * math.exp(-sigma * self.T) - d_now * c) / s)
        a_seen = a_k * math.exp(sigma * (k - max(self.delay, 0) - 1) * self.T)
        # the model: one sample of the probe on a motor of mass m_d with this mode and decay
        model = MotorLoop(omega, self.m_d, two_sigma * self.m_d, self.T)
        delta, rate = model.gamma[0] * self.probe, model.gamma[1] * self.probe
        a_model = math.hypot(delta, (rate + sigma * delta) / w_d)
        return a_seen / a_model if a_model > 0.0 else 0.0

    def state(self) -> list[float]:
        """Readings, first deflection, delay, verdict and mass ratio, then the identifier's
        state."""
        return [float(self.k), self.delta0, float(self.delay), float(self.verdict),
                self.mass_ratio, *self.identifier.state()]

    def set_state(self, values: Sequence[float]) -> None:
        """Restore :meth:`state`."""
        if len(values) != 20:
            raise ValueError(f"law.check holds {len(values)} numbers, not 20")
        v = [float(x) for x in values]
        self.k, self.delta0, self.delay = int(v[0]), v[1], int(v[2])
        verdict = int(v[3])
        if not self.PENDING <= verdict <= self.NOT_FOLLOWING:
            raise ValueError(f"law.check: verdict {verdict} is not one of 0 to 4")
        self.verdict = verdict
        self.mass_ratio = v[4]
        self.identifier.set_state(v[5:])
