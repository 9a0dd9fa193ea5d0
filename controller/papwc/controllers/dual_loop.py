"""Dual-loop pulse control of a flexible drive: a motor-side loop between pulses.

On a drive whose motor (mass m_d) pushes the table through a spring (stiffness k_t,
damping c_t), a pulse leaves the drive ringing; a pulse started from a ringing drive
moves the table by an amount its height and width do not decide. This controller
reads both encoders -- the table's ``x_meas`` and the motor's ``x_d_meas`` -- and

* checks its drive model against the motor encoder before it acts on it
  (:class:`~.drive_check.DriveCheck`): at its first sample a probe of :data:`PROBE_SHARE`
  times ``f_c_est`` on the motor (the spring's first peak, at most twice that, stays below
  the friction that holds the table); the readings give the delay of the force (0, or 1
  for a master stepping plant and controller side by side), the mode of the free ringing
  and the motor mass its amplitude implies. A mode told (``f_mode``) or a mass told
  (``m_d_est``) that the ringing contradicts, or no ringing within :data:`PROBE_WAIT_S`, is
  refused: every maneuver stops ``model_rejected``, the table not moved; a motor encoder
  that does not follow the probe, ``invalid_measurement``. Otherwise the motor loop is
  built on the mode seen;
* between pulses, once the table is stuck, runs a *motor loop*
  (:class:`~.motor_loop.MotorLoop`): state feedback on the spring deflection delta = x_d - x
  and its rate that brings both to zero (poles at :data:`LOOP_POLE`; the rate from a
  two-reading estimator on the same model; with a delay, on the state the force already
  sent leaves). A loop that feeds the drive (its ringing grown to :data:`LOOP_GROWTH`
  times what it took over) or moves the table (beyond what the drive's energy explains,
  and the rest band or :data:`LOOP_SLIP`) stops the controller for good
  (``model_rejected``, 0 N); so does a drive that does not relax within
  :data:`RELAX_MAX_S`;
* plans its pulses as the exact-model controller does
  (:class:`papwc.controllers.exact.ExactController`), on the rest detection of a rigid
  table, and fires a plan only within the runaway bound ``1.5*abs(e) + x_resolution``
  (:meth:`DualLoopController.plan_pulse`): no pulse away from the target, each
  prediction times the largest recent move/prediction of its width class within the bound,
  wide pulses stopped short for a one-sample landing planned on the recent one-sample moves
  (:class:`~.move_curve.MoveCurve`), a staircase where nothing is known;
* applies a pulse of n samples at height f_p as n samples of f_p on the motor (one
  sample: f_p/(2*sin(omega*T/2)), the motor force whose spring's first peak pushes
  the table with f_p, at most ``f_p_max``), then no force until that peak
  (``ceil(1/(4*f_mode*T) - 1/2)`` samples and the delay) and on while the table's reading
  still moves (by more than the rest band), then the motor loop;
* gives the sequencer a sample only while a pulse is being applied or the drive
  is *relaxed*: the deflection's amplitude k_t*sqrt(delta**2 + (delta'/omega)**2)
  at most ``f_relax`` on :data:`RELAX_SAMPLES` readings in a row. So a pulse
  starts, a pulse's move is read and the maneuver settles only from a relaxed
  drive; settled, the force is 0.

The drive model is the mode frequency ``f_mode`` (Hz, of the motor on the spring
against the stuck table: omega = 2*pi*f_mode = sqrt(k_t/m_d)), the motor mass
``m_d_est`` (kg) and ``c_t_est`` (N.s/m). A loop sampled at T can damp such a mode only
well below the Nyquist frequency: ``f_mode`` must lie in [0, :data:`F_MODE_MAX_T`/T] (the
settings refuse others). With ``f_mode`` = 0 and without ``identify_mode`` there is no
motor loop: the controller is the exact-model controller on the table's encoder. With
``f_mode`` = 0 and ``identify_mode`` the probe identifies the mode (within 0.25/T) instead
of checking one; without one (the motor encoder not connected, a rigid drive) it goes on
on the table's encoder alone, and takes any later free ringing of a stuck table into the
fit.

The host sets :attr:`DualLoopController.x_d_meas` (m) before each
:meth:`~DualLoopController.update` (the controller slave and PulseController.fmu
do, from their input ``x_d_meas``); a reading that is not finite stops it with
``invalid_measurement``, and so does a motor reading that does not follow a pulse's
first force (less than :data:`~.drive_check.MOTOR_FOLLOWS` of the motor's move on the
model: the encoder disconnected), before the loop acts on it.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from ..model.controller_settings import F_MODE_MAX_T
from ..model.pulse import bisect_increasing
from ..model.variables import Variable
from .drive_check import MOTOR_FOLLOWS, DriveCheck
from .exact import EXACT_SETTINGS, ExactController
from .interface import Mode, Outcome, Reason
from .mode_id import ModeIdentifier
from .motor_loop import LOOP_POLE, MotorLoop
from .move_curve import MoveCurve
from .sequencer import M_D_EST, RUNAWAY_FACTOR, X_LIMIT
from .settings import ControllerSettings
from .trust import TrustRegion

#: The settings the dual-loop controller reads besides the shared ones, the exact-model
#: controller's and ``m_d_est``.
DUAL_LOOP_SETTINGS: tuple[Variable, ...] = (
    Variable("c_t_est", "Damping of the motor-table coupling the motor loop is designed with",
             "N.s/m", 0.0, min=0.0, max=1e9, nominal=100.0),
    Variable("f_relax", "Largest force amplitude of the drive's ringing, k_t*sqrt(delta**2 + "
             "(delta'/(2*pi*f_mode))**2) with delta = x_d_meas - x_meas, at which the drive "
             "counts as relaxed (a pulse starts, a move is read, the maneuver settles only "
             "from a relaxed drive)", "N", 2.0, min=0.0, min_open=True, max=1e9,
             nominal=1.0),
    Variable("identify_mode", "With f_mode = 0: identify the drive's mode from the motor "
             "encoder's free ringing (x_d_meas - x_meas while the table sticks) after a probe "
             "(one sample of 0.4*f_c_est on the motor at the first sample, which friction "
             "holds the table against) and build the motor loop on it, with m_d_est and "
             "c_t_est; the table's encoder alone until then, and for good if no ringing "
             "within 0.5 s or a mode above 0.25/T. False: f_mode = 0 means no motor loop",
             "", False,
             type="Boolean"),
)


__all__ = ["CappedTrust", "DualLoopController", "MotorLoop", "CURVE_EXTEND", "F_MODE_MAX_T",
           "JUMP_STEP", "KEEP_RATIOS", "LAND_FACTOR", "LAND_PRIOR", "LOOP_GROWTH", "LOOP_POLE",
           "LOOP_REFERENCE", "LOOP_SLIP", "LOWER_TOL", "PROBE_SHARE", "PROBE_WAIT_S", "RATIO_PRIOR",
           "RATIO_WIDTHS", "RELAX_SAMPLES"]

#: Readings in a row within ``f_relax`` for the drive to count as relaxed.
RELAX_SAMPLES = 3
#: Longest the drive may take to relax, s: beyond it the controller stops.
RELAX_MAX_S = 1.0
#: The probe of the mode's identification: one sample of this share of ``f_c_est``...
PROBE_SHARE = 0.4
#: ... and the longest wait for the ringing to identify, s.
PROBE_WAIT_S = 0.5
#: Moves over predictions kept per width class of pulse, newest last...
KEEP_RATIOS = 8
#: ... the classes: the pulses of at least this many samples and fewer than the next...
RATIO_WIDTHS = (1, 2, 3, 4, 8)
#: ... and the factor a pulse's prediction is taken to be exceeded by before any is kept.
RATIO_PRIOR = 2.0
#: A one-sample pulse planned on the recent moves moves at most this many times the
#: farthest of them.
CURVE_EXTEND = 2.0
#: Relative width to which a one-sample height is lowered to its bound.
LOWER_TOL = 1e-6
#: A pulse wider than one sample stops this many times the shortest recent one-sample move
#: short of the target.
LAND_FACTOR = 2.0
#: ... and, before any moved, this share of the error short.
LAND_PRIOR = 0.01
#: A one-sample move at most this far above the highest height that did not move the table
#: (relative) is a breakaway's smallest move: no pulse fires whose bound is below those.
JUMP_STEP = 0.03
#: Samples the motor loop acts after a pulse before its ringing is held to what they saw...
LOOP_REFERENCE = 2
#: ... times this (and ``f_relax``): a ringing grown beyond it stops the controller.
LOOP_GROWTH = 2.0
#: Least band of the table's reading, m, beyond the slide the drive's energy explains, while
#: the motor loop holds the table stuck (or the rest band, if wider): five times the largest
#: encoder noise of the project's batteries (0.4 um rms).
LOOP_SLIP = 2e-6


class CappedTrust(TrustRegion):
    """The trust region with a cap the dual-loop controller sets while it plans (1 else)."""

    def __init__(self, initial: float, guarded: bool, flexible: bool) -> None:
        super().__init__(initial, guarded, flexible)
        self.cap = 1.0

    def __call__(self) -> float:
        return min(super().__call__(), self.cap)


class DualLoopController(ExactController):
    """Exact-model pulses from a relaxed drive, a motor loop between them (see the module).

    It reads the settings of kind ``exact`` and ``f_mode`` (Hz, in [0, 0.25/T]),
    ``m_d_est`` (kg), ``c_t_est`` (N.s/m), ``f_relax`` (N) and ``identify_mode``.
    """

    kind = "dual_loop"
    #: The settings this kind reads besides the shared ones (registry: every kind's).
    SETTINGS = EXACT_SETTINGS + (M_D_EST,) + DUAL_LOOP_SETTINGS
    #: Its one-sample pulses are the free drive's (scaled by ``one_sample_gain``): Eq. (3)
    #: plans them, as before the evidence of the breakaway.
    evidence_planning = True
    reads_x_d_meas = True

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        f_mode = float(settings.f_mode)
        if not 0.0 <= f_mode * T <= F_MODE_MAX_T:
            raise ValueError(f"f_mode = {f_mode!r} Hz: the dual-loop controller needs the "
                             f"drive's mode in [0, {F_MODE_MAX_T:g}/T] = [0, "
                             f"{F_MODE_MAX_T / T:g}] Hz")
        # The pulses are planned as on a rigid table: the motor loop relaxes the drive
        # before each, so neither the rest's dwell nor the trust region need the mode.
        super().__init__(dataclasses.replace(settings, f_mode=0.0), T)
        self.trust = self.seq.trust = CappedTrust(self.trust.value, self.trust.guarded,
                                                  self.trust.flexible)
        self.settings = settings
        #: Moves over predictions of the last pulses of one sample and of wider ones.
        self.ratios: dict[int, list[float]] = {w: [] for w in RATIO_WIDTHS}
        #: Moves of the last one-sample pulses that moved the table visibly, m, and of those
        #: at most JUMP_STEP above a height that did not move it since it last moved.
        self.moves_1: list[float] = []
        self.jumps: list[float] = []
        #: The recent one-sample pushes that moved the table and their moves.
        self.curve = MoveCurve()
        self.f_relax = float(settings.f_relax)
        self.relax_max = max(1, int(round(RELAX_MAX_S / self.T)))
        #: The motor loop (None until the drive check has accepted a mode).
        self.motor: MotorLoop | None = None
        self.one_sample_gain = 1.0
        self.free_samples = 0
        #: Samples from a force's sample to the one it acts over (the drive check's).
        self.delay = 0
        self.probe_max = max(1, int(round(PROBE_WAIT_S / self.T)))
        #: The check of the drive model against the motor encoder at the first samples
        #: (a mode told, or ``identify_mode``), and its fit of the ringing.
        self.check: DriveCheck | None = None
        self.mode_id: ModeIdentifier | None = None
        if f_mode > 0.0 or settings.identify_mode:
            self.check = DriveCheck(self.T, float(settings.x_resolution), f_mode,
                                    float(settings.m_d_est),
                                    PROBE_SHARE * float(settings.f_c_est), self.probe_max)
            self.mode_id = self.check.identifier
        #: Motor encoder reading for the next update, m (set by the host; 0 unconnected).
        self.x_d_meas = 0.0
        #: The forces output at the last two samples, N (newest first).
        self.u_hist = [0.0, 0.0]
        #: Reason code with which every maneuver is refused (0: none): the drive check
        #: found the model told contradicted, or the motor encoder not following.
        self.refused = 0
        #: The maneuver's first sample waits for a relaxed drive (the probe rings it).
        self.wait_relaxed = False
        self._reset_drive()

    @property
    def u_last(self) -> float:
        """Force output at the last update, N."""
        return self.u_hist[0]

    def _use_mode(self, f_mode: float, c_t: float) -> None:
        """Build the motor loop for the mode f_mode (Hz) with the coupling's damping c_t
        (N.s/m), the motor mass ``m_d_est`` and the drive check's delay."""
        self.motor = MotorLoop(2.0 * math.pi * f_mode, float(self.settings.m_d_est), c_t, self.T,
                               delay=self.delay)
        #: Motor force per unit of the law's height of a one-sample pulse: one sample of
        #: force F on the motor of a relaxed drive pushes the table with at most
        #: 2*F*sin(omega*T/2) (the spring's first peak), so the height the law plans is
        #: the table's push.
        self.one_sample_gain = 1.0 / (2.0 * math.sin(math.pi * f_mode * self.T))
        #: Samples of no force after a pulse's last one: until the spring's force after one
        #: sample from a relaxed drive peaks, (pi/2 - omega*T/2)/omega, rounded up, and the
        #: delay.
        self.free_samples = int(math.ceil(0.25 / (f_mode * self.T) - 0.5 - 1e-9)) + self.delay

    def _accept(self, f_mode: float, x_meas: float) -> None:
        """The drive's mode f_mode (Hz) seen: the motor loop on it, its estimate seeded with
        the last force-free deflection of the fit; the maneuver's next pulse waits for the
        loop to relax the drive."""
        self._use_mode(f_mode, float(self.settings.c_t_est))
        recent = self.mode_id.recent
        if len(recent) == 2:
            self.motor.observe(recent[0], 0.0)
            self.motor.readings = 1
        self.x_last = x_meas
        # the ringing seen was this mode, which the motor loop now relaxes before every
        # pulse: the rest's dwell and the trust of a rigid table again
        self.rest.ring_dwell = 0
        self.rest.update_test()
        self.relaxed = 0
        self.wait_relaxed = True
        self.trust.ring = False
        self.trust.value = max(self.trust.value, self.trust0(self.settings))

    def _identify(self, x_d: float, x_meas: float) -> None:
        """``identify_mode`` after a probe that showed no mode: take a stuck table's later
        force-free readings into the fit; once it has a mode (within 0.25/T), between
        pulses and coarse moves, build the motor loop."""
        mode_id = self.mode_id
        mode_id.observe(x_d - x_meas, x_meas, self.u_hist[self.delay], self.rest.band)
        seq = self.seq
        if (mode_id.f_mode > 0.0 and mode_id.f_mode * self.T <= F_MODE_MAX_T
                and seq.pulse_left == 0 and seq.mode != Mode.COARSE):
            self._accept(mode_id.f_mode, x_meas)

    def _refuse(self, reason: int) -> float:
        """Refuse this maneuver and every later one with ``reason``: output 0."""
        self.refused = int(reason)
        self.seq.stop(reason)
        return 0.0

    def _check_step(self, x_d: float, x_meas: float, x_ref: float) -> float | None:
        """A sample of the drive check: the probe, then no force while the readings say
        whether the force reaches the drive and which mode it rings with (see
        :class:`~.mode_id.DriveCheck`); N, or None once the check has accepted a mode or
        (``identify_mode``) found none, and the sample goes on."""
        check = self.check
        if check.k == 0:
            check.observe(x_d - x_meas, x_meas)
            return math.copysign(check.probe, x_ref - x_meas)
        verdict = check.observe(x_d - x_meas, x_meas)
        if verdict == DriveCheck.PENDING:
            return 0.0
        if verdict == DriveCheck.ACCEPTED:
            self.delay = max(check.delay, 0)
            self._accept(check.f_mode, x_meas)
            return None
        if self.settings.f_mode > 0.0:
            # the mode told not seen, or contradicted, or the motor encoder not following
            # the probe: the model is not acted on, the drive is left as the probe left it
            return self._refuse(Reason.INVALID_MEASUREMENT
                                if verdict == DriveCheck.NOT_FOLLOWING else Reason.MODEL_REJECTED)
        # identify_mode, no mode seen: the table's encoder alone, any later ringing fitted
        self.delay = max(check.delay, 0)
        return None

    def _reset_drive(self) -> None:
        if self.motor is not None:
            self.motor.reset()
        #: Readings in a row with the drive relaxed; samples since it last was.
        self.relaxed = 0
        self.unrelaxed = 0
        self.drive_stop = False
        #: Samples of no force still to go after the last pulse (0: none, but no force while
        #: the table moves; -1: the motor loop acts).
        self.free = -1
        #: The table's last reading, m.
        self.x_last = 0.0
        #: Samples until the reading that must show a pulse's first force on the motor
        #: (0: none pending), and the motor reading it started from, m.
        self.fired = 0
        self.x_d_fired = 0.0
        #: Samples the motor loop has acted since the last pulse, and the largest ringing
        #: amplitude of its first :data:`LOOP_REFERENCE` samples, N.
        self.loop_n = 0
        self.loop_amp0 = 0.0
        #: The table's reading where the motor loop took over, m.
        self.x_loop = 0.0

    def reset(self) -> None:
        """Start a new maneuver from rest (learned model kept; the drive's estimate anew)."""
        super().reset()
        self._reset_drive()
        if self.check is not None and self.check.verdict == DriveCheck.PENDING:
            self.check.restart()  # cut short: a new probe

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force u (N) over the next sample, from the table's reading x_meas (m), the
        motor's :attr:`x_d_meas` (m) and the reference x_ref (m)."""
        u = self._update(x_meas, x_ref)
        self.u_hist = [u, self.u_hist[0]]
        return u

    def _update(self, x_meas: float, x_ref: float) -> float:
        seq = self.seq
        if self.refused:
            return 0.0 if seq.stopped else seq.stop(self.refused)
        x_d = self.x_d_meas
        check = self.check
        if check is not None and check.verdict == DriveCheck.PENDING:
            if not (-X_LIMIT <= x_d <= X_LIMIT and -X_LIMIT <= x_meas <= X_LIMIT
                    and -X_LIMIT <= x_ref <= X_LIMIT):
                return 0.0 if seq.stopped else seq.stop(Reason.INVALID_MEASUREMENT)
            u = self._check_step(x_d, x_meas, x_ref)
            if u is not None:
                return u
        elif self.motor is None and self.mode_id is not None:
            self._identify(x_d, x_meas)
        motor = self.motor
        if motor is None:
            return seq.update(x_meas, x_ref)
        x_prev, self.x_last = self.x_last, x_meas
        if seq.stopped or self.drive_stop:
            return 0.0
        if not (-X_LIMIT <= x_d <= X_LIMIT and -X_LIMIT <= x_meas <= X_LIMIT):
            return seq.stop(Reason.INVALID_MEASUREMENT)
        # the force over the interval that ends here, and the one already sent for the next
        applied = self.u_hist[self.delay]
        sent = self.u_hist[0] if self.delay else 0.0
        if self.fired:
            self.fired -= 1
            if not self.fired and abs(x_d - self.x_d_fired) < MOTOR_FOLLOWS * abs(
                    motor.gamma[0] * applied):
                # the reading that must show a pulse's first force on a relaxed drive: the
                # motor moved by about Gamma_1*u; a reading that did not follow (an encoder
                # disconnected, stuck) would make the loop push on a drive it does not see
                return seq.stop(Reason.INVALID_MEASUREMENT)
        motor.observe(x_d - x_meas, applied)
        if motor.amplitude() <= self.f_relax:
            self.relaxed += 1
        else:
            self.relaxed = 0
        loop = False
        if seq.pulse_left > 0 or seq.mode == Mode.COARSE:
            u = seq.update(x_meas, x_ref)  # a pulse or the coarse move goes on
            if seq.pulse_left == 0 and seq.mode == Mode.PULSE:
                self.free = self.free_samples
        elif self.free > 0 or (self.free == 0 and abs(x_meas - x_prev) > self.rest.band):
            # no force until the spring's first peak, and then while the table moves
            self.free = max(self.free - 1, 0)
            u = 0.0
        elif self.relaxed >= RELAX_SAMPLES or (seq.first and not self.wait_relaxed):
            self.free = -1
            self.wait_relaxed = False
            self.unrelaxed = 0
            u = seq.update(x_meas, x_ref)
            if seq.idle_samples:
                # (a sample the sequencer only counted: the motor loop's force still changes)
                seq.catch_up()
            if seq.stopped:
                u = 0.0
            elif not (seq.mode == Mode.PULSE or seq.mode == Mode.COARSE):
                u, loop = motor.force(sent), True
            else:
                self.fired, self.x_d_fired = 1 + self.delay, x_d
                self.loop_n = 0
                self.loop_amp0 = 0.0
                if seq.pulse_left == 0 and seq.mode == Mode.PULSE:
                    # a pulse of one sample fired: the table's push is the law's height
                    self.free = self.free_samples
                    u *= self.one_sample_gain
        else:
            self.free = -1
            self.unrelaxed += 1
            if self.unrelaxed > self.relax_max and seq.outcome != Outcome.SETTLED:
                return self._drive_rejected()
            u, loop = motor.force(sent), True
        if loop and self._loop_fails(motor.amplitude(), x_meas):
            return self._drive_rejected()
        if seq.mode == Mode.SETTLED and seq.outcome == Outcome.SETTLED:
            u = 0.0  # settled from a relaxed drive: no force, as every pulse controller
        return min(max(u, -self.settings.f_p_max), self.settings.f_p_max)

    def _loop_fails(self, amplitude: float, x_meas: float) -> bool:
        """Whether the motor loop, acting at this sample, fails on a drive unlike its model.

        Either the drive's ringing, ``amplitude`` (N), has grown to :data:`LOOP_GROWTH`
        times the largest of the loop's first :data:`LOOP_REFERENCE` samples since the last
        pulse (and ``f_relax``): the loop feeds the drive instead of relaxing it. Or the
        table's reading x_meas (m) has moved from where the loop took over by more than
        the energy the drive held then can slide it, ``A**2/(2*k_t*f_c_est)`` with A that
        largest amplitude, plus the rest band (at least :data:`LOOP_SLIP`): the loop's own
        force moves the table, which only a pulse may move.
        """
        self.loop_n += 1
        if self.loop_n == 1:
            self.x_loop = x_meas
        if self.loop_n <= LOOP_REFERENCE:
            self.loop_amp0 = max(self.loop_amp0, amplitude)
        a_0 = self.loop_amp0
        slip = a_0 * a_0 / (2.0 * self.motor.k_t * self.settings.f_c_est)
        if abs(x_meas - self.x_loop) > slip + max(self.rest.band, LOOP_SLIP):
            return True
        return (self.loop_n > LOOP_REFERENCE
                and amplitude > LOOP_GROWTH * max(self.loop_amp0, self.f_relax))

    def _drive_rejected(self) -> float:
        """The drive is not the model (it does not relax, the loop feeds it or moves the
        table): ``model_rejected``, no force, in this maneuver and every later one."""
        self.drive_stop = True
        return self._refuse(Reason.MODEL_REJECTED)

    @staticmethod
    def width_class(n: int) -> int:
        """The class of a pulse of n samples: the widest of :data:`RATIO_WIDTHS` up to n."""
        return max(w for w in RATIO_WIDTHS if w <= max(n, 1))

    def move_ratio(self, n: int) -> float:
        """Factor by which a pulse of n samples may exceed its prediction: the largest of
        the last :data:`KEEP_RATIOS` moves over predictions of its width class
        (:meth:`width_class`) that moved the table, at least 1; :data:`RATIO_PRIOR` before
        any."""
        kept = self.ratios[self.width_class(n)]
        return max(1.0, *kept) if kept else RATIO_PRIOR

    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Pulse for the error e (m): the exact-model law's, held to the bound of a move.

        With the motor loop, no pulse goes away from the target (the two-pulse moves of the
        law: the drive's smallest move is no smaller away than toward), and a pulse fires
        only if its prediction times :meth:`move_ratio` stays within ``1.5*abs(e)`` and a
        count (``x_resolution``); where the law's plan goes away, or is one sample beyond
        that, one sample toward the target as high as the law's model allows for it
        (:meth:`_lowered`). The law plans with its trust capped at ``1.5`` over the
        smaller ratio of the two kinds of pulse, and a pulse wider than one sample to stop
        :data:`LAND_FACTOR` times the shortest recent one-sample move short of the target
        (the one-sample pulse that lands there moves far less than a wide pulse misses by;
        the drive cannot move the table less than that one). A plan beyond the bound is
        planned again with the ratio of its own kind, if larger. None within it: no pulse
        helps.
        """
        if self.motor is None or not math.isfinite(e):
            return super().plan_pulse(e)
        # (a relative 1e-9: a plan for exactly the capped trust is within it)
        bound = (RUNAWAY_FACTOR * abs(e) + float(self.settings.x_resolution)) * (1.0 + 1e-9)
        short = (LAND_FACTOR * min(self.moves_1) if self.moves_1
                 else LAND_PRIOR * abs(e))
        if self.jumps and min(self.jumps) > bound:
            # a one-sample pulse just above one that did not move the table moved it farther:
            # so may the next one that moves it (a drive that cannot move the table less)
            self.seq.refusal = Reason.NO_MOVE_HELPS
            return 1, 0.0
        planned = self.evidence.planned
        trust = self.trust
        ratio = min(self.move_ratio(w) for w in RATIO_WIDTHS)
        land = short < 0.5 * abs(e)
        try:
            while True:
                self.evidence.planned = planned
                trust.cap = min(1.0, RUNAWAY_FACTOR / ratio)
                if land:
                    trust.cap = min(trust.cap, 1.0 - short / abs(e))
                n, f_p = super().plan_pulse(e)
                if not math.isfinite(f_p) or (f_p == 0.0
                                              and self.seq.refusal != Reason.NO_MOVE_HELPS):
                    return n, f_p
                if land and (n == 1 or f_p == 0.0):
                    land = False  # a one-sample pulse lands: for the whole way
                    continue
                toward = f_p * e > 0.0
                if n > 1 and toward and self.predict(n, f_p) * self.move_ratio(n) <= bound:
                    return n, f_p
                if toward and n > 1 and self.move_ratio(n) > ratio:
                    ratio = self.move_ratio(n)  # again, with the ratio of its width
                    continue
                # the law goes away first, finds no pulse that helps, plans one sample, or
                # a wider pulse beyond the bound: one sample
                planned_1 = self._one_sample(e, bound, short,
                                             abs(f_p) if toward and n == 1 else 0.0)
                if planned_1 is None:
                    break
                f_p, pred = planned_1
                self.evidence.planned = (1, f_p, pred)
                return 1, math.copysign(f_p, e)
        finally:
            trust.cap = 1.0
        self.seq.refusal = Reason.NO_MOVE_HELPS
        return 1, 0.0

    def _one_sample(self, e: float, bound: float, short: float, f_law: float
                    ) -> tuple[float, float] | None:
        """One sample toward the target for the error e (m) whose move times
        :meth:`move_ratio` stays within ``bound`` (m): its push (N) and predicted move (m),
        or None.

        It plans for the whole error, or the bound over the ratio if less, and ``short``
        (m) short of the target where the move that is left is no shorter than the shortest
        recent one-sample move (it lands from nearer, next). On the recent moves
        (:class:`~.move_curve.MoveCurve`, at most :data:`CURVE_EXTEND` times the farthest);
        before two, the law's height ``f_law`` (N, 0: none) if its model keeps it within
        the bound, else as high as that model allows (:meth:`_lowered`), else a staircase's
        step above the highest height known not to move the table (its first move is the
        smallest the table makes), planned for the goal. A push at most a staircase's step
        above a height that did not move the table since it last moved is that step; a push
        moves at least what any lower one moved (the move grows with the push). The push is
        at most ``f_p_max`` over the one-sample gain (the motor's force is held to
        ``f_p_max``).
        """
        ratio = self.move_ratio(1)
        push_max = self.settings.f_p_max / self.one_sample_gain
        goal = min(abs(e), bound / ratio * (1.0 - 1e-9))  # (the bound after rounding)
        if self.moves_1 and abs(e) - short >= min(self.moves_1):
            goal = min(goal, abs(e) - short)
        curve = self.curve
        if curve.ready:
            far = CURVE_EXTEND * max(d for _, d in curve.points)
            f = min(curve.push(min(goal, far)), push_max)
            pred = curve.move(f)
        else:
            f = min(f_law, push_max)
            pred = self.predict(1, f) if f > 0.0 else math.inf
            if not pred * ratio <= bound:
                f = self._lowered(goal, min(f_law, push_max) if f_law > 0.0 else push_max)
                pred = self.displacement(1, f) if f > 0.0 else 0.0
            if not f > 0.0:
                f, pred = min(self._f_still() * (1.0 + JUMP_STEP), push_max), goal
        if 0.0 < f < self.evidence.f_lb * (1.0 + JUMP_STEP):
            f, pred = min(self.evidence.f_lb * (1.0 + JUMP_STEP), push_max), max(pred, goal)
        pred = max(pred, max((d for f_i, d in curve.points if f_i <= f), default=0.0))
        if f > 0.0 and pred * ratio <= bound:
            return f, pred
        return None

    def _f_still(self) -> float:
        """Highest height known not to move the table, N: of a one-sample pulse since it last
        moved, the fit's bracket of the breakaway, or the fitted sliding friction."""
        est = self.estimator
        return max(est.f_s_lo, est.f_c_hat, self.evidence.f_lb)

    def _lowered(self, goal: float, f_hi: float) -> float:
        """Highest height (N) below f_hi whose one-sample move on the law's model is at most
        ``goal`` (m), a staircase's step above the highest height known not to move the
        table (0: none)."""
        f_lo = self._f_still() * (1.0 + JUMP_STEP)
        if not f_lo < f_hi or self.displacement(1, f_lo) > goal:
            return 0.0
        self.evidence.planned = (0, 0.0, 0.0)
        return bisect_increasing(lambda f: self.displacement(1, f), goal, f_lo, f_hi,
                                 LOWER_TOL * f_hi)[0]

    def learn(self, n: int, f_p: float, d: float) -> None:
        """The law learns the pulse's move d (m); its move over the prediction is kept."""
        pred = self.seq.pred
        visible = abs(d) > max(self.rest.band, 0.5 * self.estimator.x_resolution)
        if self.motor is not None and pred > 0.0 and math.isfinite(d) and visible:
            # (a pulse that did not move says nothing of how far one may overshoot)
            kept = self.ratios[self.width_class(n)]
            kept.append(abs(d) / pred)
            del kept[:-KEEP_RATIOS]
            if n == 1:
                self.moves_1 = (self.moves_1 + [abs(d)])[-KEEP_RATIOS:]
                if f_p * d > 0.0:
                    self.curve.add(abs(f_p), abs(d))
                if 0.0 < self.evidence.f_lb < abs(f_p) <= self.evidence.f_lb * (1.0 + JUMP_STEP):
                    # it broke away just above a height that did not move the table
                    self.jumps = (self.jumps + [abs(d)])[-KEEP_RATIOS:]
        super().learn(n, f_p, d)

    @property
    def f_low(self) -> float:
        """Lowest motor force it pulses with now, N: one sample at it is its smallest pulse."""
        return min(ExactController.f_low.fget(self) * self.one_sample_gain,
                   self.settings.f_p_max)

    def law_state(self) -> dict[str, Any]:
        """The exact-model law's state, the drive check's, the motor loop's and the
        relaxation counts."""
        out = super().law_state()
        out["motor"] = self.motor.state() if self.motor is not None else []
        out["relax"] = [self.relaxed, self.unrelaxed, int(self.drive_stop), self.free]
        out["x_last"] = self.x_last
        out["fired"] = [self.fired, self.x_d_fired]
        out["x_d_meas"] = self.x_d_meas
        out["check"] = self.check.state() if self.check is not None else []
        out["u_hist"] = list(self.u_hist)
        out["loop"] = [self.loop_n, self.loop_amp0, self.x_loop]
        out["refused"] = self.refused
        for w in RATIO_WIDTHS:
            out[f"ratios_{w}"] = list(self.ratios[w])
        out["moves_1"] = list(self.moves_1)
        out["jumps"] = list(self.jumps)
        out["curve"] = self.curve.state()
        out["wait_relaxed"] = int(self.wait_relaxed)
        return out

    def set_law_state(self, values: Mapping[str, Any]) -> None:
        super().set_law_state(values)
        check = self.check
        if check is not None:
            check.set_state(list(values["check"]))
            self.delay = max(check.delay, 0)
            self.motor = None
            if list(values["motor"]):
                if not check.f_mode > 0.0:
                    raise ValueError("law.motor holds numbers, but no mode was seen (no "
                                     "motor loop)")
                self._use_mode(check.f_mode, float(self.settings.c_t_est))
        elif list(values["check"]):
            raise ValueError("law.check holds numbers, but the controller checks no drive "
                             "(f_mode = 0, identify_mode off)")
        if self.motor is not None:
            self.motor.set_state(list(values["motor"]))
        elif list(values["motor"]):
            raise ValueError("law.motor holds numbers, but there is no motor loop")
        u_hist = [float(v) for v in values["u_hist"]]
        if len(u_hist) != 2:
            raise ValueError(f"law.u_hist holds {len(u_hist)} numbers, not 2")
        self.u_hist = u_hist
        loop = [float(v) for v in values["loop"]]
        if len(loop) != 3:
            raise ValueError(f"law.loop holds {len(loop)} numbers, not 3")
        self.loop_n, self.loop_amp0, self.x_loop = int(loop[0]), loop[1], loop[2]
        self.refused = int(values["refused"])
        for w in RATIO_WIDTHS:
            key = f"ratios_{w}"
            kept = [float(v) for v in values[key]]
            if len(kept) > KEEP_RATIOS:
                raise ValueError(f"law.{key} holds {len(kept)} numbers, at most {KEEP_RATIOS}")
            self.ratios[w] = kept
        moves_1 = [float(v) for v in values["moves_1"]]
        if len(moves_1) > KEEP_RATIOS:
            raise ValueError(f"law.moves_1 holds {len(moves_1)} numbers, at most {KEEP_RATIOS}")
        self.moves_1 = moves_1
        jumps = [float(v) for v in values["jumps"]]
        if len(jumps) > KEEP_RATIOS:
            raise ValueError(f"law.jumps holds {len(jumps)} numbers, at most {KEEP_RATIOS}")
        self.jumps = jumps
        self.curve.set_state(list(values["curve"]))
        self.wait_relaxed = bool(values["wait_relaxed"])
        relax = [int(v) for v in values["relax"]]
        if len(relax) != 4:
            raise ValueError(f"law.relax holds {len(relax)} numbers, not 4")
        self.relaxed, self.unrelaxed, self.drive_stop, self.free = (
            relax[0], relax[1], bool(relax[2]), relax[3])
        self.x_d_meas = float(values["x_d_meas"])
        self.x_last = float(values["x_last"])
        fired = [float(v) for v in values["fired"]]
        if len(fired) != 2:
            raise ValueError(f"law.fired holds {len(fired)} numbers, not 2")
        self.fired, self.x_d_fired = int(fired[0]), fired[1]
