"""The pulse sequencer: coarse move, hand-over, pulse and wait, safeguards, outcome.

The sequence within one maneuver:

1. *coarse*: PD feedback with Coulomb feed-forward while the error is outside
   ``e_band`` (or the mass moves); once inside ``e_band`` and slow enough that
   coasting would stop it inside ``e_band`` (``m_est*v**2/(2*f_c_est)``), the
   force is released and friction stops the mass (an overdamped loop that
   creeps would otherwise never read still);
2. once the mass is at rest inside ``e_band``, *pulse* mode: a pulse is planned
   (by the control law), applied for whole samples, and followed by *wait* until
   the mass is at rest again; the displacement from the pulse's start to that
   rest is given to the law;
3. *settled* once the mass is at rest with ``abs(e) <= tolerance``, and, on an encoder of
   count q the law is told (``x_resolution``), with ``abs(e) + q/2 <= tolerance`` (the
   table lies anywhere within q/2 of a still reading; for a tolerance below q/2, at the
   count nearest the target): the output is 0. A controller that gives up (the law
   refuses to plan, the pulse budget is spent, no pulse can bring the mass nearer)
   *stops*: output 0 until the next maneuver. Either way ``outcome`` and
   ``outcome_reason`` say how the maneuver ended
   (:data:`papwc.model.controller_settings.OUTCOMES`, ``OUTCOME_REASONS``).

Rest is read by a :class:`~.rest.RestDetector`. With encoder noise sigma > 0
the sequencer decides on the averaged reading ``x_hat`` at N = D + 1 readings
and then each time N has grown by half: settled once ``|e_hat| + 3*s <=
tolerance`` (``s = sigma/sqrt(N)``); a pulse once ``|e_hat|`` exceeds the
tolerance and ``3*s`` and ``2.5*s`` is below the larger of the tolerance and
``p*|e_hat|``, p the relative error expected of the move (the law's
``precision``, at least 0.01); else it keeps averaging. So with noise it can
resolve errors below the noise, and it never calls settled an error it cannot
tell from one outside the tolerance.

A pulse is judged not to have moved the mass only after ``D + 1`` unchanged
intervals following its last sample, one more than a moving mass needs, so that
a loop which delivers the force one sample late is not mistaken for a pulse that
did not move. The mass is assumed at rest when a maneuver starts.

With ``safeguards`` (the default) the sequencer stops a maneuver after
``max_pulses`` pulses and never fires a pulse whose expected displacement (the law's
``reach``: its model's prediction, or what its evidence says where that knows better)
would leave the mass farther from the target than the maneuver started, even if it
moves 1/trust times that (:class:`~.trust.TrustRegion`, which judges the model's
prediction). On a drive told its mode it also fires none that could leave the table
farther than the maneuver started should the spring give the table all the work the pulse
did on the motor (:meth:`PulseSequencer.drive_slip`, with ``m_d_est`` and ``f_c_est``).

On a machine with a mode, told (``f_mode`` > 0) or seen ringing (a mode the settings did
not name, see :mod:`.rest`), a pulse's move depends on the ringing it meets more than on
its height, so the pulses shrink: one sample each, and once a sample has moved more than
half the runaway bound ``1.5*|e|`` (:data:`RING_MARGIN`), one sample at the law's lowest
height ``f_low`` (the smallest pulse it can make). Its coarse feedback hands over within
:data:`E_BAND_FLEXIBLE` (or ``e_band`` if smaller) instead of ``e_band``, and also where
friction holds the mass against it (stalled, inside ``e_band``): the pulses take over
from there.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Protocol

from ..model.variables import Variable
from .interface import Mode, Outcome, Reason
from .rest import NOISE_DWELL, NOISE_WINDOW, RestDetector
from .settings import ControllerSettings
from .trust import TRUST_MIN, TrustRegion

#: ``m_d_est``: the motor mass of a drive told its mode, read by the sequencer's slip bound
#: (:meth:`PulseSequencer.drive_slip`); every pulse kind lists it among its settings.
M_D_EST = (
    Variable("m_d_est", "Motor mass of the flexible drive (the mode f_mode is that of the "
             "motor on the coupling against the stuck table: k_t = m_d_est*(2*pi*f_mode)**2); "
             "told f_mode, a pulse controller fires no pulse whose work on a motor of this "
             "mass, given back by the spring, could sling the table farther than the maneuver "
             "started", "kg", 50.0, min=1e-6, max=1e9, nominal=10.0)
)


__all__ = ["PRECISION_MIN", "X_LIMIT", "Z_ACT", "Z_DECIDE", "Law", "PulseSequencer"]

#: Largest absolute position read as one, m: beyond it (or NaN) a reading is invalid and the
#: controller stops (its sums of squares stay finite).
X_LIMIT = 1e6
#: Confidence of the decisions on averaged readings (standard errors): settled only with
#: abs(e) + Z_DECIDE*s <= tolerance, a pulse only for abs(e) > Z_DECIDE*s.
Z_DECIDE = 3.0
#: A pulse is planned once the error is known to Z_ACT*s within the tolerance (or within
#: the precision of the pulse).
Z_ACT = 2.5
#: The runaway bound's factor: a pulse should move at most RUNAWAY_FACTOR*abs(e) (plus a count).
RUNAWAY_FACTOR = 1.5
#: On a machine with a mode, a sample may move this many times the most one has moved.
RING_MARGIN = 2.0
#: Largest hand-over band on a machine with a mode (told or seen ringing), m: the coarse
#: feedback brings a long move this near before the pulses take over.
E_BAND_FLEXIBLE = 1.5e-3
#: On a machine with a mode, the coarse feedback has stalled (friction holds the mass
#: against it) once the reading has stayed within STALL_BAND (m) for STALL_SAMPLES samples;
#: inside ``e_band`` the force is then released and the pulses take over.
STALL_BAND = 5e-6
STALL_SAMPLES = 20
#: The error is never asked to be known better than this fraction of it before a pulse
#: (a first move need not land closer than the next can correct).
PRECISION_MIN = 0.01

_O_SETTLED = Outcome.SETTLED
_M_SETTLED = Mode.SETTLED
_M_COARSE = Mode.COARSE
_M_PULSE = Mode.PULSE
_M_WAIT = Mode.WAIT
_NAN = math.nan


class Law(Protocol):
    """What the sequencer asks of its control law (:class:`~.base.PulseControllerBase`)."""

    settings: ControllerSettings
    T: float
    revision: int

    def plan_pulse(self, e: float) -> tuple[int, float]: ...

    def predict(self, n: int, f_p: float) -> float: ...

    def reach(self, n: int, f_p: float) -> float: ...

    def learn(self, n: int, f_p: float, d: float) -> None: ...

    def precision(self, e: float) -> float: ...

    def budget_spent(self) -> bool: ...


class PulseSequencer:
    """Sequencing of one maneuver of a pulse controller (see the module).

    Parameters
    ----------
    law : Law
        The control law: ``plan_pulse``, ``predict``, ``reach``, ``learn``, ``precision``,
        ``budget_spent``.
    rest : RestDetector
        Rest detection of the controller.
    trust : TrustRegion
        Trust region of the controller.

    Attributes
    ----------
    mode : int
        :class:`Mode` code.
    pulses : int
        Pulses started in this maneuver.
    outcome, outcome_reason : int
        :class:`Outcome` and :class:`Reason` codes.
    refusal : int
        Reason code the law sets when it refuses to plan (height 0).
    last_n, last_f : int, float
        Samples and height (N) of the last pulse.
    last_d : float
        Displacement of the last pulse judged, m.
    e0 : float
        Error at the start of the maneuver, m.
    pred : float
        Displacement predicted for the present pulse, m (0: no prediction).
    """

    #: Names of the state (:meth:`state`), in order.
    FIELDS = ("mode", "pulses", "first", "x_prev", "v_hat", "pulse_left", "f_pulse",
              "n_pulse", "x_start", "waited", "last_n", "last_f", "last_d", "outcome",
              "outcome_reason", "stopped", "e0", "released", "pred", "refusal", "stall_x",
              "stall_n")
    _INTS = frozenset(("mode", "pulses", "pulse_left", "n_pulse", "waited", "last_n",
                       "outcome", "outcome_reason", "refusal", "stall_n"))
    _BOOLS = frozenset(("first", "stopped", "released"))

    def __init__(self, law: Law, rest: RestDetector,
                 trust: TrustRegion) -> None:
        self.law = law
        self.rest = rest
        self.trust = trust
        s = law.settings
        self.T = law.T
        self.tolerance = s.tolerance
        self.e_band = s.e_band
        self.f_p_max = s.f_p_max
        self.f_c_est = s.f_c_est
        self.m_est = s.m_est
        self.m_d_est = float(s.m_d_est)
        self.k_p = s.k_p_value
        self.k_d = s.k_d_value
        self.guarded = bool(s.safeguards)
        self.max_pulses = int(s.max_pulses)
        #: Half the encoder's count the law is told (``x_resolution``; 0 for a law that is
        #: not), m: how far from a still reading the table may be.
        self.half_count = 0.5 * float(s.x_resolution)
        self.refusal = Reason.NO_MOVE_HELPS
        self.reset()

    def reset(self) -> None:
        """Start a new maneuver from rest."""
        self.mode = Mode.SETTLED  # at rest; decided anew at the first sample
        self.idle_samples = 0
        self.idle_x = self.idle_ref = math.nan
        self.pulses = 0
        self.first = True
        self.x_prev, self.v_hat = math.nan, 0.0
        # the pulse under way, and the last one (samples, force, displacement)
        self.pulse_left, self.f_pulse, self.n_pulse, self.x_start, self.waited = 0, 0.0, 0, 0.0, 0
        self.last_n, self.last_f, self.last_d = 0, 0.0, 0.0
        self.outcome = Outcome.ACTIVE
        self.outcome_reason = Reason.NONE
        self.stopped = False
        self.e0 = math.nan
        self.released = False
        self.stall_x = 0.0
        self.stall_n = 0
        self.pred = 0.0
        self.rest.reset()

    @property
    def last_pulse(self) -> tuple[int, float]:
        """Samples and height (N) of the last pulse."""
        return self.last_n, self.last_f

    # -- the sample --------------------------------------------------------------------
    def update(self, x_meas: float, x_ref: float) -> float:
        """Force (N) to hold over the next sample, from the reading and reference (m)."""
        if x_meas == self.idle_x and x_ref == self.idle_ref:
            # Settled, and the reading and reference those of the last sample: the
            # sample is only counted (see catch_up).
            self.idle_samples += 1
            return 0.0
        if self.idle_samples:
            self.catch_up()
        if self.stopped:
            return 0.0
        if not (-X_LIMIT <= x_meas <= X_LIMIT and -X_LIMIT <= x_ref <= X_LIMIT):  # also NaN
            return self.stop(Reason.INVALID_MEASUREMENT)
        rest = self.rest
        if (self.outcome == _O_SETTLED and self.mode == _M_SETTLED and x_meas == rest.anchor
                and rest.lo == rest.hi and rest.sigma2 == 0.0
                and rest.n >= rest.dwell and rest.n >= NOISE_DWELL
                and abs(x_ref - x_meas) <= self.tolerance):
            # Settled and the reading unchanged: the steps below would only count it
            # (the same state, the same result, less work), and so would they for every
            # further sample with this reading and reference.
            rest.n += 1
            self.v_hat = 0.0
            self.x_prev = x_meas
            rest.ring[rest.ring_n % NOISE_WINDOW] = x_meas
            rest.ring_n += 1
            self.idle_x = x_meas
            self.idle_ref = x_ref
            return 0.0
        self.idle_x = _NAN
        mode = self.mode
        if self.first:
            at_rest = True
            self.first = False
            self.v_hat = 0.0
            rest.start_run(x_meas)
            self.e0 = x_ref - x_meas
            dx = 0.0
        else:
            dx = x_meas - self.x_prev
            self.v_hat = dx / self.T
            at_rest = rest.read(x_meas, mode != _M_PULSE and (mode != _M_COARSE
                                                              or self.released))
        self.x_prev = x_meas

        if self.pulse_left > 0:
            self.pulse_left -= 1
            return self.f_pulse
        if mode != _M_COARSE or self.released:
            legs = rest.legs
            at_rest = rest.force_free(x_meas, dx, at_rest)
            if rest.legs > legs and self.guarded:
                # ringing seen (rest detection): shrink the pulses from now on
                self.trust.ringing()
        if mode == _M_PULSE:
            self.mode = mode = _M_WAIT
            self.waited = 0
        if mode == _M_WAIT:
            self.waited += 1
            if self.n_pulse > 0:
                # A pulse response moves the mass one way only, so "moved" is read off
                # the present position.
                moved = abs(x_meas - self.x_start) > rest.band
                if not at_rest or (not moved and self.waited <= rest.dwell):
                    return 0.0
                self._pulse_ended(rest.x_hat() - self.x_start)
            elif not at_rest:
                return 0.0
        elif not at_rest:
            if mode == _M_SETTLED:
                return 0.0
            e = x_ref - x_meas
            if self.released:
                return 0.0
            if ((abs(e) <= self.hand_over_band() and self._coasts_inside(e))
                    or self._stalled(x_meas, e)):
                self.released = True
                rest.ring_n = 0
                return 0.0
            return self.coarse(e)

        # At rest: settle, pulse, or coarse feedback.
        return self._decide(x_ref)

    def _pulse_ended(self, d: float) -> None:
        """The pulse's mass is at rest again, d (m) from where the pulse started."""
        law, n, f_p = self.law, self.n_pulse, self.f_pulse
        self.last_d = d
        d_along = d if f_p > 0.0 else -d
        rest = self.rest
        noise = Z_DECIDE * rest.sigma_move()
        self.trust.judge(self.pred, d_along, noise)
        law.learn(n, f_p, d)
        law.revision += 1
        if n == 1 and self.flexible():
            self.trust.d_one = max(self.trust.d_one, abs(d))
        self.n_pulse = 0

    def catch_up(self) -> None:
        """Count the idle samples into the rest (what update would have done for each)."""
        k = self.idle_samples
        self.idle_samples = 0
        self.rest.count_idle(k, self.idle_x)

    # -- decisions at rest ---------------------------------------------------------------
    def _decide(self, x_ref: float) -> float:
        """At rest: settle, keep averaging, pulse or coarse feedback."""
        rest, law = self.rest, self.law
        x_hat = rest.x_hat()
        e = x_ref - x_hat
        tol = self.tolerance
        if rest.sigma2 > 0.0:
            # decisions at N = D + 1 readings, then each time N has grown by half
            look = max(rest.look, rest.dwell + 1)
            if rest.n < look and self.mode in (Mode.WAIT, Mode.SETTLED):
                return 0.0
            while look <= rest.n:
                look = (3 * look + 1) // 2
            rest.look = look
            s = rest.sigma_mean()
            if abs(e) + Z_DECIDE * s <= tol:
                return self.settle()
            if not (abs(e) > max(tol, Z_DECIDE * s)
                    and Z_ACT * s <= max(tol, max(law.precision(e), PRECISION_MIN) * abs(e))):
                if self.mode == Mode.SETTLED and self.outcome == Outcome.SETTLED:
                    return 0.0
                self.mode = Mode.WAIT
                return 0.0
        elif abs(e) <= tol and (abs(e) + self.half_count <= tol or abs(e) <= self.half_count):
            # on an encoder of count q the table lies within q/2 of the reading: settled
            # where that whole range is within the tolerance (or, for a tolerance below q/2,
            # at the count nearest the target, the best the encoder can tell)
            return self.settle()
        if abs(e) > self.e_band or (abs(e) > self.hand_over_band()
                                    and not (self.mode == _M_COARSE
                                             and self.stall_n > STALL_SAMPLES)):
            if self.mode != _M_COARSE:
                self.stall_x = x_hat
                self.stall_n = 0
            elif self._stalled(self.x_prev, e):
                self.released = True
                rest.ring_n = 0
                return 0.0
            self.mode = Mode.COARSE
            self.released = False
            self.outcome = Outcome.ACTIVE
            return self.coarse(x_ref - self.x_prev)
        if self.guarded and law.budget_spent():
            return self.stop(Reason.PULSE_BUDGET)
        self.refusal = Reason.NO_MOVE_HELPS
        n, f_p = law.plan_pulse(e)
        if f_p == 0.0 or not math.isfinite(f_p):
            return self.stop(self.refusal)
        if self.guarded and self.flexible():
            n, f_p = self._ringing_pulse(e, f_p)
        pred = law.predict(n, f_p)
        if self.guarded and (self.may_end_farther(e, f_p, law.reach(n, f_p))
                             or self.may_slip_farther(e, n, f_p)):
            return self.stop(Reason.NO_MOVE_HELPS)
        return self.fire(n, f_p, pred, x_hat)

    def may_end_farther(self, e: float, f_p: float, pred: float) -> bool:
        """Whether a pulse of height f_p (N) predicted to move pred (m) may leave the mass
        farther than the maneuver started (and than now, error e m), should it move 1/trust
        times the prediction: the sequencer does not fire it."""
        if not math.isfinite(pred):
            return False
        step = math.copysign(pred, f_p)
        return self._farther(e, max(abs(e - step), abs(e - step / max(self.trust(), TRUST_MIN))))

    def _farther(self, e: float, after: float) -> bool:
        """Whether an error of ``after`` (m) left by a pulse fired at the error e (m) is
        farther than the maneuver started and than now."""
        return after > abs(self.e0) and after > abs(e)

    def drive_slip(self, n: int, f_p: float) -> float:
        """Farthest a pulse of n samples at f_p (N) can move the table of a drive told its
        mode, m: ``(f_p*n*T)**2/(2*m_d_est*f_c_est)`` (0 on a machine not told one).

        The force does at most the work it would do on the motor alone, ``(f_p*n*T)**2/
        (2*m_d_est)`` (the spring only holds the motor back while the table sticks, the drive
        at rest before the pulse), and the spring gives that back to the table when it breaks
        away: a sliding friction of at least ``f_c_est`` then stops the table within that work
        over ``f_c_est`` (the drive's damping takes its share too). A drive still ringing
        from the last slip holds a few newtons more, a small part of it.
        """
        if not self.trust.flexible or not self.m_d_est > 0.0 or not self.f_c_est > 0.0:
            return 0.0
        work = (f_p * n * self.T) ** 2 / (2.0 * self.m_d_est)
        return work / self.f_c_est

    def may_slip_farther(self, e: float, n: int, f_p: float) -> bool:
        """Whether a pulse of n samples at f_p (N) may leave the table of a drive told its
        mode farther than the maneuver started (and than now, error e m), should the spring
        sling it the whole :meth:`drive_slip`: the sequencer does not fire it."""
        slip = self.drive_slip(n, f_p)
        return slip > 0.0 and self._farther(e, abs(e - math.copysign(slip, f_p)))

    def _ringing_pulse(self, e: float, f_p: float) -> tuple[int, float]:
        """The pulse on a machine seen ringing: one sample; at ``f_low`` once a sample has
        moved more than the runaway bound ``1.5*|e|`` over ``RING_MARGIN`` (N, signed)."""
        f_low = self.law.f_low
        if (RING_MARGIN * self.trust.d_one > RUNAWAY_FACTOR * abs(e)
                and 0.0 < f_low < abs(f_p)):
            f_p = math.copysign(f_low, f_p)
        return 1, f_p

    def fire(self, n: int, f_p: float, pred: float, x_hat: float) -> float:
        """Start the pulse of n samples at f_p (N) predicted to move pred (m) from x_hat (m)."""
        rest = self.rest
        self.pred = pred if math.isfinite(pred) else 0.0
        self.mode = Mode.PULSE
        self.outcome = Outcome.ACTIVE
        self.outcome_reason = Reason.NONE
        self.pulses += 1
        self.n_pulse = n
        self.f_pulse = f_p
        self.pulse_left = n - 1
        self.x_start = x_hat
        # (the rest that ends here is not force-free: it does not update the noise)
        rest.start_run(self.x_prev)
        rest.ring_n = 0
        rest.forget_direction()
        self.last_n, self.last_f = n, f_p
        return f_p

    def settle(self) -> float:
        """Settled: within the tolerance at rest; output 0."""
        self.mode = Mode.SETTLED
        self.outcome = Outcome.SETTLED
        self.outcome_reason = Reason.WITHIN_TOLERANCE
        return 0.0

    def stop(self, reason: int) -> float:
        """Give up for this maneuver: output 0, mode settled, outcome stopped."""
        self.stopped = True
        self.mode = Mode.SETTLED
        self.outcome = Outcome.STOPPED
        self.outcome_reason = int(reason)
        self.pulse_left = 0
        self.f_pulse = 0.0
        return 0.0

    # -- the coarse move ---------------------------------------------------------------
    def coarse(self, e: float) -> float:
        """PD feedback with Coulomb feed-forward, saturated at f_p_max (N)."""
        self.rest.forget_direction()
        u = self.k_p * e - self.k_d * self.v_hat + math.copysign(self.f_c_est, e)
        f_max = self.f_p_max
        return min(max(u, -f_max), f_max)

    def _coasts_inside(self, e: float) -> bool:
        """Whether the mass, coasting from its present speed, stops inside the hand-over band."""
        v = self.v_hat
        d = self.m_est * v * v / (2.0 * self.f_c_est)
        return abs(e - math.copysign(d, v)) <= self.hand_over_band()

    def _stalled(self, x: float, e: float) -> bool:
        """On a machine with a mode, whether the coarse feedback has held the mass within
        :data:`STALL_BAND` of x (m) for :data:`STALL_SAMPLES` samples, inside ``e_band``."""
        if abs(x - self.stall_x) > STALL_BAND:
            self.stall_x = x
            self.stall_n = 0
            return False
        self.stall_n += 1
        return (self.stall_n > STALL_SAMPLES and abs(e) <= self.e_band and self.guarded
                and self.flexible())

    def flexible(self) -> bool:
        """Whether the machine has a mode: told (``f_mode`` > 0) or seen ringing."""
        return self.trust.flexible or self.trust.ring

    def hand_over_band(self) -> float:
        """Error band of the hand-over from coarse feedback to pulses, m: ``e_band``, and on a
        machine with a mode at most :data:`E_BAND_FLEXIBLE`."""
        if self.guarded and self.flexible():
            return min(self.e_band, E_BAND_FLEXIBLE)
        return self.e_band

    # -- state -------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The state by name (:attr:`FIELDS`): numbers (flags as 0 or 1)."""
        if self.idle_samples:
            self.catch_up()
        bools = self._BOOLS
        return {name: int(getattr(self, name)) if name in bools else getattr(self, name)
                for name in self.FIELDS}

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state`."""
        self.idle_samples = 0
        self.idle_x = self.idle_ref = math.nan
        for name in self.FIELDS:
            value = values[name]
            if name in self._INTS:
                value = int(value)
            elif name in self._BOOLS:
                value = bool(value)
            else:
                value = float(value)
            setattr(self, name, value)
