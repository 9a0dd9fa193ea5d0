"""PID position control with Coulomb friction feed-forward: the baseline users run today.

The controller fires no pulses. At every sample it tracks a reference
trajectory from the position where the maneuver started to ``x_ref``: a
trapezoidal speed profile whose acceleration is at most ``a_max`` and speed at
most ``v_max`` (a triangle when the move is too short to reach ``v_max``). The
force is

    u = k_p*e + k_i*I + k_d*(v_r - v_hat) + m_est*a_r + f_c_est*sgn(...)

with ``e = r - x_meas`` (r, v_r, a_r the reference's position, speed and
acceleration, ``v_hat`` the measured speed), the feed-forward of the Coulomb
friction in the direction of the reference's speed (once it has arrived: of the
error), saturated at ``f_p_max``. The integral I stops growing while the
force is saturated in the direction the error would push it (conditional
integration: anti-windup) and its term never exceeds the force limit.

Default gains are the coarse loop's (:class:`~.sequencer.PulseSequencer`, ``m_est*w**2``
and ``2*0.7*w*m_est``) with ``w = 0.1/T`` rad/s, a tenth of the sampling rate
(``w = 10 rad/s`` at T = 0.01 s, the coarse loop's own), and ``k_i =
0.25*m_est*w**3`` (the closed loop ``m*s**3 + k_d*s**2 + k_p*s + k_i`` of the
rigid mass is stable for ``k_i < 1.4*m_est*w**3``). On a machine with a known mode
(``f_mode`` > 0) ``w`` is at most ``0.05*2*pi*f_mode`` and no friction is fed forward once the
reference has arrived: the switching ``f_c_est*sgn(e)`` drives the spring of a flexible drive
into a limit cycle (2.7 mm peak to peak at 1 kHz on the 20 Hz drive of ``realism.toml``).

Rest detection, the noise estimate and the averaged reading are the pulse
controllers' (:class:`~.rest.RestDetector`), the sequence that of their coarse move
(:class:`PidSequencer`, a :class:`~.sequencer.PulseSequencer` whose coarse force is
the PID's): once the reference has arrived and the mass, within
``tolerance`` of the target, would coast to rest inside it, the force is
released and the base's force-free rest test decides (with encoder noise: on
the average of the readings at rest); the outcome is ``settled`` only at rest
with ``|e|`` within the tolerance as the base decides it. An error beyond the
tolerance at rest is the PID's again (the integral kept). A PID that hunts --
rests on alternating sides of the target -- stops at the rest that follows
``hunt_max`` reversals if that rest is nearer the target than the maneuver
started (outcome ``stopped``, reason ``hunting``), so that the time limit does
not catch it on an excursion beyond where it started.
"""

from __future__ import annotations

import dataclasses
import math

from ..model.controller_settings import OUTCOME_REASONS
from ..model.variables import Variable
from .base import PulseControllerBase
from .interface import Mode
from .sequencer import X_LIMIT, PulseSequencer
from .settings import ControllerSettings

#: The settings the PID reads besides the shared ones.
PID_SETTINGS: tuple[Variable, ...] = (
    Variable("k_i", "Integral gain of the PID; default 0.25*m_est*w**3 with w = 0.1/T rad/s, "
             "at most 0.05*2*pi*f_mode (k_p and k_d default to m_est*w**2 and 2*0.7*w*m_est "
             "for it: the coarse loop's gains, which are these at T = 0.01 s)", "N/(m.s)", None,
             min=0.0, max=1e18, optional=True, fmi_default=37500.0),
    Variable("a_max", "Largest acceleration of the PID's reference trajectory; default "
             "(f_p_max - f_c_est)/(2*m_est), half what the force limit leaves over the "
             "friction", "m/s2", None, min=0.0, min_open=True, max=1e6, optional=True,
             fmi_default=(300.0 - 80.0) / (2.0 * 150.0)),
    Variable("v_max", "Largest speed of the PID's reference trajectory", "m/s", 0.05,
             min=0.0, min_open=True, max=1e3),
    Variable("hunt_max", "Reversals after which the PID, at rest nearer the target than the "
             "maneuver started, stops (outcome stopped, reason hunting): a reversal is a rest "
             "on the other side of the target than the last one", "", 4, type="Integer",
             min=1, max=1_000_000),
)


#: Bandwidth of the default gains as a fraction of the sampling rate 1/T (rad/s per 1/s).
BANDWIDTH = 0.1
#: Damping ratio of the default proportional and derivative gains (the coarse loop's).
ZETA = 0.7
#: Bandwidth of the default gains on a machine with a known mode, a fraction of its
#: frequency (rad/s per rad/s): a loop closed around a drive's spring through the table's
#: encoder must stay well below the mode.
MODE_BANDWIDTH = 0.05
#: Default integral gain in units of m_est*w**3.
INTEGRAL = 0.25
#: Reason code of a PID that stopped hunting (:data:`OUTCOME_REASONS`).
HUNTING = OUTCOME_REASONS.index("hunting")


