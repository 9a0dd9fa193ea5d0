"""The controller interface and the pulse sequencing all pulse controllers share.

A controller sees what a real one sees: the time and the measured position
(an encoder), never the velocity nor the plant's stuck flag. At every sample it
returns the force to hold over the next sample (zero-order hold).

The sequence within one maneuver:

1. *coarse*: PD feedback with Coulomb feed-forward while the error is outside
   ``e_band`` (or the mass moves); once inside ``e_band`` and slow enough that
   coasting would stop it inside ``e_band`` (``m_est*v**2/(2*f_c_est)``), the
   force is released and friction stops the mass (an overdamped loop that
   creeps would otherwise never read still);
2. once the mass is at rest inside ``e_band``, *pulse* mode: a pulse is planned
   (subclass), applied for whole samples, and followed by *wait* until the
   mass is at rest again; the displacement from the pulse's start to that rest
   is given to the estimator (subclass);
3. *settled* once the mass is at rest with ``|e| <= tolerance``: the output is
   0. A controller that gives up (a subclass refuses to plan, the pulse budget
   is spent, no pulse can bring the mass nearer) *stops*: output 0 until the
   next maneuver. Either way :attr:`Controller.outcome` and
   :attr:`Controller.outcome_reason` say how the maneuver ended
   (:data:`papwc.model.settings.OUTCOMES`, ``OUTCOME_REASONS``).

Rest is read from the measured position alone: at rest means it has stayed
within a band of width B over a dwell of D sample intervals. B and D are
``rest_band`` and ``rest_samples`` (0 and 1 by default: exactly unchanged over
one interval); with ``rest_auto`` they grow to ``6*sigma`` and 5 samples once
encoder noise sigma has been measured, and D to 2.5 periods of ``f_mode``. The
noise sigma is estimated from samples at rest: from the spread of the readings
over each rest, and, before any rest could be seen, from force-free windows of
16 readings whose net drift is within 3 times their sample-to-sample scatter
(a moving mass drifts by more). With an ideal, noiseless encoder the readings
at rest are equal, sigma stays 0 and the test is the one of rest_band and
rest_samples.

While at rest the readings are averaged: the controller acts on the mean
``x_hat`` of the readings since the rest began, whose uncertainty is
``s = sigma/sqrt(N)``. With sigma > 0 it decides at N = D + 1 and then each
time N has grown by half: settled once ``|e_hat| + 3*s <= tolerance``; a
pulse once ``|e_hat|`` exceeds the tolerance and ``3*s`` (the error is known
not to be 0) and ``2.5*s`` is
below the larger of the tolerance and ``p*|e_hat|``, p the relative error
expected of the move (:meth:`Controller.precision`, 0.1 unless the controller
knows better; at least 0.01); else it keeps averaging. So
with noise it can resolve errors below the noise, and it never calls settled
an error it cannot tell from one outside the tolerance.

A pulse is judged not to have moved the mass only after ``D + 1`` unchanged
intervals following its last sample, one more than a moving mass needs, so that
a loop which delivers the force one sample late (a co-simulation master
stepping plant and controller side by side) is not mistaken for a pulse that
did not move. The mass is assumed at rest when a maneuver starts.

With ``safeguards`` (the default) the base also stops a maneuver after
``max_pulses`` pulses and never fires a pulse whose predicted displacement
(:meth:`Controller.predict`) would leave the mass farther from the target than
the maneuver started; subclasses keep their pulses inside a trust region
(:meth:`Controller.trust`): the displacement they plan is at most
``trust*|e|``, where ``trust`` (<= 1) shrinks when pulses moved more than
predicted and grows back while they move as predicted.
"""

from __future__ import annotations

import math

from ..model.settings import MODE_PERIODS, OUTCOME_REASONS, OUTCOMES
from .settings import ControllerSettings

#: Largest |position| read as one, m: beyond it (or NaN) a reading is invalid and the
#: controller stops (its sums of squares stay finite).
X_LIMIT = 1e6

