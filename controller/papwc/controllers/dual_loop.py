"""Dual-loop pulse control of a flexible drive: a motor-side loop between pulses.

On a drive whose motor (mass m_d) pushes the table through a spring (stiffness k_t,
damping c_t), a pulse leaves the drive ringing; a pulse started from a ringing drive
moves the table by an amount its height and width do not decide. This controller
reads both encoders -- the table's ``x_meas`` and the motor's ``x_d_meas`` -- and

* between pulses, once the table is stuck, runs a *motor loop*: state feedback on
  the spring deflection delta = x_d - x and its rate (the table's friction holds
  it), that brings both to zero (poles at :data:`LOOP_POLE`; the rate from a
  two-reading estimator on the same model);
* plans and learns its pulses as the exact-model controller does
  (:class:`papwc.controllers.exact.ExactController`: Eq. (3) learned from its
  own pulses, inside a trust region), on the rest detection and trust region of a
  rigid table: with the drive relaxed before every pulse, a pulse's move is a
  function of its height and width;
* applies a pulse of n samples at height f_p as n samples of f_p on the motor (one
  sample: f_p/(2*sin(omega*T/2)), the motor force whose spring's first peak pushes
  the table with f_p), then no force until that peak (``ceil(1/(4*f_mode*T) - 1/2)``
  samples) and on while the table's reading still moves (by more than the rest
  band), then the motor loop: the table's move is that of the pulse on the free
  drive (no more), and the loop relaxes the drive with the table stuck;
* gives the sequencer a sample only while a pulse is being applied or the drive
  is *relaxed*: the deflection's amplitude k_t*sqrt(delta**2 + (delta'/omega)**2)
  at most ``f_relax`` on :data:`RELAX_SAMPLES` readings in a row. So a pulse
  starts, a pulse's move is read and the maneuver settles only from a relaxed
  drive; settled, the force is 0.

The drive model is the mode frequency ``f_mode`` (Hz, of the motor on the spring
against the stuck table: omega = 2*pi*f_mode = sqrt(k_t/m_d)), the motor mass
``m_d_est`` (kg; k_t = m_d_est*omega**2) and ``c_t_est`` (N.s/m). A loop sampled
at T can damp such a mode only well below the Nyquist frequency: ``f_mode`` must
lie in [0, :data:`F_MODE_MAX_T`/T] (the settings refuse others); with ``f_mode``
= 0 (no drive model) there is no motor loop and the controller is the exact-model
controller on the table's encoder, with its rest and trust of a rigid table. With
``f_mode`` = 0 and ``identify_mode``, the mode is identified instead: at the first sample
a probe of one sample of :data:`PROBE_SHARE` times ``f_c_est`` on the motor (the spring's
first peak, at most twice that, stays below the friction that holds the table), then no
force while :class:`~.mode_id.ModeIdentifier` fits the free ringing the motor encoder
shows (at most :data:`PROBE_WAIT_S`); with a mode within 0.25/T the motor loop is built
on it (with ``m_d_est`` and ``c_t_est``, as for a mode told), the ringing the table-only
rest detection saw is forgotten, and the maneuver's first pulse waits for the relaxed
drive. Without one (the motor encoder not connected, a rigid drive), it goes on on the
table's encoder alone, and takes any later free ringing of a stuck table into the fit.
When the drive does not relax within :data:`RELAX_MAX_S` seconds (a drive unlike its
model), the controller stops with the reason ``model_rejected`` and outputs 0.

The host sets :attr:`DualLoopController.x_d_meas` (m) before each
:meth:`~DualLoopController.update` (the controller slave and PulseController.fmu
do, from their input ``x_d_meas``); a reading that is not finite stops it with
``invalid_measurement``, and so does a motor reading that does not follow a pulse's
first sample (less than :data:`MOTOR_FOLLOWS` of the motor's move on the model: the
encoder not connected), before the loop acts on it.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from ..model.controller_settings import F_MODE_MAX_T
from ..model.variables import Variable
from .exact import EXACT_SETTINGS, ExactController
from .interface import Mode, Outcome, Reason
from .mode_id import ModeIdentifier
from .sequencer import M_D_EST, X_LIMIT
from .settings import ControllerSettings

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


__all__ = ["DualLoopController", "MotorLoop", "F_MODE_MAX_T", "LOOP_POLE", "PROBE_SHARE",
           "PROBE_WAIT_S", "RELAX_SAMPLES"]

#: Poles of the motor loop (z-plane, both): 0 would be deadbeat; a little above it keeps
#: the loop damped with the drive model a few percent off.
LOOP_POLE = 0.2
#: Readings in a row within ``f_relax`` for the drive to count as relaxed.
RELAX_SAMPLES = 3
#: Longest the drive may take to relax, s: beyond it the controller stops.
RELAX_MAX_S = 1.0
#: The probe of the mode's identification: one sample of this share of ``f_c_est``...
PROBE_SHARE = 0.4
#: ... and the longest wait for the ringing to identify, s.
PROBE_WAIT_S = 0.5
#: Least fraction of the motor's move over a pulse's first sample (on the model) that its
#: encoder must show; less stops the controller (``invalid_measurement``).
MOTOR_FOLLOWS = 0.1


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
    """

    def __init__(self, omega: float, m_d: float, c_t: float, T: float,
                 pole: float = LOOP_POLE) -> None:
        self.omega = float(omega)
        self.m_d = float(m_d)
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
        self.u_prev = 0.0
        #: Readings taken since the reset (at most 2 counted).
        self.readings = 0

    def observe(self, delta: float, u_prev: float) -> None:
        """Take the reading delta (m) after u_prev (N) was held over the last sample."""
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

    def force(self) -> float:
        """The loop's force for the next sample, N."""
        k1, k2 = self.gain
        return -(k1 * self.delta + k2 * self.rate)

    def amplitude(self) -> float:
        """Force amplitude of the deflection's ringing, N:
        k_t*sqrt(delta**2 + (delta'/omega)**2)."""
        if self.readings < 2:
            return math.inf
        return self.k_t * math.hypot(self.delta, self.rate / self.omega)

    def state(self) -> list[float]:
        """delta (m), its rate (m/s), the last force (N), the readings (0, 1, 2)."""
        return [self.delta, self.rate, self.u_prev, float(self.readings)]

    def set_state(self, values: list[float]) -> None:
        """Restore :meth:`state`."""
        if len(values) != 4:
            raise ValueError(f"law.motor holds {len(values)} numbers, not 4")
        self.delta, self.rate, self.u_prev = (float(v) for v in values[:3])
        self.readings = min(max(int(values[3]), 0), 2)


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
    evidence_planning = False
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
        self.settings = settings
        self.f_relax = float(settings.f_relax)
        self.relax_max = max(1, int(round(RELAX_MAX_S / self.T)))
        #: The motor loop (None without a mode: f_mode = 0 and none identified yet).
        self.motor: MotorLoop | None = None
        self.one_sample_gain = 1.0
        self.free_samples = 0
        #: The identification of the mode from the motor encoder's ringing (f_mode = 0 and
        #: ``identify_mode``), and the samples since its probe (-1: not fired yet).
        self.mode_id = (ModeIdentifier(self.T, float(settings.x_resolution))
                        if f_mode == 0.0 and settings.identify_mode else None)
        self.probe_k = -1
        self.probe_max = max(1, int(round(PROBE_WAIT_S / self.T)))
        if f_mode > 0.0:
            self._use_mode(f_mode, float(settings.c_t_est))
        #: Motor encoder reading for the next update, m (set by the host; 0 unconnected).
        self.x_d_meas = 0.0
        #: Force output at the last update while there is no motor loop, N.
        self.u_last = 0.0
        #: The maneuver's first sample waits for a relaxed drive (the mode was identified
        #: from a probe's ringing within it).
        self.wait_relaxed = False
        self._reset_drive()

    def _use_mode(self, f_mode: float, c_t: float) -> None:
        """Build the motor loop for the mode f_mode (Hz) with the coupling's damping c_t
        (N.s/m) and the motor mass ``m_d_est``."""
        self.motor = MotorLoop(2.0 * math.pi * f_mode, float(self.settings.m_d_est), c_t, self.T)
        #: Motor force per unit of the law's height of a one-sample pulse: one sample of
        #: force F on the motor of a relaxed drive pushes the table with at most
        #: 2*F*sin(omega*T/2) (the spring's first peak), so the height the law plans is
        #: the table's push.
        self.one_sample_gain = 1.0 / (2.0 * math.sin(math.pi * f_mode * self.T))
        #: Samples of no force after a pulse's last one: until the spring's force after one
        #: sample from a relaxed drive peaks, (pi/2 - omega*T/2)/omega, rounded up.
        self.free_samples = int(math.ceil(0.25 / (f_mode * self.T) - 0.5 - 1e-9))

    def _identify(self, x_d: float, x_meas: float) -> None:
        """Take the readings into the identification of the mode; once it has one (within
        0.25/T), between pulses and coarse moves, build the motor loop."""
        mode_id = self.mode_id
        # while the probe rings the drive, friction holds the table (the probe is below it):
        # its reading wanders by noise alone, whose band is not known yet
        probing = 0 <= self.probe_k < self.probe_max
        mode_id.observe(x_d - x_meas, x_meas, self.u_last,
                        math.inf if probing else self.rest.band)
        seq = self.seq
        if (mode_id.f_mode > 0.0 and mode_id.f_mode * self.T <= F_MODE_MAX_T
                and seq.pulse_left == 0 and seq.mode != Mode.COARSE):
            self._use_mode(mode_id.f_mode, float(self.settings.c_t_est))
            self.motor.u_prev = self.u_last
            self.x_last = x_meas
            # the ringing seen was this mode, which the motor loop now relaxes before every
            # pulse: the rest's dwell and the trust of a rigid table again
            self.rest.ring_dwell = 0
            self.rest.update_test()
            # the probe still rings the drive: the maneuver's first pulse waits for it too
            self.relaxed = 0
            self.wait_relaxed = True
            self.trust.ring = False
            self.trust.value = max(self.trust.value, self.trust0(self.settings))

    def _probe(self, x_meas: float, x_ref: float) -> float:
        """The probe of the identification: one sample of ``PROBE_SHARE*f_c_est`` on the
        motor toward the target (the spring's first peak, at most twice that, stays below
        the friction that holds the table), then no force while the drive rings, for at
        most ``PROBE_WAIT_S``; N."""
        if self.probe_k < 0:
            self.probe_k = 0
            u = math.copysign(PROBE_SHARE * float(self.settings.f_c_est), x_ref - x_meas)
        else:
            self.probe_k += 1
            u = 0.0
        self.u_last = u
        return u

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
        #: A pulse started at the last sample, from the motor reading x_d_fired (m).
        self.fired = False
        self.x_d_fired = 0.0

    def reset(self) -> None:
        """Start a new maneuver from rest (learned model kept; the drive's estimate anew)."""
        super().reset()
        self._reset_drive()

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force u (N) over the next sample, from the table's reading x_meas (m), the
        motor's :attr:`x_d_meas` (m) and the reference x_ref (m)."""
        seq = self.seq
        if self.motor is None and self.mode_id is not None:
            self._identify(self.x_d_meas, x_meas)
            if self.motor is None and self.probe_k < self.probe_max:
                return self._probe(x_meas, x_ref)
        motor = self.motor
        if motor is None:
            self.u_last = seq.update(x_meas, x_ref)
            return self.u_last
        x_d = self.x_d_meas
        x_prev, self.x_last = self.x_last, x_meas
        if seq.stopped or self.drive_stop:
            return 0.0
        if not (-X_LIMIT <= x_d <= X_LIMIT and -X_LIMIT <= x_meas <= X_LIMIT):
            return seq.stop(Reason.INVALID_MEASUREMENT)
        if self.fired:
            # the sample after a pulse's first force on a relaxed drive: the motor moved
            # by about Gamma_1*u; a reading that did not follow (an encoder not connected,
            # stuck) would make the loop push on a drive it does not see
            if abs(x_d - self.x_d_fired) < MOTOR_FOLLOWS * abs(motor.gamma[0] * motor.u_prev):
                motor.u_prev = 0.0
                return seq.stop(Reason.INVALID_MEASUREMENT)
            self.fired = False
        motor.observe(x_d - x_meas, motor.u_prev)
        if motor.amplitude() <= self.f_relax:
            self.relaxed += 1
        else:
            self.relaxed = 0
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
                u = motor.force()
            else:
                self.fired, self.x_d_fired = True, x_d
                if seq.pulse_left == 0 and seq.mode == Mode.PULSE:
                    # a pulse of one sample fired: the table's push is the law's height
                    self.free = self.free_samples
                    u *= self.one_sample_gain
        else:
            self.free = -1
            self.unrelaxed += 1
            if self.unrelaxed > self.relax_max and seq.outcome != Outcome.SETTLED:
                self.drive_stop = True
                seq.stop(Reason.MODEL_REJECTED)
                motor.u_prev = 0.0
                return 0.0
            u = motor.force()
        if seq.mode == Mode.SETTLED and seq.outcome == Outcome.SETTLED:
            u = 0.0  # settled from a relaxed drive: no force, as every pulse controller
        u = min(max(u, -self.settings.f_p_max), self.settings.f_p_max)
        motor.u_prev = u
        return u

    @property
    def f_low(self) -> float:
        """Lowest motor force it pulses with now, N: one sample at it is its smallest pulse."""
        return min(ExactController.f_low.fget(self) * self.one_sample_gain,
                   self.settings.f_p_max)

    def law_state(self) -> dict[str, Any]:
        """The exact-model law's state, the motor loop's and the relaxation counts."""
        out = super().law_state()
        out["motor"] = self.motor.state() if self.motor is not None else []
        out["relax"] = [self.relaxed, self.unrelaxed, int(self.drive_stop), self.free]
        out["x_last"] = self.x_last
        out["fired"] = [int(self.fired), self.x_d_fired]
        out["x_d_meas"] = self.x_d_meas
        out["mode_id"] = self.mode_id.state() if self.mode_id is not None else []
        out["u_last"] = self.u_last
        out["probe_k"] = self.probe_k
        out["wait_relaxed"] = int(self.wait_relaxed)
        return out

    def set_law_state(self, values: Mapping[str, Any]) -> None:
        super().set_law_state(values)
        mode_id = self.mode_id
        if mode_id is not None:
            mode_id.set_state(list(values["mode_id"]))
            self.motor = None
            if list(values["motor"]):
                if not mode_id.f_mode > 0.0:
                    raise ValueError("law.motor holds numbers, but f_mode = 0 and no mode "
                                     "was identified (no motor loop)")
                self._use_mode(mode_id.f_mode, float(self.settings.c_t_est))
        elif list(values["mode_id"]):
            raise ValueError("law.mode_id holds numbers, but f_mode is given")
        if self.motor is not None:
            self.motor.set_state(list(values["motor"]))
        elif list(values["motor"]):
            raise ValueError("law.motor holds numbers, but there is no motor loop")
        self.u_last = float(values["u_last"])
        self.probe_k = int(values["probe_k"])
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
        self.fired, self.x_d_fired = bool(fired[0]), fired[1]