def pid_gains(settings: ControllerSettings, T: float) -> tuple[float, float, float]:
    """Gains ``(k_p, k_d, k_i)`` of the PID (N/m, N.s/m, N/(m.s)) for sample period T (s).

    Each is the setting if given, else derived from ``m_est`` and the bandwidth
    ``w = 0.1/T`` rad/s: ``m_est*w**2``, ``2*0.7*w*m_est``, ``0.25*m_est*w**3``.
    """
    w = BANDWIDTH / T
    if settings.f_mode > 0.0:
        w = min(w, 2.0 * math.pi * settings.f_mode * MODE_BANDWIDTH)
    m = settings.m_est
    k_p = m * w * w if settings.k_p is None else settings.k_p
    k_d = 2.0 * ZETA * w * m if settings.k_d is None else settings.k_d
    k_i = INTEGRAL * m * w ** 3 if settings.k_i is None else settings.k_i
    return float(k_p), float(k_d), float(k_i)


def trapezoid(d: float, a_max: float, v_max: float, t: float) -> tuple[float, float, float]:
    """Reference of a rest-to-rest move of ``d`` (m) at time ``t`` (s) after its start.

    Trapezoidal speed profile: acceleration ``a_max`` (m/s**2) up to ``v_max``
    (m/s), cruise, the same deceleration; a triangle when ``|d| < v_max**2/a_max``.

    Returns
    -------
    (float, float, float)
        Position from the start (m), speed (m/s), acceleration (m/s**2), along d.
    """
    s = 1.0 if d >= 0.0 else -1.0
    dist = abs(d)
    if dist == 0.0 or t < 0.0:
        return 0.0, 0.0, 0.0
    v_top = min(v_max, math.sqrt(dist * a_max))
    t_a = v_top / a_max
    t_c = (dist - v_top * t_a) / v_top
    if t < t_a:
        return s * 0.5 * a_max * t * t, s * a_max * t, s * a_max
    if t < t_a + t_c:
        return s * (0.5 * v_top * t_a + v_top * (t - t_a)), s * v_top, 0.0
    t_d = t - t_a - t_c
    if t_d < t_a:
        left = t_a - t_d
        return s * (dist - 0.5 * a_max * left * left), s * a_max * left, -s * a_max
    return d, 0.0, 0.0


class PidSequencer(PulseSequencer):
    """The pulse sequencer's coarse move with the PID's force; it never hands over to pulses.

    The PID (:class:`PidController`) is its law: the coarse force is
    :meth:`PidController.force`, the force is released once the reference has arrived
    and the mass would coast to rest within the tolerance, and at rest the sequencer
    settles or keeps averaging, the PID acts again, or it stops hunting.
    """

    law: PidController

    def coarse(self, e: float) -> float:
        """The PID force (N); ``e`` (x_ref - x) is not used: the error is r - x."""
        self.rest.forget_direction()
        return self.law.force(self.x_prev, self.v_hat)

    def _coasts_inside(self, e: float) -> bool:
        """Release the force once the reference arrived and the mass would coast to rest
        within the tolerance (the rest test then judges the rest)."""
        if not self.law.arrived():
            return False
        v = self.v_hat
        d = self.m_est * v * v / (2.0 * self.f_c_est)
        return abs(e - math.copysign(d, v)) <= self.tolerance

    def _decide(self, x_ref: float) -> float:
        """At rest: settle or keep averaging; else the PID acts, or stops hunting.

        A rest within the tolerance read while the PID pushes is not judged: the force is
        released and the force-free rest test (which tells noise from a rest) judges.
        """
        law, rest = self.law, self.rest
        if (self.mode == Mode.COARSE and not self.released
                and abs(x_ref - rest.x_hat()) <= self.tolerance):
            self.released = True
            rest.ring_n = 0
            return 0.0
        u = super()._decide(x_ref)
        if self.mode != Mode.COARSE or not law.arrived():
            return u
        e = x_ref - rest.x_hat()
        side = 1.0 if e > 0.0 else -1.0
        if law.side and side != law.side:
            law.reversals += 1
        law.side = side
        if law.reversals >= int(law.settings.hunt_max) and abs(e) < abs(self.e0):
            return self.stop(HUNTING)
        return u


