"""Pulse control on the exact pulse model, Eq. (3), learned from the controller's own pulses.

PAPWC (Section 3) plans with the Coulomb-only model (4) and cannot move the mass
less than one sample at the stiction force, Eq. (20). This controller

* predicts a pulse's displacement with Eq. (3) (Eq. (2) at c = 0),
  :func:`papwc.model.pulse.pulse_displacement`, corrected by what the nearest
  earlier pulses of the same width moved against it (on a plant that is not
  Eq. (3) -- Stribeck, ripple, a lag -- the model's error varies slowly with
  the height, so the pulses near the one planned say how far it will go);
* learns m, f_c and c from the measured displacements of its recent pulses by a
  small regularized least-squares fit (Levenberg-Marquardt) weighted with the
  measurement's resolution and noise, and brackets the breakaway force f_s
  between the highest amplitude that did not move the mass and the lowest that
  did;
* plans inside a trust region: a single pulse moves by ``trust*|e|``, where
  the trust (``trust0`` at first, at most 1) doubles after every pulse that
  moved as predicted and shrinks after one that moved more, so a model fooled by
  noise or by a plant unlike Eq. (3) plans short pulses near the breakaway force
  instead of long ones;
* plans the fastest such pulse: the fewest samples n whose required amplitude
  lies in [f_floor, f_p_max], the amplitude solving the (corrected) model;
* moves less than its smallest single pulse (one sample at f_floor, d_small)
  by two pulses: first away from the target by d_small, then back by
  ``|e| + d_small`` in one pulse; no pulse moves farther than the larger of
  ``|e|`` and d_small;
* plans a pulse wider than any in its history (where the model extrapolates: a
  fit to one-sample pulses near breakaway says little of two samples on a table
  with pre-sliding or a lag) for at most ``_EXPLORE`` (3) times the farthest a
  pulse in the history moved, and, while the model's misfit or its last
  prediction's error is above ``_EXACT_ENOUGH`` (20 %), with ``_NEW_WIDTH`` (2/3)
  of the trust;
* while its fit rests on sliding pulses of one width and lies more than ``_IMPLAUSIBLE``
  (2) prior standard deviations from the settings' estimates (a lag or Stribeck fitted by
  a mass, friction and damping the table does not have), plans a pulse wider than any made
  at most ``_WIDER`` (1.5) times as wide (one sample wider for narrow ones) and no higher
  than the highest of that width;
* after a pulse its model missed by more than 50 %, plans no pulse wider than
  the widest it has made nor more than 10 % higher than the highest of at least
  that width (a model refitted to one or two pulses of a plant unlike Eq. (3)
  says little about a pulse unlike them);
* falls back to cautious pulses when its model is not to be trusted (a pulse
  missed while its relative error is 50 % or more, or three pulses in a row
  missed by more than 100 %): only the smallest pulse toward the target, and
  only while that cannot end farther from it than the mass is; after one that
  moved less than the rest band (a creep: pre-sliding, a lag), one sample 10 %
  higher, while the model says it moves no farther than the error;
* where that plan finds no pulse that helps at the start of a maneuver (or after a
  pulse planned so), plans one sample for the lowest breakaway force still possible
  (:meth:`ExactController.plan_pulse`): a pulse that did not move proves the breakaway
  lies above its height until the table moves again, so a maneuver after a learned one
  starts and a pulse that crept is evidence, not the end of it;
* on a table whose breakaway is smooth (two one-sample pulses that moved far less than
  Eq. (3) says, or Eq. (3) finding no pulse that helps before any moved the table visibly),
  and from the first pulse on a drive told its mode (the ringing each slip leaves shifts the
  breakaway the next pulse meets), plans its one-sample pulses on the evidence of the
  breakaway (:class:`~papwc.controllers.breakaway.BreakawayEvidence`): for the lowest
  breakaway force still possible, with the excess that moves the table ``trust*|e|`` on a
  curve fitted to its creeps, so that a table breaking away higher moves less; Eq. (3) keeps
  planning on a mode seen ringing (not told) and for the dual-loop kind;
* stops once ``|e|`` is below what a move can achieve (half the encoder
  resolution, or the model's relative error times the move), when even the
  cautious pulse cannot help a rejected model (``model_rejected``), and after
  ``max_pulses`` pulses in one maneuver at the latest, so it cannot
  limit-cycle.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from typing import Any

from ..model.pulse import b_coulomb, bisect_increasing, nearest_increasing, pulse_displacement
from ..model.variables import Variable
from .base import Z_DECIDE, PulseControllerBase, Reason
from .breakaway import BreakawayEvidence
from .budget import HISTORY_MAX, PLAN_RESERVE, Ops
from .exact_fit import PulseModelEstimator
from .sequencer import M_D_EST
from .settings import ControllerSettings

#: The settings the exact-model controller reads besides the shared ones (and ``m_d_est``);
#: the dual-loop controller reads them too.
EXACT_SETTINGS: tuple[Variable, ...] = (
    Variable("c_est", "Initial estimate of the viscous damping", "N.s/m", 0.0, min=0.0,
             max=1e9, nominal=100.0),
    Variable("history", f"Number of pulses kept for the fit (at most {HISTORY_MAX}: a step of "
             "the fit, one Levenberg-Marquardt iteration over them, fits an update's budget "
             "beside the plan)", "", 16, type="Integer", min=1, max=HISTORY_MAX),
    Variable("x_resolution", "Resolution of the position measurement; weights the fit", "m",
             0.0, min=0.0, max=1.0, nominal=1e-6),
    Variable("f_s_tol", "Relative width of the f_s bracket below which no more probing is "
             "done", "1", 0.02, min=0.0, max=1.0, min_open=True),
    Variable("trust0", "Trust region of a new controller: the largest planned displacement as "
             "a fraction of |e|; it grows to 1 while the model predicts well and shrinks when "
             "it does not", "1", 0.5, min=0.0, max=1.0, min_open=True),
)


__all__ = ["ExactController", "PulseModelEstimator"]

#: Bounds of the correction of the model by the nearest earlier pulses (a factor).
_CORRECTION_BOUNDS = (1e-3, 1e3)
#: Relative prediction error beyond which a single-sample pulse near breakaway (below the
#: lowest height known to move and 1.2 times the highest known not to, or f_c) counts as
#: not having moved (while the model otherwise predicts within it).
_USEFUL = 0.2
#: A single-sample pulse near breakaway that moved less than this fraction of the
#: prediction counts as not having moved (the Stribeck evidence PAPWC uses too).
_FAR_LESS = 0.25
#: Consecutive pulses that the model misses by more than 100 % after which it is rejected:
#: only the smallest pulse is made from then on (while it can bring the mass nearer).
_REJECT_AFTER = 3
#: Largest step above the highest height tried (of at least the planned width) while the
#: model has not yet predicted a pulse well (relative).
_TRIED_STEP = 0.1
#: Relative error of the last prediction beyond which planned pulses stay near those tried.
_TRIED_AFTER = 0.5
#: Largest step of a probe of f_s above the highest height known not to move (relative).
_PROBE_STEP = 0.1
#: Relative model error from which, after a missed pulse, only the smallest pulse is made.
_CAUTIOUS = 0.5
#: Largest planned displacement relative to the farthest a pulse in the history moved.
_EXPLORE = 3.0
#: Trust (relative) of a pulse wider than every pulse in the history.
_NEW_WIDTH = 2.0 / 3.0
#: Relative model error (misfit over the history, or of the last prediction) above which
#: a pulse wider than any made is planned with ``_NEW_WIDTH`` of the trust.
_EXACT_ENOUGH = 0.2
#: Step of a one-sample pulse above the highest height that did not move (relative).
_LB_STEP = 0.002
#: One-sample pulses whose implied breakaway forces are kept.
_IMPLIED = 8
#: Smallest relative margin below the lowest breakaway seen, where a new one may lie.
_LB_MARGIN = 0.03
#: Where Eq. (3)'s plan refuses with the error above this many times the resolution
#: and tolerance together, the controller plans on the evidence of the breakaway.
_GIVE_UP_FAR = 10.0
#: One-sample pulses that crept (moved less than _FAR_LESS of Eq. (3)) that show a
#: smooth breakaway.
_CREEPS = 2
#: A move planned on the evidence is at most this many times the farthest it holds.
_EV_EXTRAPOLATE = 2.0
#: Pulses planned on the evidence that fell short of their plan alike (within a factor
#: _STEADY, each below _SHORT of it) after which the planned move is raised, at most
#: _BOOST_MAX times.
_SHORTFALLS = 3
_STEADY = 2.0
_SHORT = 0.5
_BOOST_MAX = 4.0
#: A one-sample move not seen (within 3 standard deviations of a measured displacement)
#: but above this many of them may have been a move: it proves nothing of the breakaway.
_UNSURE = 2.0
#: Relative error expected of a move planned on the evidence of the breakaway.
_EV_PRECISION = 0.5
#: A pulse wider than the widest in the history is at most this many times as wide (and at
#: most one sample wider for narrow ones): at one height its move grows about as the width
#: squared, so at most 2.25 times the widest one's.
_WIDER = 1.5
#: A fit on sliding pulses of one width that lies more than this many prior standard
#: deviations from the settings' estimates is taken as a plant unlike Eq. (3)
#: (``_unlike_eq3``).
_IMPLAUSIBLE = 2.0
#: Largest pulse width searched, samples.
_N_SEARCH_MAX = 1 << 20


def _counted(update: Callable[..., float]) -> Callable[..., float]:
    """``update`` of a kind built on the exact-model law, counted against the update's
    budget (:mod:`.budget`): what the sample leaves of it goes to the refit of Eq. (3) under
    way (:meth:`ExactController.spare`)."""

    @functools.wraps(update)
    def counted(self: ExactController, t: float, x_meas: float, x_ref: float) -> float:
        ops = self.ops
        ops.reset()
        if self.estimator.job:
            self.seq.idle_x = math.nan  # a sample with work to do is not only counted
        try:
            u = update(self, t, x_meas, x_ref)
            self.spare()
        finally:
            ops.end()
        return u

    return counted


class ExactController(PulseControllerBase):
    """Pulse control on the exact model, Eq. (3), with m, f_c, c and f_s learned online.

    Each pulse is planned for the measured error ``e`` (see the module): a
    single pulse of ``trust*|e|`` when that is at least the smallest pulse
    d_small = d(1 sample, ``f_floor``), else a two-pulse move (away by d_small,
    then back) when the trust allows planning the whole way back, else the
    smallest pulse toward the target when it brings the mass nearer. The
    displacement of a planned pulse is the model's, Eq. (3), times the ratio
    measured/model of the earlier pulses of the same width nearest in height
    (interpolated between the nearest below and above). ``f_floor`` is the
    lowest height known to move the mass, or, while the f_s bracket is wider
    than ``f_s_tol`` (relative), the middle of the bracket, so that pulses
    below the known height probe f_s.

    It reads the settings of kind ``exact`` (see
    :data:`papwc.model.controller_settings.CONTROLLER_SETTINGS`): ``c_est`` (initial
    estimate of c, N.s/m), ``history`` (pulses kept for the fit), ``max_pulses``
    (pulses per maneuver after which it stops), ``x_resolution`` (resolution of
    the measurement, m, weights the fit), ``f_s_tol`` (relative width of the
    f_s bracket below which no more probing is done) and ``trust0`` (the trust
    region of a new controller).
    """

    kind = "exact"
    #: The settings this kind reads besides the shared ones (registry: every kind's).
    SETTINGS = EXACT_SETTINGS + (M_D_EST,)
    #: Whether pulses near breakaway may be planned on the evidence of the breakaway.
    evidence_planning = True

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        self.f_s_tol = float(settings.f_s_tol)
        #: The operations of the present update (:mod:`.budget`).
        self.ops = Ops()
        #: Ratios measured/model of the history's pulses under one model (:meth:`correction`;
        #: derived, not state: the key ``None`` holds the model they are for).
        self._ratios: dict = {}
        self.estimator = PulseModelEstimator(
            settings.m_est,
            settings.f_c_est,
            float(settings.c_est),
            T,
            settings.f_p_max,
            history=int(settings.history),
            x_resolution=float(settings.x_resolution),
            ops=self.ops,
        )
        #: Relative errors of the last predictions (a priori, beyond the noise).
        self.errors = [1.0, 1.0]
        #: Consecutive pulses the model missed by more than 100 %.
        self.misses = 0
        #: Relative error of the last single-sample pulse planned right after another
        #: (the way back of a two-pulse move), and whether the last pulse had one sample.
        self.fine_error = 1.0
        self._after_single = False
        #: Highest one-sample height that did not move the table since it last moved, N (0:
        #: none): the breakaway force lies above it until the table moves again.
        self.f_lb = 0.0
        #: Breakaway forces the last one-sample pulses that moved imply, N (newest last): the
        #: highest height that did not move just before, or where its move says.
        self.implied: list[float] = []
        #: The last one-sample pulse planned on that evidence: (n, height N, prediction m).
        self._planned: tuple[int, float, float] = (0, 0.0, 0.0)
        self._planned_last = False
        #: The evidence of the breakaway and of one-sample moves near it.
        self.breakaway = BreakawayEvidence(settings.f_c_est, settings.m_est, T, self.ops)
        #: The lowest breakaway still possible when the present pulse was planned on that
        #: evidence, N (0: the pulse was not).
        self.ev_lo = 0.0
        #: One-sample pulses that moved far less than Eq. (3) says a table breaking away
        #: at once moves (``_CREEPS`` of them make the breakaway smooth).
        self.creeps = 0
        #: Moves over their plans of the last pulses planned on the evidence that moved.
        self.shortfall: list[float] = []
        #: A pulse of this maneuver moved the table visibly.
        self.moved = False
        super().__init__(settings, T)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        # a kind built on this law (the dual loop) that has its own update is counted too
        super().__init_subclass__(**kwargs)
        if "update" in cls.__dict__:
            cls.update = _counted(cls.__dict__["update"])

    @_counted
    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force u (N) over the next sample (:meth:`PulseControllerBase.update`), the
        sample's work counted against its budget (:mod:`.budget`)."""
        return self.seq.update(x_meas, x_ref)

    def reset(self) -> None:
        """Start a new maneuver from rest: the learned model is kept, misses forgotten.

        The table has moved since the last pulse: its breakaway force is drawn anew, so the
        heights that did not move prove nothing any more (``f_lb`` = 0).
        """
        super().reset()
        self.misses = 0
        self.f_lb = 0.0
        self.breakaway.table_moved()
        self.ev_lo = 0.0
        self.moved = False
        self.revision += 1  # f_low may differ

    def spare(self) -> None:
        """The rest of the sample's budget: the refit of Eq. (3) under way goes on (the
        estimates change once it ends)."""
        est = self.estimator
        if est.job:
            est.advance(0)
            if not est.job:
                self.revision += 1

    # -- planning ----------------------------------------------------------------------
    @property
    def f_floor(self) -> float:
        """Lowest height a pulse is planned with, N: known to move, or probing f_s."""
        est = self.estimator
        lower = max(est.f_s_lo, est.f_c_hat)
        floor = est.f_s_hi
        if floor - lower > self.f_s_tol * floor:
            # probe: the middle of the bracket, but no more than _PROBE_STEP above the
            # highest height known not to move (a pulse far above breakaway runs away)
            floor = 0.5 * (lower + floor)
            if est.f_s_lo > 0.0:
                floor = min(floor, est.f_s_lo * (1.0 + _PROBE_STEP))
        # Eq. (3) gives no motion at or below f_c.
        return min(max(floor, est.f_c_hat * (1.0 + 1e-9)), self.settings.f_p_max)

    @property
    def f_low(self) -> float:
        """Lowest height it plans with now, N: just above the lowest breakaway force still
        possible (:meth:`f_b_low`) once there is evidence of it, else ``f_floor``."""
        if self.on_evidence():
            low = self.breakaway.lowest()
            if low > 0.0:
                return min(low, self.settings.f_p_max)
        return self.f_floor

    def on_evidence(self) -> bool:
        """Whether the pulses near breakaway are planned on the evidence of the breakaway:
        it showed smooth, on a machine without a mode seen ringing, with ``safeguards``
        (on a drive told its mode, from its first pulse: :meth:`plan_pulse`)."""
        return (self.evidence_planning and self.breakaway.smooth and self.guarded
                and (self.trust.flexible or not self.seq.flexible()))

    def correction(self, n: int, f: float) -> float:
        """Ratio measured/model of the earlier pulses of width n nearest to height f (N).

        Of the pulses in the history of the width nearest to n (n itself if
        there are any; the longer of two as near), interpolated linearly in the
        height between the nearest pulse below f and the nearest above (the most
        recent of equal heights); the nearest one if all lie on one side; 1
        without history. If the latest pulse has that width, the interpolation
        is shifted to pass through it (it was made where the mass is now: on a
        plant whose friction varies along the way it says most). Outside the
        heights measured at width n the ratio is at least 1 (a pulse is never
        planned longer on the strength of an extrapolation). Bounded to
        ``_CORRECTION_BOUNDS``.
        """
        est = self.estimator
        if not est.pulses:
            return 1.0
        # the pulses of the nearest width (the same, if there is one)
        width = min((abs(n_i - n), -n_i) for n_i, _, _ in est.pulses)
        n_near = -width[1]
        same = [(f_i, d_i) for n_i, f_i, d_i in est.pulses if n_i == n_near]
        m, f_c, c = est.params()
        t = n_near * self.T

        ratios = self._ratios
        if ratios.get(None) != (m, f_c, c, self.T):
            # the ratios hold for this model only (the cache is the plan's, not state)
            ratios.clear()
            ratios[None] = (m, f_c, c, self.T)

        def ratio(point: tuple[float, float]) -> float:
            key = (t, *point)
            if key not in ratios:
                model = self.eq3(point[0], t, m, f_c, c)
                ratios[key] = point[1] / model if model > 0.0 else math.inf
            return ratios[key]

        def interpolated(f: float) -> float:
            below = above = None
            for point in same:
                if point[0] <= f and (below is None or point[0] >= below[0]):
                    below = point
                if point[0] >= f and (above is None or point[0] <= above[0]):
                    above = point
            if below is None or above is None or above[0] == below[0]:
                return ratio(below if above is None else above)
            r0, r1 = ratio(below), ratio(above)
            return r0 + (f - below[0]) / (above[0] - below[0]) * (r1 - r0)

        r = interpolated(f)
        latest = same[-1]
        if est.pulses[-1][0] == n_near:
            # the latest pulse, where the mass is now, says most: the curve goes through it
            r += ratio(latest) - interpolated(latest[0])
        heights = [point[0] for point in same]
        if not min(heights) <= f <= max(heights) or n_near != n:
            # beyond the pulses measured, only a correction to the safe side (less motion
            # than the model predicts is not assumed)
            r = max(r, 1.0)
        lo, hi = _CORRECTION_BOUNDS
        return min(max(r, lo), hi) if r == r else 1.0

    def eq3(self, f: float, t: float, m: float, f_c: float, c: float) -> float:
        """Eq. (3), :func:`~papwc.model.pulse.pulse_displacement` (m), counted in the update's
        operations (:mod:`.budget`)."""
        self.ops.eq3 += 1
        return pulse_displacement(f, t, m, f_c, c)

    def displacement(self, n: int, f: float) -> float:
        """Displacement of a pulse of n samples at height f > 0 (N): the corrected model, m."""
        m, f_c, c = self.estimator.params()
        return self.eq3(f, n * self.T, m, f_c, c) * self.correction(n, f)

    def predict(self, n: int, f_p: float) -> float:
        """Displacement (m, along f_p) the corrected model predicts for the pulse.

        For the pulse just planned on the evidence of the breakaway force, the larger of
        that and of its move if the table broke away at the lowest force still possible.
        """
        if f_p == 0.0:
            return 0.0
        n_plan, f_plan, pred = self._planned
        if n == n_plan and abs(f_p) == f_plan:
            return pred
        return self.displacement(n, abs(f_p))

    def plan_displacement(self, d: float, f_floor: float | None = None) -> tuple[int, float]:
        """Fastest pulse for a displacement d > 0 (m): n samples and height (N, > 0).

        The fewest samples n (<= n_max) for which ``d(n, f_p_max) >= d``; the
        height solves the corrected model at that n. If even ``d(n, f_floor)``
        exceeds d, the pulse of n - 1 samples at f_p_max (which falls short) is
        taken, or, for n = 1, the smallest pulse ``(1, f_floor)``.
        """
        f_max = self.settings.f_p_max
        f_lo = self.f_floor if f_floor is None else f_floor
        n_cap = min(self.n_max, _N_SEARCH_MAX)
        reach_cache: dict[int, float] = {}

        def reach(n: int) -> float:
            if n not in reach_cache:
                reach_cache[n] = self.displacement(n, f_max)
            return reach_cache[n]

        if not d > 0.0 or not math.isfinite(d):
            return 1, f_lo
        # Smallest n with reach(n) >= d: exponential then binary search.
        hi = 1
        while hi < n_cap and reach(hi) < d:
            hi = min(2 * hi, n_cap)
        if reach(hi) < d:
            return n_cap, f_max
        lo = hi // 2  # reach(lo) < d, or lo = 0
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if reach(mid) < d:
                lo = mid
            else:
                hi = mid
        n = hi
        if self.displacement(n, f_lo) > d:
            return (n - 1, f_max) if n > 1 else (1, f_lo)
        return n, self._amplitude(d, n, f_lo, f_max)

    def _amplitude(self, d: float, n: int, f_lo: float, f_hi: float) -> float:
        """Height in [f_lo, f_hi] whose corrected displacement over n samples is closest to d,
        and not beyond it where the correction steps (between the heights of two pulses
        it interpolates): there the highest height below the step."""
        def move(f: float) -> float:
            return self.displacement(n, f)

        f = nearest_increasing(move, d, f_lo, f_hi)
        if f > f_lo and move(f) > d * (1.0 + 1e-12):
            f = bisect_increasing(move, d, f_lo, f_hi)[0]
        return f

    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Pulse for the error e (m): :meth:`_plan`, or, where that finds no pulse that
        helps, one planned on the evidence of the breakaway force.

        When the model's plan refuses (``no_move_helps``, ``model_rejected``) while
        ``|e|`` exceeds half a count and there is evidence of where the table breaks
        away (:meth:`f_b_low`), one sample toward the target is planned for the lowest
        breakaway force still possible: the height that moves ``trust*|e|`` if the table
        broke away there (:meth:`lowest_breakaway_move`), and above the highest height
        that did not move since the table last moved (``f_lb``). A pulse that did not
        move raises ``f_lb``; so a maneuver is not given up while such a pulse can help.
        On a drive told its mode (``f_mode`` > 0) the one-sample pulses are planned so from
        the first (:meth:`_plan_smooth`); on a mode seen ringing, by Eq. (3).
        """
        self._planned_last = self._planned[0] == 1
        self._planned = (0, 0.0, 0.0)
        self.ev_lo = 0.0
        if not self.guarded or not math.isfinite(e):
            return self._plan(e)
        if self.trust.flexible and self.evidence_planning:
            # a drive told its mode: the ringing each slip leaves shifts the breakaway the
            # next pulse meets, as a breakaway drawn anew at every stick does; its one-sample
            # pulses are planned for the lowest breakaway still possible from the first
            self.breakaway.smooth = True
        if self.on_evidence():
            return self._plan_smooth(e)
        if self.seq.flexible():
            # a mode seen ringing: a pulse's move depends on the ringing it meets more
            # than on the breakaway; Eq. (3) plans, the sequencer shrinks the pulses
            return self._plan_eq3(e)
        n, f_p = self._plan_eq3(e)
        if ((f_p == 0.0 and self.seq.refusal in (Reason.NO_MOVE_HELPS, Reason.MODEL_REJECTED))
                or (f_p != 0.0 and self.seq.may_end_farther(e, f_p, self.reach(n, f_p)))):
            if (self.evidence_planning and not self.moved
                    and abs(e) > _GIVE_UP_FAR * (self.estimator.x_resolution
                                                 + self.settings.tolerance)):
                # Eq. (3) finds no pulse that helps before any has moved the table
                # visibly while it is far from the target: the table is not Eq. (3)'s;
                # plan on the evidence of the breakaway from now on
                self.breakaway.smooth = True
                self._planned = (0, 0.0, 0.0)
                return self._plan_smooth(e)
        return n, f_p

    def _plan_eq3(self, e: float) -> tuple[int, float]:
        """:meth:`_plan`, or, where it refuses at the start of a maneuver (or right after a
        pulse planned so), one sample for the lowest breakaway force :meth:`f_b_low`."""
        n, f_p = self._plan(e)
        if f_p != 0.0:
            return n, f_p
        if (self.seq.refusal not in (Reason.NO_MOVE_HELPS, Reason.MODEL_REJECTED)
                or abs(e) <= max(0.5 * self.estimator.x_resolution, self.settings.tolerance)
                or not (self.pulses == 0 or self._planned_last)):
            return n, f_p
        f_b = self.f_b_low()
        if not f_b > 0.0:
            return n, f_p
        f_max = self.settings.f_p_max
        f_min = min(f_b * (1.0 + _LB_STEP), f_max)
        goal = self.trust() * abs(e)

        def move(h: float) -> float:
            return self.lowest_breakaway_move(h, f_b)

        if move(f_min) > goal:
            return n, f_p  # even the lowest such pulse would go beyond the trust region
        # the highest height that moves at most trust*|e| if the table broke away at f_b
        f = f_max if move(f_max) <= goal else bisect_increasing(move, goal, f_min, f_max)[0]
        self._planned = (1, f, move(f))
        return 1, math.copysign(f, e)

    def _plan_smooth(self, e: float) -> tuple[int, float]:
        """Pulse for the error e (m) on a table whose breakaway is smooth.

        A move the model plans wider than one sample is the model's (Eq. (3) with its
        correction, as on any table, wider than any made only within ``_EXPLORE`` times
        the farthest move). A one-sample pulse is planned on the evidence of the
        breakaway (:meth:`_evidence_height`).
        """
        if self.budget_spent():
            self.seq.refusal = Reason.PULSE_BUDGET
            return 1, 0.0
        self.seq.refusal = Reason.NO_MOVE_HELPS
        if abs(e) <= max(0.5 * self.estimator.x_resolution, self.settings.tolerance):
            return 1, 0.0
        toward = math.copysign(1.0, e)
        n, f_p, goal = self._plan_width(self.trust() * abs(e), self.f_floor)
        if n > 1:
            return n, toward * f_p
        return 1, toward * self._evidence_height(goal, f_p)

    def _plan_width(self, goal: float, f_lo: float) -> tuple[int, float, float]:
        """The fastest pulse for ``goal`` (m) above ``f_lo`` (N), and the goal it was planned
        for: wider than any pulse in the history (where the model extrapolates), for at most
        ``_EXPLORE`` times the farthest any moved, and with ``_NEW_WIDTH`` of it while the
        model's misfit or its last prediction's error is above ``_EXACT_ENOUGH``."""
        est = self.estimator
        n, f_p = self.plan_displacement(goal, f_lo)
        if est.pulses and n > est.widest:
            goal = self._explored(goal)
            if max(est.rel_misfit, self.errors[-1]) > _EXACT_ENOUGH:
                goal *= _NEW_WIDTH
            n, f_p = self.plan_displacement(goal, f_lo)
            if n > est.widest and self._unlike_eq3():
                # a fit to sliding pulses of one width cannot tell how the move grows with
                # the width (a lag, Stribeck make it grow faster than Eq. (3)): at most
                # _WIDER times as wide (one sample wider) as the widest made, no higher than
                # the highest of that width, as high as the model says for the goal below that
                n = min(n, max(est.widest + 1, int(_WIDER * est.widest)))
                f_top = max((abs(f) for n_i, f, _ in est.pulses if n_i == est.widest),
                            default=self.settings.f_p_max)
                f_p = (f_top if self.displacement(n, f_top) < goal
                       else self._amplitude(goal, n, min(f_lo, f_top), f_top))
        return n, f_p, goal

    def _unlike_eq3(self) -> bool:
        """Whether the fit rests on sliding pulses of one width and lies more than
        ``_IMPLAUSIBLE`` prior standard deviations from the settings' estimates: a plant
        unlike Eq. (3) (a lag, Stribeck) fitted by a mass, friction and viscous damping it
        does not have (measured: c 4,000-18,000 N.s/m, f_c 14-49 N for a table of 700 and
        100), whose moves at other widths it does not know."""
        est = self.estimator
        if len({n_i for n_i, _, _ in est.pulses if n_i > 1}) >= 2:
            return False
        return est.prior_distance() > _IMPLAUSIBLE

    def _evidence_height(self, goal: float, f_model: float) -> float:
        """Height (N) of one sample that moves the table at most ``goal`` (m), planned for
        the lowest breakaway force still possible (:meth:`BreakawayEvidence.lowest`).

        Its excess over that force moves the table ``goal`` on the curve of the evidence
        that moves it least far for it (:meth:`BreakawayEvidence.plan_excess`; before the
        evidence has a curve, half of that on Eq. (2) with the friction at the breakaway
        force): if the table breaks away higher, the pulse moves it less. A pulse that does
        not move raises that lowest force until the table moves. A move beyond
        ``_EV_EXTRAPOLATE`` times the farthest creep the evidence holds is planned by the
        model (``f_model``, N) where it learned one-sample pulses, no higher than the
        creeps' curve allows; else no farther than that reach.
        """
        ev = self.breakaway
        low = ev.lowest()
        if not low > 0.0:
            est = self.estimator
            low = max(est.f_s_lo, est.f_c_hat)
        planned = goal
        goal *= self._boost()
        reach = _EV_EXTRAPOLATE * ev.farthest()
        if ev.fitted and goal > reach:
            # beyond the creeps the evidence holds: as far as Eq. (3) and the one-sample
            # pulses it learned say, where it learned some, but no higher than the creeps'
            # curve allows; else no farther than the evidence reaches
            if any(n_i == 1 for n_i, _, _ in self.estimator.pulses):
                f = min(low + ev.plan_excess(goal), abs(f_model))
                f = max(f, low + ev.plan_excess(reach))
            else:
                f = low + ev.plan_excess(reach)
                planned = min(planned, reach)
        else:
            f = low + ev.plan_excess(goal)
        f = min(f, self.settings.f_p_max)
        self.ev_lo = low
        self._planned = (1, f, planned)
        return f

    def _boost(self) -> float:
        """Factor on the move planned on the evidence: the recent ones all fell as short of
        their plan (within ``_STEADY`` of each other, and below ``_SHORT``) and no pulse
        has failed to move the table (pre-sliding: it creeps wherever it is pushed, the same
        each time) -- the planned move over the longest of their shares of it, at most
        ``_BOOST_MAX``; else 1."""
        shares = self.shortfall
        if self.breakaway.held or len(shares) < _SHORTFALLS or not min(shares) > 0.0:
            return 1.0
        if max(shares) > _SHORT or max(shares) > _STEADY * min(shares):
            return 1.0
        return min(1.0 / max(shares), _BOOST_MAX)

    def f_b_low(self) -> float:
        """The lowest breakaway force still possible now, N (0: no evidence yet).

        ``f_lb`` (a one-sample pulse at that height did not move since the table last
        moved); right after a move (the breakaway is drawn anew), the lowest of the
        breakaway forces the last one-sample pulses implied (:attr:`implied`), lowered
        by their relative spread (at least ``_LB_MARGIN``); without those, the same from
        the fit's bracket and f_c.
        """
        if self.f_lb > 0.0:
            return self.f_lb
        lo = min(self.implied, default=0.0)
        hi = max(self.implied, default=0.0)
        if not lo > 0.0:
            # no breakaway seen between two heights: below the fit's bracket and f_c
            est = self.estimator
            lo = hi = max(est.f_s_lo, est.f_c_hat) if est.pulses else 0.0
            if not lo > 0.0:
                return 0.0
        # the breakaway is drawn anew: below the lowest seen by the spread seen
        spread = max((hi - lo) / hi, _LB_MARGIN)
        return lo * (1.0 - spread)

    def lowest_breakaway_move(self, f: float, f_b: float) -> float:
        """Displacement of one sample at height f (N) if the table broke away at f_b (N), m.

        Eq. (2): the friction at f_b throughout (at the low speeds of a pulse near
        breakaway the friction stays near the breakaway force), no viscous damping, and the
        smaller of the learned mass and ``m_est`` (a fit fooled by a plant unlike Eq. (3)
        does not make the move look shorter than it may be).
        """
        m = min(self.estimator.m_hat, self.settings.m_est)
        return self.eq3(f, self.T, m, f_b, 0.0) if f > f_b else 0.0

    def implied_breakaway(self, f: float, d: float) -> float:
        """Breakaway force (N) at which one sample at f (N) moves d > 0 (m) by
        :meth:`lowest_breakaway_move` (0 if even a breakaway at 0 does not explain d)."""
        lo, hi = 1e-9 * f, f
        if self.lowest_breakaway_move(f, lo) <= d:
            return 0.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if self.lowest_breakaway_move(f, mid) > d:
                lo = mid
            else:
                hi = mid
        return lo

    def _plan(self, e: float) -> tuple[int, float]:
        """Pulse for the error e (m): toward the target, or away first for a two-pulse move.

        When ``trust*|e|`` is below the smallest pulse, a single sample below
        ``f_floor`` (and above the highest height known not to move) that the
        model says moves ``trust*|e|`` is tried first: it probes f_s.

        While the model is not to be trusted (a missed pulse with a relative
        error of 50 % or more, or three pulses in a row missed by more than
        100 %) only the smallest pulse toward the target is planned, if it is
        predicted to move at most abs(e); after a one-sample pulse that moved less
        than the rest band, one sample ``1 + _PROBE_STEP`` times as high, if it
        is predicted to move at most abs(e).

        Refuses (height 0; the controller stops, see :attr:`refusal`) when e is
        not finite, when ``max_pulses`` pulses have been applied in this
        maneuver, when a rejected model's smallest pulse cannot help
        (``model_rejected``), or when no pulse can bring the mass nearer: ``|e|`` below what a
        move can achieve (half the measurement resolution, or the error the
        model's relative error implies for the pulses of the move), or below
        half the smallest pulse with too little trust for a two-pulse move.
        """
        if not math.isfinite(e):
            self.seq.refusal = Reason.INVALID_MEASUREMENT
            return 1, 0.0
        if self.budget_spent():
            self.seq.refusal = Reason.PULSE_BUDGET
            return 1, 0.0
        est = self.estimator
        f_lo = self.f_floor
        d = abs(e)
        d_small = self.displacement(1, f_lo)
        trust = self.trust()
        rel = max(min(est.rel_misfit, max(self.errors)), 1e-9)
        toward = math.copysign(1.0, e)
        self.seq.refusal = Reason.NO_MOVE_HELPS
        if self.misses >= _REJECT_AFTER or (self.misses and rel >= _CAUTIOUS):
            # The model is not to be trusted: only the smallest pulse toward the target,
            # and only while it lands no farther than now even if it moves twice as far
            # as the pulses of that height moved so far.
            n_last, f_last = self.seq.last_pulse
            if (n_last == 1 and abs(f_last) >= f_lo and self.pulses
                    and abs(self.seq.last_d) <= self.rest.band):
                # the last cautious pulse did not move measurably (a creep): 10 % higher,
                # while the model says it moves no farther than the error
                f_up = min(abs(f_last) * (1.0 + _PROBE_STEP), self.settings.f_p_max)
                if self.displacement(1, f_up) <= d:
                    return 1, toward * f_up
            if d_small <= d:
                return 1, toward * f_lo
            if self.misses >= _REJECT_AFTER:
                self.seq.refusal = Reason.MODEL_REJECTED
            return 1, 0.0
        if trust * d >= d_small:
            if d <= max(0.5 * est.x_resolution, rel * d):
                return 1, 0.0
            n, f_p, goal = self._plan_width(trust * d, f_lo)
            n, f_p = self._within_tried(n, f_p, goal, f_lo)
            return n, toward * f_p
        if d_small <= 1.5 * d or abs(d_small - d) <= rel * d_small:
            return 1, toward * f_lo  # the smallest pulse toward: it lands within d/2
        two = d + d_small
        # the way back is planned from where the way out ended: its error is what counts
        rel_back = max(min(rel, self.fine_error), 1e-9)
        if (trust * two >= d_small and d > max(0.5 * est.x_resolution, rel_back * two)
                and d + d_small / trust <= abs(self.seq.e0)):
            if self.pulses + 2 > self.max_pulses:
                self.seq.refusal = Reason.PULSE_BUDGET
                return 1, 0.0
            return 1, -toward * f_lo  # away by d_small; back by d + d_small next
        # A height below the lowest known to move may move the mass less: a probe of f_s
        # toward the target, planned to move trust*|e| if it moves at all.
        f_probe_lo = max(est.f_s_lo, est.f_c_hat) * (1.0 + 1e-9)
        if f_probe_lo < f_lo:
            if self.displacement(1, f_probe_lo) < trust * d:
                return 1, toward * self._amplitude(trust * d, 1, f_probe_lo, f_lo)
            # the smallest pulse that may move: just above the highest height that did not
            f_probe = min(f_lo, max(est.f_s_lo * (1.0 + 2.0 * self.f_s_tol), f_probe_lo))
            if f_probe < f_lo and self.displacement(1, f_probe) < 2.0 * d:
                return 1, toward * f_probe  # (moving as predicted, it leaves |e| smaller)
        if d_small < 2.0 * d and abs(d_small - d) < d:
            return 1, toward * f_lo
        return 1, 0.0

    def _explored(self, d: float) -> float:
        """d (m), at most ``_EXPLORE`` times the farthest any pulse in the history moved."""
        moved = [d_i for _, _, d_i in self.estimator.pulses]
        return min(d, _EXPLORE * max(moved)) if moved else d

    def _within_tried(self, n: int, f_p: float, d: float, f_lo: float) -> tuple[int, float]:
        """The planned pulse (n samples, height f_p > 0 N, for d m), kept near those tried.

        After a pulse the model missed by more than ``_TRIED_AFTER``, a
        pulse is no wider than the widest in the history and no higher than
        ``1 + _TRIED_STEP`` times the highest of at least its width (but at
        least ``f_lo``): on a plant unlike Eq. (3) a model fitted to one or two
        pulses says little about a pulse unlike them.
        """
        est = self.estimator
        if self.errors[-1] <= _TRIED_AFTER or not est.pulses:
            return n, f_p
        if n > est.widest:
            n = est.widest
            f_p = self._amplitude(d, n, f_lo, self.settings.f_p_max)
        f_seen = max(f_i for n_i, f_i, _ in est.pulses if n_i >= n)
        return n, min(f_p, max(f_lo, f_seen * (1.0 + _TRIED_STEP)))

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Take the measured displacement d (m) of the pulse (n samples, f_p N) into the model.

        A pulse that moved the table measurably (beyond 3 standard deviations of a measured
        displacement and half the resolution) ends the proof of ``f_lb`` (the breakaway
        is drawn anew at the next stop); a one-sample pulse that moved adds the breakaway
        force it implies to :attr:`implied` (``f_lb`` if above 0, else from its move by
        :meth:`implied_breakaway`). A one-sample pulse that did not move, or one planned
        on the evidence that moved less than ``_FAR_LESS`` of its prediction (it crept:
        pre-sliding), raises ``f_lb`` to its height.
        """
        pred = self.seq.pred
        d_along = d if f_p > 0.0 else -d
        est = self.estimator
        est.meas_sigma = self.rest.sigma_move()
        noise = Z_DECIDE * est.meas_sigma
        ev = self.breakaway
        visible = math.isfinite(d_along) and abs(d_along) > max(noise, 0.5 * est.x_resolution)
        self.moved = self.moved or visible
        if n == 1 and math.isfinite(f_p) and math.isfinite(d_along):
            moved = visible and d_along > 0.0
            crept = moved and d_along < _FAR_LESS * self._eq3_reach(abs(f_p))
            # a move too short to tell from the noise may have been one: it proves nothing of
            # the breakaway (the table may have stuck anew, lower)
            unsure = not moved and d_along > _UNSURE * noise / Z_DECIDE
            if (moved and not crept) or unsure:
                ev.table_moved()  # a long move (the model's), or one that may have been
            else:
                ev.observe(abs(f_p), d_along, moved, self.ev_lo)
            if crept and not ev.smooth:
                # far less than a table that breaks away at once moves: a smooth
                # breakaway (Stribeck friction, a lag), seen twice (once may be noise)
                self.creeps += 1
                ev.smooth = self.creeps >= _CREEPS
            if self.ev_lo > 0.0:
                self.ev_lo = 0.0
                self._after_single = True
                if pred > 0.0 and moved:
                    self.shortfall = (self.shortfall + [d_along / pred])[-_SHORTFALLS:]
                if moved and not crept:
                    # a long move: Eq. (3) and its correction learn it
                    est.observe(n, f_p, d, PLAN_RESERVE)
                return
        elif visible:
            ev.table_moved()
        crept = (n == 1 and self._planned[0] == 1 and 0.0 < d_along < _FAR_LESS * pred)
        if math.isfinite(d_along) and math.isfinite(f_p):
            if crept:
                # far less than even a breakaway at f_b_low would move it: pre-sliding or a
                # creep below breakaway, evidence that the breakaway lies above (a probe)
                self.f_lb = max(self.f_lb, abs(f_p))
            elif visible:
                if n == 1 and d_along > 0.0:
                    # broke away between f_lb and f_p, or where its move says
                    f_b = self.f_lb or self.implied_breakaway(abs(f_p), d_along)
                    if f_b > 0.0:
                        self.implied = (self.implied + [f_b])[-_IMPLIED:]
                self.f_lb = 0.0
            elif n == 1:
                self.f_lb = max(self.f_lb, abs(f_p))
        if pred > 0.0 and math.isfinite(d_along) and d_along > max(noise, self.rest.band):
            # (a pulse that did not move probed f_s: it says nothing of the model)
            r = max(abs(d_along - pred) - noise, 0.0) / pred
            near = n == 1 and abs(f_p) < min(est.f_s_hi, 1.2 * max(est.f_s_lo, est.f_c_hat))
            if near and (d_along < _FAR_LESS * pred
                         or (r > _USEFUL and max(self.errors) <= _USEFUL)):
                # A height near breakaway and below the lowest known to move, which moved
                # far less than predicted, or unlike every prediction that held so far
                # (Stribeck: friction kept up at low speed; pre-sliding): no use for
                # planning. It counts as one that did not move.
                est.observe(n, f_p, 0.0)
                return
            self.errors = [self.errors[-1], min(r, 1e3)]
            self.misses = self.misses + 1 if r > 1.0 else 0
            if n == 1 and self._after_single:
                self.fine_error = min(r, 1e3)
        self._after_single = n == 1
        est.observe(n, f_p, d, PLAN_RESERVE)

    def precision(self, e: float) -> float:
        """Relative error expected of the move for e (m): the last two prediction errors.

        1 for a two-pulse move (its first pulse goes away by the smallest pulse,
        whatever e is; the error counts when the way back is planned).
        """
        if self.on_evidence():
            return _EV_PRECISION
        if abs(e) < self.displacement(1, self.f_floor) / self.trust():
            return 1.0
        return min(max(self.errors), 0.1)

    def _eq3_reach(self, f: float) -> float:
        """Move (m) of one sample at f (N) on Eq. (3), the larger with the fitted and with
        the initial estimates: what a table that breaks away at once moves at least."""
        s = self.settings
        prior = self.eq3(f, self.T, s.m_est, s.f_c_est, float(s.c_est))
        return max(self.estimator.displacement(f, 1), prior)

    def estimates(self) -> dict[str, float]:
        """``b_hat`` (Eq. (4) at f_p_max, m/s**2), ``f_c_hat``, ``m_hat``, ``c_hat``, f_s bracket.

        Units: m/s**2, N, kg, N.s/m, N; ``trust`` (1).
        """
        est = self.estimator
        m, f_c, c = est.params()
        f_p = self.settings.f_p_max
        return {
            "b_hat": b_coulomb(f_p, m, f_c),
            "f_c_hat": f_c,
            "m_hat": m,
            "c_hat": c,
            "f_s_lo": est.f_s_lo,
            "f_s_hi": est.f_s_hi,
            "trust": self.trust.value,
        }

    def law_state(self) -> dict[str, Any]:
        """The prediction errors, misses, and the estimator's state (``estimator.*``)."""
        est = self.estimator
        out = {**super().law_state(), "errors": list(self.errors), "misses": self.misses,
               "meas_sigma": est.meas_sigma, "fine_error": self.fine_error,
               "after_single": int(self._after_single), "f_lb": self.f_lb,
               "implied": list(self.implied), "planned": [float(v) for v in self._planned],
               "ev_lo": self.ev_lo, "creeps": self.creeps, "moved": int(self.moved),
               "shortfall": list(self.shortfall)}
        out.update({f"breakaway.{k}": v for k, v in self.breakaway.state().items()})
        out.update({f"estimator.{k}": v for k, v in est.state().items()})
        return out

    def set_law_state(self, values: Mapping[str, Any]) -> None:
        super().set_law_state(values)
        errors = [float(v) for v in values["errors"]]
        if len(errors) != 2:
            raise ValueError(f"law.errors holds {len(errors)} numbers, not 2")
        self.errors = errors
        self.misses = int(values["misses"])
        self.f_lb = float(values["f_lb"])
        implied = [float(v) for v in values["implied"]]
        if len(implied) > _IMPLIED:
            raise ValueError(f"law.implied holds {len(implied)} numbers, at most {_IMPLIED}")
        self.implied = implied
        n_plan, f_plan, pred = (float(v) for v in values["planned"])
        self._planned = (int(n_plan), f_plan, pred)
        self.ev_lo = float(values["ev_lo"])
        self.creeps = int(values["creeps"])
        self.moved = bool(values["moved"])
        shortfall = [float(v) for v in values["shortfall"]]
        if len(shortfall) > _SHORTFALLS:
            raise ValueError(f"law.shortfall holds {len(shortfall)} numbers, at most "
                             f"{_SHORTFALLS}")
        self.shortfall = shortfall
        self.breakaway.set_state({k.split(".", 1)[1]: v for k, v in values.items()
                                  if k.startswith("breakaway.")})
        self.estimator.meas_sigma = float(values["meas_sigma"])
        self.fine_error, self._after_single = (float(values["fine_error"]),
                                               bool(values["after_single"]))
        self.estimator.set_state({k.split(".", 1)[1]: v for k, v in values.items()
                                  if k.startswith("estimator.")})
