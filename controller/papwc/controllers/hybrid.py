"""The 1 kHz pulse hybrid: the PID's approach with its in-position window, then force ramps.

A drive's 1 kHz loop brings the table near the target and the PID's in-position window
(:mod:`.pid`) holds its force once the table rests within ``in_position_band``. Where that
leaves the table outside the tolerance, the hybrid does what the PID's integrator does
blindly, but watching: a *force ramp* from the force held toward the target, at
``ramp_rate``, cut as soon as the readings show a reliable move. A 1 kHz loop sees a
breakaway within milliseconds, so the ramp stops the table after a fraction of a
micrometre, where a 100 Hz pulse controller cannot stop what it sees only 10 ms later
(issue 46).

A ramp, one *pulse* of the ``pulses`` output (the spec judges its move, from its first
sample to the next rest, against ``bound_m``):

1. it starts from the force held, at rest inside the window with the averaged error known
   to lie outside the tolerance; up to the force at which the last ramp toward the same
   side moved the table (less :data:`KNEE_MARGIN`), it climbs :data:`FAST` times faster;
2. each sample, the mean of the last m readings (m = 1, 2, 4, 8, 16) is compared with the
   averaged reading at rest before the ramp: a move toward the target beyond ``Z_RAMP``
   standard errors of that difference is reliable (the standard error from the rest
   detector's noise estimate and the encoder count ``x_resolution``, not a single count);
3. cut: the force drops to at most :data:`CUT_SHARE` of ``f_c_est`` toward the target
   (below any sliding friction, so a table that broke away stops), and is held while the
   table comes to rest; the window's hold then judges the new rest (settled, another ramp,
   or the PID again outside the window).

A ramp that reaches ``f_p_max`` without a move stops the maneuver (``cannot_move``).

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math

from ..model.variables import Variable
from .interface import Mode, Reason
from .pid import HYBRID_BAND, PID_SETTINGS, PidController, PidSequencer, rounding_bias
from .rest import NOISE_WINDOW
from .sequencer import Z_ACT, Z_DECIDE
from .settings import ControllerSettings

__all__ = ["HYBRID_SETTINGS", "HybridController", "HybridSequencer"]

#: The settings the hybrid reads besides the shared ones and the PID's.
HYBRID_SETTINGS: tuple[Variable, ...] = (
    Variable("ramp_rate", "Rate of the hybrid's force ramps near the target (from the force "
             "held toward the target, cut on the first reliable move)", "N/s", 150.0,
             min=0.0, min_open=True, max=1e9, nominal=100.0),
)

#: The PID's settings the hybrid reads (its window is always on: no ``in_position``).
_PID_READ = tuple(v for v in PID_SETTINGS if v.name != "in_position")

#: Standard errors of a move beyond which it is reliable (a false cut costs one more ramp).
Z_RAMP = 4.0
#: A ramp is cut once the table has moved this share of the error (or at the first
#: reliable move where that is farther).
REACH = 0.5
#: Standard errors by which the averaged error must lie outside the tolerance before a ramp
#: (a ramp's move is uncertain by more than the tolerance: waiting to be sure of a small
#: error costs more than a ramp that was not needed).
Z_START = Z_DECIDE
#: The error need be known to this share of it before a ramp (the pulse controllers' default
#: precision): a ramp moves a fraction of it.
PRECISION = 0.1
#: Lengths of the means of the last readings compared with the rest before the ramp.
MEANS = (1, 2, 4, 8, 16)
#: Factor of ``ramp_rate`` below the knee (the force that moved the table last, less
#: KNEE_MARGIN of it).
FAST = 30.0
#: Share of the last moving force below which the ramp climbs fast.
KNEE_MARGIN = 0.05
#: Share of ``f_c_est`` below which a ramp climbs fast where no force has moved the table
#: toward that side yet (below the Coulomb friction no table breaks away).
KNEE_SHARE = 1.0
#: The cut: the force toward the target drops to at most this share of ``f_c_est``.
CUT_SHARE = 0.5
#: A table that has moved this many times its move at the cut under the force held after
#: a shallow cut slides: the force drops (a deep cut).
BRAKE = 1.25
#: Readings in the mean that watches the move after a cut.
BRAKE_MEAN = 4
#: Lowest share of ``ramp_rate`` a ramp slows to, and the factor by which it regains it.
RATE_MIN = 0.125
RATE_UP = 1.25
#: Samples the force is held after a cut before the window judges the rest anyway.
WAIT_MAX = 300
#: Samples at ``f_p_max`` without a move after which a ramp gives up.
TOP_SAMPLES = 50
#: Phases of the fine positioning.
IDLE, RAMP, WAIT = 0, 1, 2


class HybridSequencer(PidSequencer):
    """The PID with its window (:class:`~.pid.PidSequencer`), ramps inside the window."""

    law: HybridController

    def quiet_readings(self) -> bool:
        """The force-free windows take the readings once the reference has arrived, but not
        while a ramp changes the force."""
        return self.law.phase != RAMP and self.law.arrived()

    def holding_force(self, u: float) -> float:
        """The force held for the PID's last force u (N): u, at most ``f_c_est``.

        The ramps start from it, nearer the breakaway than none (the PID's window bleeds it
        to zero: held or bled, the hybrid's figures: 108 against 91 of 144 runs within one
        count, realism_mc(_lugre)_hybrid.toml with seed offsets 0, 2000, 3000). A table slips
        under a force held near its breakaway (a stiction drawn anew, an actuator's lag
        catching up, creep on pre-sliding bristles), and a force above the sliding friction
        keeps it sliding; the Coulomb friction's estimate ``f_c_est`` lies below any sliding
        friction, so a slip under it dies out.
        """
        return math.copysign(min(abs(u), self.f_c_est), u)

    def coasts_into_window(self, x_ref: float) -> bool:
        """The PID's force is not cut as the table coasts into the hybrid's window: the ramps
        start from the force the PID holds, nearer the breakaway than none."""
        return False

    def window_act(self, x_ref: float, at_rest: bool) -> float:
        """A ramp, the hold after its cut, or the PID with its window (force, N)."""
        law = self.law
        if law.phase == RAMP:
            return self.ramp(x_ref)
        if law.phase == WAIT:
            law.waited += 1
            side = law.side_r
            moved = side * (self.recent_mean(min(law.waited, BRAKE_MEAN)) - law.x0)
            law.peak = max(law.peak, moved)
            if law.shallow and moved > BRAKE * law.d_cut:
                # it goes on moving under the force held: it slides, brake
                law.shallow = False
                law.u_cut = side * min(side * law.u_cut, CUT_SHARE * self.f_c_est)
            if (at_rest and self.still()) or law.waited >= WAIT_MAX:
                law.phase = IDLE
                if law.waited >= NOISE_WINDOW:
                    self.learn_rate(side * (self.recent_mean(NOISE_WINDOW) - law.x0))
                if not law.shallow and law.waited >= NOISE_WINDOW:
                    back = law.peak - side * (self.recent_mean(NOISE_WINDOW) - law.x0)
                    noise2 = self.rest.sigma2 + law.q * law.q / 12.0
                    if back > 0.0 and back * back > Z_RAMP * Z_RAMP * noise2 * (
                            1.0 / BRAKE_MEAN + 1.0 / NOISE_WINDOW):
                        law.elastic = True
                return self.enter_hold(x_ref, law.u_cut, capped=False)
            if abs(x_ref - self.x_prev) > law.w_band + self.reading_margin():
                law.phase = IDLE
                law.holding = True
                return self.leave_hold()
            return law.u_cut
        return super().window_act(x_ref, at_rest)

    def inside(self, e: float, s: float) -> float:
        """Inside the window, the averaged error e (m, standard error s) known to lie outside
        the tolerance and known well enough: a ramp toward the target; else the force held."""
        law = self.law
        if law.mode_samples or self.rest.ringing():
            # a drive with a spring (told f_mode, or seen ringing): the table follows a
            # ramp late, after the spring has taken up force; its first move is no measure
            # of what the force will do, so the force stays held
            return law.u_hold
        tol = self.tolerance
        # beyond the tolerance less the rounding's bias (which the settled outcome counts in
        # against it): a noiseless reading one count off the target's is a move to make
        bias = rounding_bias(self.rest.sigma2, law.q)
        if not (abs(e) - Z_START * s > tol - bias
                and Z_ACT * s <= max(tol, PRECISION * abs(e))):
            return law.u_hold
        return self.start_ramp(e)

    def start_ramp(self, e: float) -> float:
        """Start a ramp toward the target from the force held (one more pulse), N."""
        law = self.law
        side = 1.0 if e > 0.0 else -1.0
        law.phase = RAMP
        law.holding = False
        law.side_r = side
        law.u = law.u_hold
        law.x0 = law.h_x0 + law.h_sum / law.h_n
        law.n0 = law.h_n
        law.e_start = e
        law.k_ramp = 0
        law.top = 0
        last = law.u_move_pos if side > 0.0 else law.u_move_neg
        law.knee = side * max((1.0 - KNEE_MARGIN) * abs(last), KNEE_SHARE * self.f_c_est)
        self.mode = Mode.PULSE
        self.pulses += 1
        return self.ramp_step()

    def ramp_step(self) -> float:
        """The ramp's next force, N: fast below the knee, ``ramp_rate`` above, at most
        ``f_p_max``."""
        law = self.law
        side = law.side_r
        fast = law.stiff and not law.elastic and (law.knee - law.u) * side > 0.0
        mu = law.mu_pos if side > 0.0 else law.mu_neg
        rate = law.ramp_rate * (FAST if fast else mu)
        u = law.u + side * rate * self.T
        if (law.knee - law.u) * side > 0.0 and (u - law.knee) * side > 0.0:
            u = law.knee
        f_max = self.f_p_max
        law.u = min(max(u, -f_max), f_max)
        law.k_ramp += 1
        return law.u

    def learn_rate(self, d: float) -> None:
        """The ramp toward its side moved d (m, to the rest after it): its rate toward that
        side is halved where d exceeded the error it started from (a slower ramp breaks the
        table away with less force to spare, and is seen sooner), and regained step by step
        (by ``RATE_UP``, at most ``ramp_rate``) where d stayed within half of it."""
        law = self.law
        e = abs(law.e_start)
        mu = law.mu_pos if law.side_r > 0.0 else law.mu_neg
        if d > e:
            mu = max(mu * 0.5, RATE_MIN)
        elif d < 0.5 * e:
            mu = min(mu * RATE_UP, 1.0)
        if law.side_r > 0.0:
            law.mu_pos = mu
        else:
            law.mu_neg = mu

    def ramp(self, x_ref: float) -> float:
        """One sample of a ramp: cut on a reliable move toward the target, else go on (N)."""
        law = self.law
        d = self.moved()
        if d > 0.0:
            return self.cut(d)
        if law.side_r * law.u >= self.f_c_est:
            # no move up to the Coulomb friction: no pre-sliding to speak of
            law.stiff = True
        if abs(law.u) >= self.f_p_max:
            law.top += 1
            if law.top >= TOP_SAMPLES:
                law.phase = IDLE
                law.holding = False
                return self.stop(Reason.CANNOT_MOVE)
            return law.u
        return self.ramp_step()

    def moved(self) -> float:
        """The move toward the target (m) that the last readings show reliably, else 0 (see
        the module): a mean of the last m beyond ``Z_RAMP`` standard errors from the rest."""
        law, rest = self.law, self.rest
        noise2 = rest.sigma2 + law.q * law.q / 12.0
        reach = REACH * abs(law.e_start)
        total = 0.0
        k = law.ring_n
        side = law.side_r
        for i in range(1, min(law.k_ramp, NOISE_WINDOW) + 1):
            total += law.ring[(k - i) % NOISE_WINDOW]
            if i in MEANS:
                d = side * (total / i - law.x0)
                if (d >= reach and d > 0.0
                        and d * d > Z_RAMP * Z_RAMP * noise2 * (1.0 / i + 1.0 / law.n0)):
                    return d
        return 0.0

    def cut(self, d: float) -> float:
        """A reliable move of d (m): the force drops toward the target to at most
        ``CUT_SHARE*f_c_est`` and is held while the table comes to rest (N); on a table seen
        to be elastic the force reached is held, and dropped only if the table goes on
        moving (see the module)."""
        law = self.law
        side = law.side_r
        if side > 0.0:
            law.u_move_pos = law.u
        else:
            law.u_move_neg = law.u
        law.d_cut = d
        law.peak = d
        if side * law.u < self.f_c_est:
            # it moved under less than the Coulomb friction: pre-sliding (or a spring)
            law.elastic = True
        law.shallow = law.elastic
        law.u_cut = law.u if law.elastic else side * min(side * law.u,
                                                          CUT_SHARE * self.f_c_est)
        law.phase = WAIT
        law.waited = 0
        self.mode = Mode.WAIT
        self.rest.start_run(self.x_prev)
        self.rest.ring_n = 0
        self.rest.forget_direction()
        return law.u_cut


class HybridController(PidController):
    """The 1 kHz pulse hybrid (see the module).

    Parameters
    ----------
    settings : ControllerSettings
        Validated settings of kind ``hybrid``: the PID's (gains, trajectory, ``hunt_max``,
        ``in_position_band``; the window is always on), ``ramp_rate``, ``x_resolution``,
        and the shared ones (``f_p_max``, ``tolerance``, ``m_est``, ``f_c_est``).
    T : float
        Sample period, s (1 ms is what it is made for).
    """

    kind = "hybrid"
    #: The settings this kind reads besides the shared ones.
    SETTINGS = _PID_READ + HYBRID_SETTINGS
    sequencer_class = HybridSequencer

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        self._reset_ramp()
        self.u_move_pos = self.u_move_neg = 0.0
        #: Whether the table was seen to spring back after a cut (pre-sliding bristles, a
        #: drive's spring): its force is then held at the cut, not dropped (kept across
        #: maneuvers: it is the table's).
        self.elastic = False
        #: The share of ``ramp_rate`` of the ramps toward each side (:meth:`HybridSequencer.
        #: learn_rate`); kept across maneuvers.
        self.mu_pos = self.mu_neg = 1.0
        #: Whether a ramp reached ``f_c_est`` without a move (no pre-sliding: the ramps may
        #: climb fast to the knee); kept across maneuvers.
        self.stiff = False
        super().__init__(settings, T)
        self.window = True
        if settings.in_position_band is None:
            self.w_band = max(self.w_band, HYBRID_BAND)
        self.ramp_rate = float(settings.ramp_rate)

    def reset(self) -> None:
        """Start a new maneuver from rest (the forces that moved the table are kept)."""
        super().reset()
        self._reset_ramp()

    def _reset_ramp(self) -> None:
        #: Phase (IDLE, RAMP, WAIT), the ramp's side (+1, -1), force (N), knee (N), the
        #: averaged reading (m) and its readings before it, the error then (m), samples
        #: ramped and at f_p_max, the force after the cut (N), samples waited since.
        self.phase = IDLE
        self.side_r = 0.0
        self.u = 0.0
        self.knee = 0.0
        self.x0 = 0.0
        self.n0 = 1
        self.e_start = 0.0
        self.k_ramp = 0
        self.top = 0
        self.u_cut = 0.0
        self.waited = 0
        #: The move at the cut and the farthest since (m, toward the target), whether the
        #: force after the cut is the one reached (not dropped).
        self.d_cut = 0.0
        self.peak = 0.0
        self.shallow = False

    @property
    def f_low(self) -> float:
        """It plans no pulse height: NaN."""
        return math.nan

    # -- state -------------------------------------------------------------------------
    _RAMP_FLOATS = ("side_r", "u", "knee", "x0", "e_start", "u_cut", "u_move_pos",
                    "u_move_neg", "d_cut", "peak", "mu_pos", "mu_neg")
    _RAMP_INTS = ("phase", "n0", "k_ramp", "top", "waited", "shallow", "elastic", "stiff")

    def law_state(self) -> dict:
        """The PID's state and the ramp's."""
        out = super().law_state()
        for name in self._RAMP_FLOATS:
            out[name] = getattr(self, name)
        for name in self._RAMP_INTS:
            out[name] = int(getattr(self, name))
        return out

    def set_law_state(self, values) -> None:
        super().set_law_state(values)
        for name in self._RAMP_FLOATS:
            setattr(self, name, float(values[name]))
        for name in self._RAMP_INTS:
            setattr(self, name, int(values[name]))
        self.shallow, self.elastic = bool(self.shallow), bool(self.elastic)
        self.stiff = bool(self.stiff)