class PidController(PulseControllerBase):
    """PID on the measured position with friction feed-forward, reference trajectory,
    anti-windup and force limit (see the module docstring).

    Parameters
    ----------
    settings : ControllerSettings
        Validated settings of kind ``pid``: the gains ``k_p``, ``k_d``, ``k_i`` (None:
        the defaults of :func:`pid_gains`), the trajectory's ``a_max`` and ``v_max``, the
        force limit ``f_p_max``, the estimates ``m_est`` and ``f_c_est``, ``tolerance`` and
        ``hunt_max``.
    T : float
        Sample period, s; the default gains scale with ``w = 0.1/T`` rad/s.
    """

    kind = "pid"
    #: The settings this kind reads besides the shared ones (registry: every kind's).
    SETTINGS = PID_SETTINGS
    sequencer_class = PidSequencer

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        # The sequencer decides at rest with e_band = tolerance: the PID hands nothing over,
        # any error beyond the tolerance is the PID's again (e_band itself is not used).
        self._reset_law()
        super().__init__(dataclasses.replace(settings, e_band=settings.tolerance), T)
        self.k_p, self.k_d, self.k_i = pid_gains(settings, T)
        s = settings
        self.a_max = (s.a_max if s.a_max is not None
                      else max(s.f_p_max - s.f_c_est, 0.0) / (2.0 * s.m_est))
        if not self.a_max > 0.0:
            self.a_max = s.f_p_max / (2.0 * s.m_est)
        self.v_max = float(s.v_max)

    # -- the interface -----------------------------------------------------------------
    def reset(self) -> None:
        """Start a new maneuver from rest; the integral starts at 0."""
        super().reset()
        self._reset_law()

    def _reset_law(self) -> None:
        #: Samples since the maneuver (or the last change of the reference) started.
        self.k = 0
        #: Integral of the tracking error, m.s.
        self.integral = 0.0
        #: Start of the reference trajectory and the target it moves to, m.
        self.x_from = math.nan
        self.x_to = math.nan
        #: The reference given at the present sample, m.
        self.x_ref_now = 0.0
        #: Side of the target (+1, -1) of the last rest beyond the tolerance, and reversals.
        self.side = 0.0
        self.reversals = 0

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force to hold over the next sample, N (see :meth:`Controller.update`)."""
        if -X_LIMIT <= x_meas <= X_LIMIT and -X_LIMIT <= x_ref <= X_LIMIT:  # not NaN either
            self.x_ref_now = x_ref
            if math.isnan(self.x_to):
                # a new maneuver: the trajectory starts at the first reading
                self.x_from, self.x_to, self.k = x_meas, x_ref, 0
        u = self.seq.update(x_meas, x_ref)
        self.k += 1
        return u

    @property
    def f_low(self) -> float:
        """It fires no pulses: the force limit, N."""
        return self.settings.f_p_max

    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Never reached (no hand-over to pulses); refuses."""
        return 1, 0.0

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Nothing is learned."""

    # -- the law -----------------------------------------------------------------------
    def reference(self) -> tuple[float, float, float]:
        """Position (m), speed (m/s) and acceleration (m/s**2) of the reference now."""
        x_ref = self.x_ref_now
        if x_ref != self.x_to:
            # a new target: the trajectory starts again from where the reference is
            self.x_from, self.x_to, self.k = self._profile()[0], x_ref, 0
        return self._profile()

    def _profile(self) -> tuple[float, float, float]:
        """The trajectory from x_from to x_to at sample k: position, speed, acceleration."""
        d = self.x_to - self.x_from
        r, v_r, a_r = trapezoid(d, self.a_max, self.v_max, self.k * self.T)
        return (self.x_to if r == d else self.x_from + r), v_r, a_r

    def arrived(self) -> bool:
        """Whether the reference trajectory has reached the target."""
        return self.reference()[1] == 0.0 and self.k > 0

    def force(self, x: float, v: float) -> float:
        """The PID force (N) for the reading x (m) and measured speed v (m/s)."""
        r, v_r, a_r = self.reference()
        err = r - x
        f_max = self.settings.f_p_max
        fb = self.k_p * err + self.k_d * (v_r - v)
        ff = self.settings.m_est * a_r
        integral = self.integral + err * self.T
        if self.k_i > 0.0:
            i_lim = f_max / self.k_i
            integral = min(max(integral, -i_lim), i_lim)
        u_lin = fb + ff + self.k_i * integral
        # Once the reference has arrived, sgn(e) switches the whole friction force each
        # time the error changes sign: a relay that a drive's spring (f_mode > 0) turns into
        # a limit cycle; there the integral alone holds the friction.
        sign = v_r if v_r != 0.0 else (err if not self.mode_samples else 0.0)
        u = u_lin + (math.copysign(self.settings.f_c_est, sign) if sign != 0.0 else 0.0)
        if abs(u) > f_max and err * u > 0.0:
            # saturated in the direction the error pushes: the integral holds (anti-windup)
            integral = self.integral
            u_lin = fb + ff + self.k_i * integral
            u = u_lin + (math.copysign(self.settings.f_c_est, sign) if sign != 0.0 else 0.0)
        self.integral = integral
        return min(max(u, -f_max), f_max)

    def estimates(self) -> dict[str, float]:
        """No model is estimated: ``b_hat`` and ``f_c_hat`` are NaN."""
        return {"b_hat": math.nan, "f_c_hat": math.nan}

    # -- state -------------------------------------------------------------------------
    def law_state(self) -> dict[str, float]:
        """The trajectory's sample count and ends, the integral, the sides and reversals."""
        return {**super().law_state(), "k": self.k, "integral": self.integral,
                "x_from": self.x_from, "x_to": self.x_to, "x_ref_now": self.x_ref_now,
                "side": self.side, "reversals": self.reversals}

    def set_law_state(self, values) -> None:
        super().set_law_state(values)
        self.k, self.integral = int(values["k"]), float(values["integral"])
        self.x_from, self.x_to = float(values["x_from"]), float(values["x_to"])
        self.x_ref_now, self.side = float(values["x_ref_now"]), float(values["side"])
        self.reversals = int(values["reversals"])