#: Readings of the force-free window in which noise is looked for before any rest.
NOISE_WINDOW = 16
#: Largest net drift of that window, in units of sqrt(2)*sigma of its scatter.
NOISE_DRIFT = 3.0
#: Band of rest detection in units of the measured noise.
BAND_SIGMAS = 6.0
#: Dwell of rest detection with measured noise, sample intervals.
NOISE_DWELL = 5
#: Confidence of the decisions on averaged readings (standard errors): settled only with
#: |e| + Z_DECIDE*s <= tolerance, a pulse only for |e| > Z_DECIDE*s.
Z_DECIDE = 3.0
#: A pulse is planned once the error is known to Z_ACT*s within the tolerance (or within
#: the precision of the pulse).
Z_ACT = 2.5
#: Rests over which the noise estimate is averaged (a running mean over at most this many).
NOISE_MEMORY = 16
#: The error is never asked to be known better than this fraction of it before a pulse
#: (a first move need not land closer than the next can correct).
PRECISION_MIN = 0.01
#: Factor by which the trust region grows after a pulse that moved as predicted.
TRUST_GROWTH = 2.0
#: Relative prediction error up to which a pulse counts as predicted well.
TRUST_GOOD = 0.2
#: Smallest trust.
TRUST_MIN = 0.05
#: Largest trust on a machine with a known mode (f_mode > 0).
TRUST_FLEXIBLE = 0.5


class Mode:
    """Mode codes (the controller FMU's ``mode`` output)."""

    COARSE = 0
    PULSE = 1
    WAIT = 2
    SETTLED = 3
    NAMES = {0: "coarse", 1: "pulse", 2: "wait", 3: "settled"}


class Outcome:
    """Outcome codes (the controller FMU's ``outcome`` output), :data:`OUTCOMES`."""

    ACTIVE = OUTCOMES.index("active")
    SETTLED = OUTCOMES.index("settled")
    STOPPED = OUTCOMES.index("stopped")


class Reason:
    """Reason codes (the controller FMU's ``outcome_reason`` output), :data:`OUTCOME_REASONS`."""

    NONE = 0
    WITHIN_TOLERANCE = OUTCOME_REASONS.index("within_tolerance")
    NO_MOVE_HELPS = OUTCOME_REASONS.index("no_move_helps")
    PULSE_BUDGET = OUTCOME_REASONS.index("pulse_budget")
    MODEL_REJECTED = OUTCOME_REASONS.index("model_rejected")
    TIME_ENDED = OUTCOME_REASONS.index("time_ended")
    INVALID_MEASUREMENT = OUTCOME_REASONS.index("invalid_measurement")
    CANNOT_MOVE = OUTCOME_REASONS.index("cannot_move")


_O_SETTLED = Outcome.SETTLED
_M_SETTLED = Mode.SETTLED
_M_COARSE = Mode.COARSE
_M_PULSE = Mode.PULSE
_M_WAIT = Mode.WAIT
_NAN = math.nan


