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

The in-position window (``in_position``, on by default where T <= 1 ms; issue 43's
practitioners' anchor): the force is not released on the way in (but cut where the table
would coast to rest inside the window); once the reference has arrived and the table rests
inside ``in_position_band`` (at rest by the rest detector, still by the slope of its last 16
readings), the integrator is frozen and the force bled to zero, the readings are averaged
and the outcome is ``settled`` only once the average is within the tolerance by three
standard errors and the rounding of a count (``x_resolution``); a reading beyond the window
by more than noise, or the average beyond it, hands the table back to the PID
(:meth:`PidSequencer.window_update`).
"""

from __future__ import annotations

import dataclasses
import math

from ..model.controller_settings import OUTCOME_REASONS
from ..model.variables import Variable
from .base import PulseControllerBase
from .exact import EXACT_SETTINGS
from .interface import Mode, Outcome, Reason
from .rest import BAND_SIGMAS, NOISE_WINDOW
from .sequencer import X_LIMIT, Z_DECIDE, PulseSequencer
from .settings import ControllerSettings

#: The encoder's count: the exact-model controller's setting (the same Variable), which the
#: window's decisions at rest read too.
X_RESOLUTION = next(v for v in EXACT_SETTINGS if v.name == "x_resolution")
#: Default half-width of the hybrid's window (kind hybrid, :mod:`.hybrid`), m.
HYBRID_BAND = 5e-6

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
             "on the other side of the target than the last one (in_position: beyond "
             "in_position_band; it then holds its force)", "", 4, type="Integer",
             min=1, max=1_000_000),
    Variable("in_position", "In-position window of the PID, as a drive's: once the reference "
             "has arrived and the table rests (still) within in_position_band of the target, "
             "the integrator is frozen and the force bled to zero (hybrid: held, at most "
             "f_c_est), the readings averaged and the outcome settled only within the "
             "tolerance; the PID acts again, with the integral it had, once the table is seen "
             "outside the band. Default: on where T <= 1 ms (a drive's loop), off at longer "
             "periods (the force is then released near the target and the rest judged "
             "without it)", "", None, type="Boolean", optional=True, fmi_default=False),
    Variable("in_position_band", "Half-width of the in-position window around the target; "
             "default the tolerance, at least one count (x_resolution; hybrid: at least "
             f"{HYBRID_BAND * 1e6:g} um)", "m", None, min=0.0, max=1.0, optional=True,
             nominal=1e-6, fmi_default=2e-5),
    X_RESOLUTION,
)

#: Sum of the squared centred sample indices of the still test's least-squares slope
#: (:meth:`PidSequencer.still`, over ``NOISE_WINDOW`` readings).
SLOPE_NORM = sum((i - 0.5 * (NOISE_WINDOW - 1)) ** 2 for i in range(NOISE_WINDOW))
#: The in-position window is on by default at sample periods up to this, s (a drive's 1 kHz
#: loop), and the relative margin that takes T = 1e-3 written in any way.
IN_POSITION_T = 1e-3
IN_POSITION_T_MARGIN = 1e-9


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


def in_position_window(settings: ControllerSettings, T: float) -> tuple[bool, float]:
    """Whether the in-position window is on, and its half-width (m), for sample period T (s).

    ``in_position`` if given, else on where ``T <= IN_POSITION_T`` (1 ms); the half-width
    ``in_position_band`` if given, else the tolerance, at least one count
    (``x_resolution``).
    """
    on = (T <= IN_POSITION_T * (1.0 + IN_POSITION_T_MARGIN) if settings.in_position is None
          else bool(settings.in_position))
    band = (max(settings.tolerance, settings.x_resolution) if settings.in_position_band is None
            else settings.in_position_band)
    return on, float(band)


def rounding_bias(sigma2: float, q: float) -> float:
    """Largest bias of the mean of readings rounded to the count q (m) under encoder noise of
    variance sigma2 (m**2), m: ``q/2`` without noise (the reading says only which count the
    table is in), ``(q/2)*exp(-2*pi**2*sigma2/q**2)`` with it (noise of a count or more
    dithers the rounding away: the first harmonic of the rounding error, bounded by q/2)."""
    if not q > 0.0:
        return 0.0
    return 0.5 * q * math.exp(-2.0 * math.pi * math.pi * sigma2 / (q * q))


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
    :meth:`PidController.force`. Without the in-position window, the force is released once
    the reference has arrived and the mass would coast to rest within the tolerance, and at
    rest the sequencer settles or keeps averaging, the PID acts again, or it stops hunting.
    With the window (``in_position``), :meth:`window_update` runs each sample instead: the
    force is never released; at rest within ``in_position_band`` it is held.
    """

    law: PidController

    def update(self, x_meas: float, x_ref: float) -> float:
        """Force (N) to hold over the next sample (with the window: :meth:`window_update`)."""
        if self.law.window:
            return self.window_update(x_meas, x_ref)
        return super().update(x_meas, x_ref)

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

    # -- the in-position window --------------------------------------------------------
    def window_update(self, x_meas: float, x_ref: float) -> float:
        """One sample of the PID with its in-position window (force, N).

        The PID acts until the reference has arrived and the table rests inside the
        window: at rest by the rest detector's band and dwell, still by the slope of the
        last readings (:meth:`still`), the averaged reading within ``in_position_band``.
        Then the force is held (:meth:`hold`) and the integrator frozen. It does not skip
        samples (``idle_samples`` stays 0).

        The readings after the reference has arrived go to the rest detector's force-free
        windows, whose scatter (sample to sample, which a slow move hardly changes) is its
        noise estimate before any hold; the spread of a rest counts as noise only under a
        force held (under the acting PID a rest may hold a move within the band).
        """
        law = self.law
        if self.stopped:
            return law.u_hold if law.holding else 0.0
        if not (-X_LIMIT <= x_meas <= X_LIMIT and -X_LIMIT <= x_ref <= X_LIMIT):  # also NaN
            law.holding = False
            return self.stop(Reason.INVALID_MEASUREMENT)
        return self.window_act(x_ref, self.window_read(x_meas, x_ref))

    def window_read(self, x_meas: float, x_ref: float) -> bool:
        """Take the reading x_meas (m): the speed, the last readings, the rest detector;
        whether at rest by its band and dwell."""
        law, rest = self.law, self.rest
        law.ring[law.ring_n % NOISE_WINDOW] = x_meas
        law.ring_n += 1
        if self.first:
            self.first = False
            self.v_hat = 0.0
            rest.start_run(x_meas)
            self.e0 = x_ref - x_meas
            self.x_prev = x_meas
            return False
        dx = x_meas - self.x_prev
        self.v_hat = dx / self.T
        self.x_prev = x_meas
        at_rest = rest.read(x_meas, law.holding)
        if self.quiet_readings():
            at_rest = rest.force_free(x_meas, dx, at_rest)
        return at_rest

    def quiet_readings(self) -> bool:
        """Whether the reading goes to the rest detector's force-free windows (the noise
        estimate): once the reference has arrived."""
        return self.law.arrived()

    def window_act(self, x_ref: float, at_rest: bool) -> float:
        """The force (N) after the reading: held inside the window, else the PID's."""
        law, rest = self.law, self.rest
        if law.holding:
            return self.hold(x_ref)
        if law.coasting:
            if not law.arrived():
                law.coasting = False
            elif at_rest and self.still():
                law.coasting = False
                return self.enter_hold(x_ref, law.u_coast, capped=False)
            else:
                return law.u_coast
        if law.arrived() and not at_rest and self.coasts_into_window(x_ref):
            law.coasting, law.u_coast = True, self.coast_force()
            self.mode = Mode.WAIT
            return law.u_coast
        if law.arrived() and at_rest:
            e = x_ref - rest.x_hat()
            if abs(e) <= law.w_band and self.still():
                return self.enter_hold(x_ref, law.u_last)
            side = 1.0 if e > 0.0 else -1.0
            if law.side and side != law.side:
                law.reversals += 1
            law.side = side
            if law.reversals >= int(law.settings.hunt_max) and abs(e) < abs(self.e0):
                law.holding, law.u_hold = True, self.holding_force(law.u_last)
                self.stop(HUNTING)
                return law.u_hold
        return self.pid_force()

    def coasts_into_window(self, x_ref: float) -> bool:
        """Whether the table, moving, would coast to rest inside the window with the force
        released (``m_est*v**2/(2*f_c_est)`` along its speed, as the PID without the window
        releases it inside the tolerance)."""
        v = self.v_hat
        if v == 0.0:
            return False
        d = self.m_est * v * v / (2.0 * self.f_c_est)
        return abs(x_ref - self.x_prev - math.copysign(d, v)) <= self.law.w_band

    def coast_force(self) -> float:
        """The force while the table coasts into the window, N: none (it is then held)."""
        return 0.0

    def holding_force(self, u: float) -> float:
        """The force the window holds for the force u (N) the PID gave last: none.

        Bled to zero at once (the integrator frozen): on a table whose friction holds it,
        any force below its breakaway holds it alike, and a force held near the breakaway
        slips it (a stiction drawn anew, an actuator's lag catching up) or, on pre-sliding
        bristles, lets it creep out of the window to be pushed back (hunting). Measured on
        realism_mc_lugre_1khz.toml (tolerance 0.1 um, offsets 0, 1000, 2000; 54 rigid runs):
        within one count 36 released against 29 held at most ``f_c_est``, the position
        moving more than a count in the last 0.5 s in 13 against 29 runs; on the stick-slip
        tables of realism_mc_1khz.toml the same runs either way (the force is cut as the
        table coasts into the window). The hybrid holds its force (its ramps start there).
        """
        return 0.0

    def enter_hold(self, x_ref: float, u: float, capped: bool = True) -> float:
        """Hold the force :meth:`holding_force` gives for u (N; not ``capped``: u itself)
        from here; its readings are averaged anew (a rest before it may have moved within the
        band, and the force held may differ from the PID's last)."""
        law = self.law
        law.holding, law.u_hold = True, self.holding_force(u) if capped else u
        self.mode = Mode.WAIT
        law.h_x0, law.h_sum, law.h_n = self.x_prev, 0.0, -NOISE_WINDOW
        law.h_look = self.rest.dwell + 1
        return law.u_hold

    def still(self) -> bool:
        """Whether the last ``NOISE_WINDOW`` readings show no move: their least-squares slope
        within ``Z_DECIDE`` standard errors of 0 (from the noise estimate; exactly 0 on a
        noiseless encoder). A table the PID pushes can creep within the rest band (a
        drive's standstill test is a speed test); False until the window is full."""
        law = self.law
        k = law.ring_n
        if k < NOISE_WINDOW:
            return False
        ring = law.ring
        mid = 0.5 * (NOISE_WINDOW - 1)
        first = ring[k % NOISE_WINDOW]
        slope = 0.0
        for i in range(NOISE_WINDOW):
            slope += (i - mid) * (ring[(k + i) % NOISE_WINDOW] - first)
        slope /= SLOPE_NORM
        return abs(slope) <= Z_DECIDE * math.sqrt(self.rest.sigma2 / SLOPE_NORM)

    def recent_mean(self, m: int) -> float:
        """Mean of the last m readings (m <= ``NOISE_WINDOW``), m."""
        law = self.law
        k = law.ring_n
        total = 0.0
        for i in range(1, m + 1):
            total += law.ring[(k - i) % NOISE_WINDOW]
        return total / m

    def pid_force(self) -> float:
        """The PID acts (mode coarse): its force at the last reading, N.

        A force is applied: the rest detector's force-free direction starts anew (a move
        the PID makes is not a ring), its quiet windows go on.
        """
        law = self.law
        self.rest.forget_direction()
        self.mode = Mode.COARSE
        self.outcome = Outcome.ACTIVE
        self.outcome_reason = Reason.NONE
        law.u_last = law.force(self.x_prev, self.v_hat)
        return law.u_last

    def hold(self, x_ref: float) -> float:
        """Inside the window: the held force (N), or the PID again once the table is outside.

        The readings under the force held are averaged (``x_hat = h_x0 + h_sum/h_n``, its
        standard error ``s`` from the noise estimate), from ``NOISE_WINDOW`` samples after
        it began (the force held settles: an actuator's lag, bristles): the table cannot
        move under it unless it slips, which :meth:`crept` sees, and the average then
        starts anew. The table is
        outside once a reading lies beyond the window by more than the rest band
        (:meth:`reading_margin`: a move, not noise), or the average beyond it by
        ``Z_DECIDE`` standard errors; the PID then acts again with the integral it had
        (frozen while the force was held): its proportional, derivative and friction terms
        take the error as it is now, so a table that crept past the target is pushed back
        at once. The outcome is ``settled`` once ``abs(e_hat) + Z_DECIDE*s`` is within the
        tolerance, decided as the pulse controllers decide (at N = D + 1 readings, then each
        time N has grown by half), and no longer once the evidence says otherwise; else
        :meth:`inside` decides. Every bound allows for the rounding of the readings to the
        encoder's count (:func:`rounding_bias`).
        """
        law = self.law
        x = self.x_prev
        if not law.arrived() or abs(x_ref - x) > law.w_band + self.reading_margin():
            return self.leave_hold()
        law.h_n += 1
        if law.h_n <= 0:
            # the force held settles (an actuator's lag, bristles): its readings are not yet
            # those of the rest
            law.h_x0 = x
            return law.u_hold
        law.h_sum += x - law.h_x0
        if self.crept():
            law.h_x0 = self.recent_mean(NOISE_WINDOW)
            law.h_sum, law.h_n = 0.0, NOISE_WINDOW
            law.h_look = NOISE_WINDOW
        if law.h_n < law.h_look:
            return law.u_hold
        while law.h_look <= law.h_n:
            law.h_look = (3 * law.h_look + 1) // 2
        e = x_ref - (law.h_x0 + law.h_sum / law.h_n)
        s = math.sqrt(self.rest.sigma2 / law.h_n)
        bias = rounding_bias(self.rest.sigma2, law.q)
        if abs(e) - Z_DECIDE * s - bias > law.w_band:
            return self.leave_hold()
        if abs(e) + Z_DECIDE * s + bias <= self.tolerance:
            self.settle()
            return law.u_hold
        if (self.outcome == Outcome.SETTLED
                and abs(e) - Z_DECIDE * s - bias > self.tolerance):
            self.mode = Mode.WAIT
            self.outcome = Outcome.ACTIVE
            self.outcome_reason = Reason.NONE
        return self.inside(e, s)

    def crept(self) -> bool:
        """Whether the table moved under the force held: the mean of the last
        ``NOISE_WINDOW`` readings away from the mean of the hold's readings before them by
        more than ``Z_DECIDE`` standard errors of their difference (and a count's
        rounding)."""
        law = self.law
        n = law.h_n
        if n < 2 * NOISE_WINDOW:
            return False
        w = NOISE_WINDOW
        last = self.recent_mean(w)
        before = law.h_x0 + (law.h_sum - w * (last - law.h_x0)) / (n - w)
        d = abs(last - before) - rounding_bias(self.rest.sigma2, law.q)
        return d > 0.0 and d * d > Z_DECIDE * Z_DECIDE * self.rest.sigma2 * (1.0 / w
                                                                             + 1.0 / (n - w))

    def inside(self, e: float, s: float) -> float:
        """Inside the window, not known to be within the tolerance (the averaged error e, m,
        its standard error s, m): the force held, N (the PID kind does nothing more)."""
        return self.law.u_hold

    def reading_margin(self) -> float:
        """How far beyond the window's edge a single reading may lie from noise alone, m:
        the rest band, at least ``BAND_SIGMAS`` times the noise estimate (0 on a noiseless
        encoder)."""
        rest = self.rest
        return max(rest.band, BAND_SIGMAS * math.sqrt(rest.sigma2))

    def leave_hold(self) -> float:
        """The table is outside the window: the PID acts again (its force, N)."""
        self.law.holding = False
        return self.pid_force()


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
        #: Whether the in-position window is on, and its half-width (m).
        self.window, self.w_band = in_position_window(s, T)
        #: The encoder's count, m.
        self.q = float(s.x_resolution)

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
        #: Side of the target (+1, -1) of the last rest beyond the tolerance (with the
        #: window: beyond it), and reversals.
        self.side = 0.0
        self.reversals = 0
        #: The window holds the force (the integrator frozen), the force held (N), and the
        #: PID's last force (N).
        self.holding = False
        self.u_hold = 0.0
        self.u_last = 0.0
        #: The force is cut while the table coasts into the window, and to what (N).
        self.coasting = False
        self.u_coast = 0.0
        #: The last readings (a ring, m) and how many were put in this maneuver.
        self.ring = [0.0] * NOISE_WINDOW
        self.ring_n = 0
        #: The readings under the force held: anchor (m), sum of their deviations from it
        #: (m), their number, and the number at which the next decision is due.
        self.h_x0 = 0.0
        self.h_sum = 0.0
        self.h_n = 0
        self.h_look = 0

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
                "side": self.side, "reversals": self.reversals, "holding": int(self.holding),
                "u_hold": self.u_hold, "u_last": self.u_last, "ring": list(self.ring),
                "ring_n": self.ring_n, "h_x0": self.h_x0, "h_sum": self.h_sum, "h_n": self.h_n,
                "h_look": self.h_look, "coasting": int(self.coasting), "u_coast": self.u_coast}

    def set_law_state(self, values) -> None:
        super().set_law_state(values)
        self.k, self.integral = int(values["k"]), float(values["integral"])
        self.x_from, self.x_to = float(values["x_from"]), float(values["x_to"])
        self.x_ref_now, self.side = float(values["x_ref_now"]), float(values["side"])
        self.reversals = int(values["reversals"])
        self.holding = bool(values["holding"])
        self.u_hold, self.u_last = float(values["u_hold"]), float(values["u_last"])
        ring = [float(q) for q in values["ring"]]
        if len(ring) != NOISE_WINDOW:
            raise ValueError(f"law.ring holds {len(ring)} numbers, not {NOISE_WINDOW}")
        self.ring, self.ring_n = ring, int(values["ring_n"])
        self.h_x0, self.h_sum = float(values["h_x0"]), float(values["h_sum"])
        self.h_n, self.h_look = int(values["h_n"]), int(values["h_look"])
        self.coasting, self.u_coast = bool(values["coasting"]), float(values["u_coast"])