class Controller:
    """Base of the pulse controllers: coarse feedback, hand-over and pulse sequencing.

    Subclasses implement :meth:`plan_pulse` and :meth:`learn`, may predict a
    pulse's displacement (:meth:`predict`) and add observables in
    :meth:`estimates`. A subclass refuses to plan by returning a height of 0
    with :attr:`refusal` set to a reason code; the controller then stops.

    Parameters
    ----------
    settings : ControllerSettings
        The controller's settings (validated by the caller).
    T : float
        Sample period, s.
    """

    kind = "base"

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        self.settings = settings
        self.T = float(T)
        # Largest pulse width in whole samples (t_p_max rounded down, at least one).
        if math.isinf(settings.t_p_max):
            self.n_max = 1 << 30
        else:
            self.n_max = max(1, int(math.floor(settings.t_p_max / self.T + 1e-9)))
        self.f_p_floor = settings.f_p_floor0
        self.k_p = settings.k_p_value
        self.k_d = settings.k_d_value
        self.guarded = bool(settings.safeguards)
        self._rest_auto = bool(settings.rest_auto)
        self.max_pulses = int(settings.max_pulses)
        # Dwell from the slowest mode: MODE_PERIODS periods, in whole samples.
        f_mode = float(settings.f_mode)
        self.mode_samples = (int(math.ceil(MODE_PERIODS / (f_mode * self.T) - 1e-9))
                             if f_mode > 0.0 else 0)
        #: Incremented whenever the estimates may have changed (an observer re-reads
        #: :meth:`estimates` only then).
        self.revision = 0
        #: Encoder noise measured at rest: variance (m**2) and the rests it is averaged over.
        self.sigma2 = 0.0
        self.noise_rests = 0
        #: Trust region: the largest planned displacement as a fraction of |e|.
        self.trust_value = 1.0
        #: Reason code set by a subclass that refuses to plan (height 0).
        self.refusal = Reason.NO_MOVE_HELPS
        self._update_rest_test()
        self.reset()

    # -- the interface -----------------------------------------------------------------
    def reset(self) -> None:
        """Start a new maneuver from rest; learned estimates are kept."""
        self.mode = Mode.SETTLED  # at rest; decided anew at the first sample
        #: Samples only counted since the state was last brought up to date (see update).
        self.idle_samples = 0
        self._idle_x = self._idle_ref = math.nan
        self.pulses = 0
        self._first = True
        self._x_prev = math.nan
        self._v_hat = 0.0
        self._pulse_left = 0
        self._f_pulse = 0.0
        self._n_pulse = 0
        self._x_start = 0.0
        self._waited = 0
        self.last_pulse: tuple[int, float] = (0, 0.0)
        self.last_d = 0.0
        self.outcome = Outcome.ACTIVE
        self.outcome_reason = Reason.NONE
        self._stopped = False
        self._e0 = math.nan
        self._released = False
        self._pred = 0.0
        # The present run of readings within the band: first reading, extremes, sums.
        self._anchor = math.nan
        self._lo = self._hi = 0.0
        self._sum = self._sum2 = 0.0
        self._n = 0
        self._look = 0
        # Force-free readings for the noise test (a ring), and how many are in it.
        self._ring = [0.0] * NOISE_WINDOW
        self._ring_n = 0
        # Direction of the last force-free change of the reading, and how often it turned.
        self._dir = 0.0
        self._turns = 0

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force to hold over the next sample.

        Parameters
        ----------
        t : float
            Time of the sample, s.
        x_meas : float
            Measured position, m.
        x_ref : float
            Reference position, m.

        Returns
        -------
        float
            Force u, N, held until the next sample.
        """
        if x_meas == self._idle_x and x_ref == self._idle_ref:
            # Settled, and the reading and reference those of the last sample: the
            # sample is only counted (see _catch_up).
            self.idle_samples += 1
            return 0.0
        if self.idle_samples:
            self._catch_up()
        if self._stopped:
            return 0.0
        if not (-X_LIMIT <= x_meas <= X_LIMIT and -X_LIMIT <= x_ref <= X_LIMIT):  # also NaN
            return self._stop(Reason.INVALID_MEASUREMENT)
        if (self.outcome == _O_SETTLED and self.mode == _M_SETTLED and x_meas == self._anchor
                and self._lo == self._hi and self.sigma2 == 0.0
                and self._n >= self._dwell and self._n >= NOISE_DWELL
                and abs(x_ref - x_meas) <= self.settings.tolerance):
            # Settled and the reading unchanged: the steps below would only count it
            # (the same state, the same result, less work), and so would they for every
            # further sample with this reading and reference.
            self._n += 1
            self._v_hat = 0.0
            self._x_prev = x_meas
            self._ring[self._ring_n % NOISE_WINDOW] = x_meas
            self._ring_n += 1
            self._idle_x = x_meas
            self._idle_ref = x_ref
            return 0.0
        self._idle_x = _NAN
        if self._first:
            at_rest = True
            self._first = False
            self._v_hat = 0.0
            self._start_run(x_meas)
            self._e0 = x_ref - x_meas
            dx = 0.0
        else:
            dx = x_meas - self._x_prev
            self._v_hat = dx / self.T
            lo, hi = self._lo, self._hi
            if x_meas == self._anchor and lo == hi:  # the reading unchanged
                self._n += 1
                at_rest = self._n > self._dwell
            else:
                # The run of readings within the band grows, or a new one starts here.
                if x_meas < lo:
                    lo = x_meas
                if x_meas > hi:
                    hi = x_meas
                if hi - lo > self._band:
                    if self._n > NOISE_DWELL and self._sum2 > 0.0:
                        self._end_run()
                    self._start_run(x_meas)
                    at_rest = False
                else:
                    self._lo, self._hi = lo, hi
                    dev = x_meas - self._anchor
                    self._sum += dev
                    self._sum2 += dev * dev
                    self._n += 1
                    at_rest = self._n > self._dwell
        self._x_prev = x_meas

        if self._pulse_left > 0:
            self._pulse_left -= 1
            return self._f_pulse
        mode = self.mode
        if mode != _M_COARSE or self._released:
            # Force-free: a mass moves one way only, so readings that turn back twice show
            # noise (or a vibration); until the noise is measured, equal readings show a
            # rest only when many in a row are.
            self._ring[self._ring_n % NOISE_WINDOW] = x_meas
            self._ring_n += 1
            if dx != 0.0:
                if dx * self._dir < 0.0:
                    self._turns += 1
                self._dir = dx
            if self._rest_auto:
                if at_rest and self._turns >= 2 and self.sigma2 == 0.0:
                    # noise makes equal readings by chance, not many in a row
                    at_rest = self._n > NOISE_DWELL and self._lo == self._hi
                if not at_rest and self._ring_n >= NOISE_WINDOW:
                    at_rest = self._quiet_window()
        if mode == _M_PULSE:
            self.mode = mode = _M_WAIT
            self._waited = 0
        if mode == _M_WAIT:
            self._waited += 1
            if self._n_pulse > 0:
                # A pulse response moves the mass one way only, so "moved" is read off
                # the present position.
                moved = abs(x_meas - self._x_start) > self._band
                if not at_rest or (not moved and self._waited <= self._dwell):
                    return 0.0
                d = self._x_hat() - self._x_start
                self.last_d = d
                self._judge(self._n_pulse, self._f_pulse, d)
                self.learn(self._n_pulse, self._f_pulse, d)
                self.revision += 1
                self._n_pulse = 0
            elif not at_rest:
                return 0.0
        elif not at_rest:
            if mode == _M_SETTLED:
                return 0.0
            e = x_ref - x_meas
            if self._released:
                return 0.0
            if abs(e) <= self.settings.e_band and self._coasts_inside(e):
                self._released = True
                self._ring_n = 0
                return 0.0
            return self._coarse(e)

        # At rest: settle, pulse, or coarse feedback.
        return self._decide(x_ref)

    def _catch_up(self) -> None:
        """Count the idle samples into the rest (what update would have done for each)."""
        k, x = self.idle_samples, self._idle_x
        self.idle_samples = 0
        self._n += k
        ring, start = self._ring, self._ring_n
        for i in range(min(k, NOISE_WINDOW)):
            ring[(start + i) % NOISE_WINDOW] = x
        self._ring_n = start + k

    def estimates(self) -> dict[str, float]:
        """Current estimates for recording: at least ``b_hat`` (m/s**2) and ``f_c_hat`` (N)."""
        return {"b_hat": math.nan, "f_c_hat": math.nan}

    # -- to implement ------------------------------------------------------------------
    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Pulse for error ``e`` (m): width in samples (>= 1) and signed height (N).

        A height of 0 refuses: the controller stops with the reason :attr:`refusal`.
        """
        raise NotImplementedError

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Take the displacement ``d`` (m) of the pulse (``n`` samples, ``f_p`` N)."""
        raise NotImplementedError

    def predict(self, n: int, f_p: float) -> float:
        """Displacement (m, >= 0, along f_p) the model predicts for the pulse; NaN: no model."""
        return math.nan

    @property
    def f_low(self) -> float:
        """Lowest pulse height it plans with now, N: one sample at it is its smallest pulse."""
        return min(self.f_p_floor, self.settings.f_p_max)

    def precision(self, e: float) -> float:
        """Relative error expected of the move for error e (m): how exactly e need be known."""
        return 0.1

    # -- trust region ------------------------------------------------------------------
    def trust(self) -> float:
        """The trust region: the largest planned displacement as a fraction of |e| (<= 1).

        On a machine with a known mode (``f_mode > 0``) at most ``TRUST_FLEXIBLE``: a drive
        still ringing from the last pulse adds to the next one what no model predicts.
        """
        if not self.guarded:
            return 1.0
        return min(self.trust_value, TRUST_FLEXIBLE) if self.mode_samples else self.trust_value

    def _judge(self, n: int, f_p: float, d: float) -> None:
        """Compare a pulse's displacement with what was predicted; adjust the trust region.

        The trust doubles (up to 1) after a pulse that moved within ``TRUST_GOOD``
        (relative) of the prediction, and otherwise becomes at most
        ``1.2/(1 + r)`` of its value for a pulse that moved ``1 + r`` times the
        prediction (never below ``TRUST_MIN``).
        """
        pred = self._pred
        if not (pred > 0.0 and math.isfinite(pred)):
            return
        d_along = d if f_p > 0.0 else -d
        noise = Z_DECIDE * math.sqrt(2.0 * self.sigma2 / max(self._dwell + 1, 1))
        err = abs(d_along - pred) - noise
        r = max(err, 0.0) / pred
        if r <= TRUST_GOOD:
            self.trust_value = min(1.0, self.trust_value * TRUST_GROWTH)
        elif d_along > pred:
            self.trust_value = max(TRUST_MIN, min(self.trust_value,
                                                  1.2 * pred / max(d_along, 1e-300)))

    # -- rest detection ----------------------------------------------------------------
    def _update_rest_test(self) -> None:
        """Band (m) and dwell (sample intervals) from the settings and what was measured."""
        s = self.settings
        band, dwell = float(s.rest_band), int(s.rest_samples)
        if self._rest_auto:
            if self.sigma2 > 0.0:
                band = max(band, BAND_SIGMAS * math.sqrt(self.sigma2))
                dwell = max(dwell, NOISE_DWELL)
            dwell = max(dwell, self.mode_samples)
        self._band, self._dwell = band, dwell

    def _start_run(self, x: float) -> None:
        self._anchor = x
        self._lo = self._hi = x
        self._sum = self._sum2 = 0.0
        self._n = 1
        self._look = 0

    def _x_hat(self) -> float:
        """Mean of the readings of the present run (the position at rest), m."""
        if self._sum == 0.0:
            return self._anchor
        return self._anchor + self._sum / self._n

    def _end_run(self) -> None:
        """A run of readings ends: if it was a rest, its spread updates the noise estimate."""
        n = self._n
        if (n > NOISE_DWELL and self._sum2 > 0.0 and self._rest_auto
                and self.mode != Mode.PULSE and (self.mode != Mode.COARSE or self._released)):
            mean = self._sum / n
            var = max(self._sum2 / n - mean * mean, 0.0) * n / (n - 1)
            self._add_noise(var)

    def _add_noise(self, var: float) -> None:
        self.noise_rests = min(self.noise_rests + 1, NOISE_MEMORY)
        self.sigma2 += (var - self.sigma2) / self.noise_rests
        self._update_rest_test()

    def _quiet_window(self) -> bool:
        """The last force-free readings drift no more than their scatter: noise, at rest.

        If so, their scatter becomes (part of) the noise estimate and the run of
        readings restarts with the present one, so that the wider band applies.
        """
        ring, k = self._ring, self._ring_n
        first = ring[k % NOISE_WINDOW]
        last = ring[(k - 1) % NOISE_WINDOW]
        s2 = 0.0
        prev = first
        for i in range(1, NOISE_WINDOW):
            x = ring[(k + i) % NOISE_WINDOW]
            s2 += (x - prev) ** 2
            prev = x
        if not s2 > 0.0:
            return False
        var = s2 / (2.0 * (NOISE_WINDOW - 1))
        if abs(last - first) > NOISE_DRIFT * math.sqrt(2.0 * var):
            return False
        self._add_noise(var)
        # the window's readings are the present rest
        self._anchor = first
        self._lo, self._hi = min(ring), max(ring)
        self._sum = sum(x - first for x in ring)
        self._sum2 = sum((x - first) ** 2 for x in ring)
        self._n = NOISE_WINDOW
        self._look = 0
        self._ring_n = 0
        return True

    # -- decisions at rest ---------------------------------------------------------------
    def _decide(self, x_ref: float) -> float:
        """At rest: settle, keep averaging, pulse or coarse feedback."""
        x_hat = self._x_hat()
        e = x_ref - x_hat
        tol = self.settings.tolerance
        if self.sigma2 > 0.0:
            # decisions at N = D + 1 readings, then each time N has grown by half
            look = max(self._look, self._dwell + 1)
            if self._n < look and self.mode in (Mode.WAIT, Mode.SETTLED):
                return 0.0
            while look <= self._n:
                look = (3 * look + 1) // 2
            self._look = look
            s = math.sqrt(self.sigma2 / self._n)
            if abs(e) + Z_DECIDE * s <= tol:
                return self._settle()
            if not (abs(e) > max(tol, Z_DECIDE * s)
                    and Z_ACT * s <= max(tol, max(self.precision(e), PRECISION_MIN) * abs(e))):
                if self.mode == Mode.SETTLED and self.outcome == Outcome.SETTLED:
                    return 0.0
                self.mode = Mode.WAIT
                return 0.0
        elif abs(e) <= tol:
            return self._settle()
        if abs(e) > self.settings.e_band:
            self.mode = Mode.COARSE
            self._released = False
            self.outcome = Outcome.ACTIVE
            return self._coarse(x_ref - self._x_prev)
        if self.guarded and self.pulses >= self.max_pulses:
            return self._stop(Reason.PULSE_BUDGET)
        self.refusal = Reason.NO_MOVE_HELPS
        n, f_p = self.plan_pulse(e)
        if f_p == 0.0 or not math.isfinite(f_p):
            return self._stop(self.refusal)
        pred = self.predict(n, f_p)
        if self.guarded and math.isfinite(pred):
            # The pulse must not leave the mass farther than the maneuver started, even if
            # it moves 1/trust times the prediction (trust: see _judge).
            step = math.copysign(pred, f_p)
            after = max(abs(e - step), abs(e - step / max(self.trust(), TRUST_MIN)))
            if after > abs(self._e0) and after > abs(e):
                return self._stop(Reason.NO_MOVE_HELPS)
        self._pred = pred if math.isfinite(pred) else 0.0
        self.mode = Mode.PULSE
        self.outcome = Outcome.ACTIVE
        self.outcome_reason = Reason.NONE
        self.pulses += 1
        self._n_pulse = n
        self._f_pulse = f_p
        self._pulse_left = n - 1
        self._x_start = x_hat
        self._end_run()
        self._start_run(self._x_prev)
        self._ring_n = 0
        self._dir = 0.0
        self._turns = 0
        self.last_pulse = (n, f_p)
        return f_p

    def _settle(self) -> float:
        self.mode = Mode.SETTLED
        self.outcome = Outcome.SETTLED
        self.outcome_reason = Reason.WITHIN_TOLERANCE
        return 0.0

    def _stop(self, reason: int) -> float:
        """Give up for this maneuver: output 0, mode settled, outcome stopped."""
        self._stopped = True
        self.mode = Mode.SETTLED
        self.outcome = Outcome.STOPPED
        self.outcome_reason = int(reason)
        self._pulse_left = 0
        self._f_pulse = 0.0
        return 0.0

    def _coasts_inside(self, e: float) -> bool:
        """Whether the mass, coasting from its present speed, stops inside ``e_band``."""
        v = self._v_hat
        d = self.settings.m_est * v * v / (2.0 * self.settings.f_c_est)
        return abs(e - math.copysign(d, v)) <= self.settings.e_band

    # -- state -------------------------------------------------------------------------
    def state(self) -> list[float]:
        """Everything that evolves, as a flat list of floats (FMU state, serialization)."""
        if self.idle_samples:
            self._catch_up()
        return [
            float(self.mode), float(self.pulses), float(self._first), self._x_prev,
            float(self._pulse_left), self._f_pulse, float(self._n_pulse),
            self._x_start, float(self.last_pulse[0]), self.last_pulse[1], self.last_d,
            self.f_p_floor, self._v_hat, float(self._waited),
            float(self.outcome), float(self.outcome_reason), float(self._stopped), self._e0,
            float(self._released), self._pred, self.sigma2, float(self.noise_rests),
            self.trust_value, float(self.refusal), self._anchor, self._lo, self._hi,
            self._sum, self._sum2, float(self._n), float(self._look), float(self._ring_n),
            self._dir, float(self._turns), *self._ring,
        ]  # fmt: skip

    def set_state(self, values: list[float]) -> None:
        """Restore a state returned by :meth:`state`."""
        self.revision += 1  # the estimates (and f_low) may differ
        self.idle_samples = 0
        self._idle_x = self._idle_ref = math.nan
        v = [float(q) for q in values]
        self.mode, self.pulses, self._first = int(v[0]), int(v[1]), bool(v[2])
        self._x_prev, self._pulse_left = v[3], int(v[4])
        self._f_pulse, self._n_pulse, self._x_start = v[5], int(v[6]), v[7]
        self.last_pulse = (int(v[8]), v[9])
        self.last_d, self.f_p_floor, self._v_hat = v[10], v[11], v[12]
        self._waited = int(v[13])
        self.outcome, self.outcome_reason = int(v[14]), int(v[15])
        self._stopped, self._e0, self._released = bool(v[16]), v[17], bool(v[18])
        self._pred, self.sigma2, self.noise_rests = v[19], v[20], int(v[21])
        self.trust_value, self.refusal = v[22], int(v[23])
        self._anchor, self._lo, self._hi, self._sum, self._sum2 = v[24:29]
        self._n, self._look, self._ring_n = int(v[29]), int(v[30]), int(v[31])
        self._dir, self._turns = v[32], int(v[33])
        self._ring = v[34:34 + NOISE_WINDOW]
        self._update_rest_test()

    # -- shared pieces -----------------------------------------------------------------
    def _coarse(self, e: float) -> float:
        """PD feedback with Coulomb feed-forward, saturated at f_p_max (N)."""
        self._dir = 0.0
        self._turns = 0
        u = self.k_p * e - self.k_d * self._v_hat + math.copysign(self.settings.f_c_est, e)
        f_max = self.settings.f_p_max
        return min(max(u, -f_max), f_max)

    def width_samples(self, t_p: float) -> int:
        """Pulse width t_p (s) rounded up to whole samples, within [1, n_max]."""
        n_max = self.n_max
        if not math.isfinite(t_p):
            return n_max
        n = math.ceil(t_p / self.T - 1e-9)
        return 1 if n < 1 else n_max if n > n_max else n
