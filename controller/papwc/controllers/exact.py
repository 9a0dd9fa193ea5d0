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
  measurement's resolution and noise (:class:`~.exact_fit.PulseModelEstimator`), and
  brackets the breakaway force f_s between the highest amplitude that did not move the
  mass and the lowest that did;
* plans inside a trust region: a single pulse moves by ``trust*abs(e)``, where the trust
  (``trust0`` at first, at most 1) doubles after every pulse that moved as predicted and
  shrinks after one that moved more, so a model fooled by noise or by a plant unlike
  Eq. (3) plans short pulses near the breakaway force instead of long ones;
* plans by one of three policies (:mod:`.exact_policies`), each with its own state, picked
  by one rule (:meth:`ExactController.choose`): the fitted model
  (:class:`~.exact_policies.FittedModel`: the fastest pulse for ``trust*abs(e)``, a two-pulse
  move below its smallest pulse, probes of the breakaway bracket, pulses wider than any
  made only within limits); the cautious policy after pulses the model missed
  (:class:`~.exact_policies.Cautious`: the smallest pulse toward the target, while it cannot
  end farther than the table is); the evidence of the breakaway
  (:class:`~.exact_policies.Evidence`: one sample for the lowest breakaway force still
  possible, on the move curve of its creeps once the breakaway showed smooth -- two
  one-sample pulses that moved far less than Eq. (3) says, a refusal far from the target
  before any pulse moved the table visibly, or a drive told its mode -- and where the model
  finds no pulse that helps at the start of a maneuver);
* works within half its sample period: every update's work is counted in operations
  against a budget (:mod:`.budget`), and the refit of Eq. (3) after a pulse goes on over
  the updates that follow where it does not fit the one that learned the pulse;
* stops once ``abs(e)`` is below what a move can achieve (half the encoder resolution, or
  the model's relative error times the move), when even the cautious pulse cannot help a
  rejected model (``model_rejected``), and once the maneuver has taken ``settle_timeout``
  seconds (its time budget, ``pulse_budget``) at the latest, so it cannot limit-cycle.

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
from .budget import HISTORY_MAX, PLAN_RESERVE, Ops
from .exact_fit import PulseModelEstimator
from .exact_policies import (
    FAR_LESS,
    PROBE_STEP,
    Cautious,
    Evidence,
    FittedModel,
    Plan,
    Refusal,
)
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
    Variable("x_resolution", "Resolution of the position measurement (the encoder's count; "
             "0: ideal): weights the exact-model controller's fit; the PID's and the hybrid's "
             "decisions at rest allow for the rounding of the readings", "m",
             0.0, min=0.0, max=1.0, nominal=1e-6),
    Variable("f_s_tol", "Relative width of the f_s bracket below which no more probing is "
             "done", "1", 0.02, min=0.0, max=1.0, min_open=True),
    Variable("trust0", "Trust region of a new controller: the largest planned displacement as "
             "a fraction of |e|; it grows to 1 while the model predicts well and shrinks when "
             "it does not", "1", 0.5, min=0.0, max=1.0, min_open=True),
    Variable("f_b_floor", "The lowest breakaway force a fresh stick may have, as the height of "
             "one sample from rest that reaches it (the identified stiction band's low end, "
             "papwc identify; papwc.identify.plant_model.PlantModel.controller_band): the floor "
             "of the staircase of one-sample pulses, which are then planned on the evidence of "
             "the breakaway from the first (0: learned from the moves)", "N", 0.0, min=0.0,
             max=1e9, nominal=100.0),
    Variable("f_b_step", "The stiction band's width above f_b_floor, as such heights: no "
             "one-sample pulse is planned higher above the lowest breakaway still possible "
             "(0: no limit)", "N", 0.0, min=0.0, max=1e9, nominal=10.0),
    Variable("settle_timeout", "Time budget of a maneuver: once this long after its start "
             "(the first sample after a reset) without settling, the controller fires no "
             "further pulse and stops (outcome_reason pulse_budget); max_pulses does not "
             "bound this kind", "s", 10.0, min=0.0, min_open=True, max=1e6, nominal=1.0),
)


__all__ = ["ExactController", "PulseModelEstimator"]

#: Bounds of the correction of the model by the nearest earlier pulses (a factor).
_CORRECTION_BOUNDS = (1e-3, 1e3)
#: Relative prediction error beyond which a single-sample pulse near breakaway (below the
#: lowest height known to move and 1.2 times the highest known not to, or f_c) counts as
#: not having moved (while the model otherwise predicts within it).
_USEFUL = 0.2
#: Where Eq. (3)'s plan refuses with the error above this many times the resolution
#: and tolerance together, the controller plans on the evidence of the breakaway.
_GIVE_UP_FAR = 10.0
#: Relative error expected of a move planned on the evidence of the breakaway.
_EV_PRECISION = 0.5
#: Largest pulse width searched, samples.
_N_SEARCH_MAX = 1 << 20
#: The refusals of the fitted or cautious plan after which the evidence may plan.
_HELPLESS = (Reason.NO_MOVE_HELPS, Reason.MODEL_REJECTED)


def _counted(update: Callable[..., float]) -> Callable[..., float]:
    """``update`` of a kind built on the exact-model law, counted against the update's
    budget (:mod:`.budget`): what the sample leaves of it goes to the refit of Eq. (3) under
    way (:meth:`ExactController.spare`)."""

    @functools.wraps(update)
    def counted(self: ExactController, t: float, x_meas: float, x_ref: float) -> float:
        ops = self.ops
        ops.reset()
        self.samples += 1
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

    Each pulse is planned for the measured error ``e`` by one of its policies
    (:attr:`fitted`, :attr:`cautious`, :attr:`evidence`; the rule: :meth:`choose`). The
    displacement of a planned pulse is the model's, Eq. (3), times the ratio
    measured/model of the earlier pulses of the same width nearest in height
    (interpolated between the nearest below and above; :meth:`displacement`). ``f_floor``
    is the lowest height known to move the mass, or, while the f_s bracket is wider
    than ``f_s_tol`` (relative), the middle of the bracket, so that pulses
    below the known height probe f_s.

    It reads the settings of kind ``exact`` (see
    :data:`papwc.model.controller_settings.CONTROLLER_SETTINGS`): ``c_est`` (initial
    estimate of c, N.s/m), ``history`` (pulses kept for the fit), ``settle_timeout``
    (s, the time of a maneuver after which it fires no further pulse), ``x_resolution``
    (resolution of the measurement, m, weights the fit), ``f_s_tol`` (relative width of the
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
        #: The identified stiction band as one-sample heights, N: its floor and width (0:
        #: not given; ``f_b_floor``, ``f_b_step``). The evidence policy plans with it
        #: (:meth:`Evidence.lowest_breakaway <.exact_policies.Evidence.lowest_breakaway>`).
        self.band = (float(settings.f_b_floor), float(settings.f_b_step))
        #: The operations of the present update (:mod:`.budget`).
        self.ops = Ops()
        #: Samples (updates) since the maneuver started: its time is ``samples*T``.
        self.samples = 0
        self.settle_timeout = float(settings.settle_timeout)
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
        super().__init__(settings, T)
        #: The three ways of planning (:mod:`.exact_policies`), each with its state.
        self.fitted = FittedModel(self)
        self.cautious = Cautious(self)
        self.evidence = Evidence(self)
        self.policies = (self.fitted, self.cautious, self.evidence)

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
        """Start a new maneuver from rest: the learned model is kept, each policy starts
        anew (the cautious one forgets its misses, the evidence the heights that did not
        move: the table has moved since, its breakaway force is drawn anew)."""
        super().reset()
        self.samples = 0
        for policy in self.policies:
            policy.reset()
        self.revision += 1  # f_low may differ

    def budget_spent(self, ahead: float = 0.0) -> bool:
        """Whether this maneuver's time budget (``settle_timeout``, s, from its start) is
        spent, or will be within ``ahead`` seconds: a maneuver that has not settled by then
        fires no further pulse."""
        return (self.samples * self.T + ahead) >= self.settle_timeout

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
            # probe: the middle of the bracket, but no more than PROBE_STEP above the
            # highest height known not to move (a pulse far above breakaway runs away)
            floor = 0.5 * (lower + floor)
            if est.f_s_lo > 0.0:
                floor = min(floor, est.f_s_lo * (1.0 + PROBE_STEP))
        # Eq. (3) gives no motion at or below f_c.
        return min(max(floor, est.f_c_hat * (1.0 + 1e-9)), self.settings.f_p_max)

    @property
    def f_low(self) -> float:
        """Lowest height it plans with now, N: just above the lowest breakaway force still
        possible (:meth:`Evidence.f_b_low <.exact_policies.Evidence.f_b_low>`) once there is
        evidence of it, else ``f_floor``."""
        if self.on_evidence():
            low = self.evidence.lowest_breakaway()
            if low > 0.0:
                return min(low, self.settings.f_p_max)
        return self.f_floor

    def on_evidence(self) -> bool:
        """Whether the pulses near breakaway are planned on the evidence of the breakaway:
        it showed smooth, on a machine without a mode seen ringing, with ``safeguards``
        (on a drive told its mode, from its first pulse: :meth:`plan_pulse`); told the
        stiction band (``f_b_floor``), from the first pulse too."""
        return (self.evidence_planning
                and (self.evidence.breakaway.smooth or self.band[0] > 0.0) and self.guarded
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
        n_plan, f_plan, pred = self.evidence.planned
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
        """Pulse for the error e (m): the plan of :meth:`choose`, or (1, 0.0) with the
        refusal's reason in ``seq.refusal``."""
        self.evidence.begin()
        choice = self.choose(e)
        if isinstance(choice, Refusal):
            self.seq.refusal = choice.reason
            return 1, 0.0
        return choice.n, choice.f_p

    def choose(self, e: float) -> Plan | Refusal:
        """The rule that picks the policy (:mod:`.exact_policies`) and its plan for e (m).

        1. On a drive told its mode (``f_mode`` > 0, with ``safeguards``) the breakaway
           counts as smooth from the first pulse: the ringing each slip leaves shifts the
           breakaway the next pulse meets, as a breakaway drawn anew at every stick does.
        2. Refused: a reading not finite (``invalid_measurement``), the maneuver's pulse
           budget spent (``pulse_budget``).
        3. On the evidence's curve (:meth:`on_evidence`): the evidence plans.
        4. Else the cautious policy where the model is not to be trusted
           (:meth:`Cautious.active <.exact_policies.Cautious.active>`), else the fitted
           model. Without ``safeguards`` that plan stands.
        5. Where it refuses (``no_move_helps``, ``model_rejected``), the evidence plans one
           sample for the lowest breakaway force still possible, at the start of a maneuver
           or right after such a pulse (:meth:`Evidence.start
           <.exact_policies.Evidence.start>`). On a mode seen ringing (not told) that plan
           stands: a pulse's move there depends on the ringing it meets more than on the
           breakaway, and the sequencer shrinks the pulses.
        6. Where the plan still refuses, or may end farther than the maneuver started, before
           any pulse of this maneuver has moved the table visibly and with the error above
           ``_GIVE_UP_FAR`` times the resolution and tolerance, the table is not Eq. (3)'s:
           the breakaway counts as smooth from now on and the evidence plans on its curve.
        """
        ev = self.evidence
        finite = math.isfinite(e)
        if self.guarded and finite and self.trust.flexible and self.evidence_planning:
            ev.breakaway.smooth = True
        if not finite:
            return Refusal(Reason.INVALID_MEASUREMENT)
        if self.budget_spent():
            return Refusal(Reason.PULSE_BUDGET)
        if self.on_evidence():
            return ev.plan(e)
        model = self.cautious if self.cautious.active(self.fitted.rel()) else self.fitted
        choice = model.plan(e)
        if not self.guarded:
            return choice
        if isinstance(choice, Refusal) and choice.reason in _HELPLESS:
            choice = ev.start(e, choice)
        if self.seq.flexible():
            return choice
        if (((isinstance(choice, Refusal) and choice.reason in _HELPLESS)
                or (isinstance(choice, Plan) and self.seq.may_end_farther(
                    e, choice.f_p, self.reach(choice.n, choice.f_p))))
                and self.evidence_planning and not ev.moved
                and abs(e) > _GIVE_UP_FAR * (self.estimator.x_resolution
                                             + self.settings.tolerance)):
            ev.breakaway.smooth = True
            ev.planned = (0, 0.0, 0.0)
            return ev.plan(e)
        return choice

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Take the measured displacement d (m) of the pulse (n samples, f_p N) into the model
        and the policies.

        The evidence first (:meth:`Evidence.learn_move <.exact_policies.Evidence.learn_move>`,
        :meth:`~.exact_policies.Evidence.learn_bound`): a pulse that moved the table
        measurably (beyond 3 standard deviations of a measured displacement and half the
        resolution) ends the proof of ``f_lb`` (the breakaway is drawn anew at the next
        stop); a one-sample pulse that moved adds the breakaway force it implies; one that
        did not move, or one planned on the evidence that moved less than ``FAR_LESS`` of its
        prediction (it crept: pre-sliding), raises ``f_lb`` to its height. A pulse planned on
        the curve ends its learning there. Then the prediction's relative error r judges
        the fitted model (its errors) and the cautious policy (a miss: r > 1), unless the
        pulse was a height near breakaway that moved far less than predicted (Stribeck,
        pre-sliding: it counts as one that did not move). Then the fit takes the pulse.
        """
        pred = self.seq.pred
        d_along = d if f_p > 0.0 else -d
        est = self.estimator
        est.meas_sigma = self.rest.sigma_move()
        noise = Z_DECIDE * est.meas_sigma
        ev = self.evidence
        visible = math.isfinite(d_along) and abs(d_along) > max(noise, 0.5 * est.x_resolution)
        ev.moved = ev.moved or visible
        self.fitted.moved(visible)
        if ev.learn_move(n, f_p, d, d_along, pred, visible, noise):
            self.fitted.after_single = True
            return
        ev.learn_bound(n, f_p, d_along, pred, visible)
        if pred > 0.0 and math.isfinite(d_along) and d_along > max(noise, self.rest.band):
            # (a pulse that did not move probed f_s: it says nothing of the model)
            r = max(abs(d_along - pred) - noise, 0.0) / pred
            near = n == 1 and abs(f_p) < min(est.f_s_hi, 1.2 * max(est.f_s_lo, est.f_c_hat))
            if near and (d_along < FAR_LESS * pred
                         or (r > _USEFUL and max(self.fitted.errors) <= _USEFUL)):
                # A height near breakaway and below the lowest known to move, which moved
                # far less than predicted, or unlike every prediction that held so far
                # (Stribeck: friction kept up at low speed; pre-sliding): no use for
                # planning. It counts as one that did not move.
                est.observe(n, f_p, 0.0)
                return
            self.fitted.judge(n, r)
            self.cautious.judge(r)
        self.fitted.after_single = n == 1
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
        return min(max(self.fitted.errors), 0.1)

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
        """The noise of a measured move (``meas_sigma``), the estimator's state
        (``estimator.*``) and each policy's (``fitted.*``, ``cautious.*``, ``evidence.*``)."""
        est = self.estimator
        out = {**super().law_state(), "meas_sigma": est.meas_sigma, "samples": self.samples}
        out.update({f"estimator.{k}": v for k, v in est.state().items()})
        for policy in self.policies:
            out.update({f"{policy.name}.{k}": v for k, v in policy.state().items()})
        return out

    def set_law_state(self, values: Mapping[str, Any]) -> None:
        super().set_law_state(values)
        parts: dict[str, dict[str, Any]] = {}
        for key, value in values.items():
            if "." in key:
                part, name = key.split(".", 1)
                parts.setdefault(part, {})[name] = value
        for policy in self.policies:
            policy.set_state(parts.get(policy.name, {}))
        self.estimator.meas_sigma = float(values["meas_sigma"])
        self.samples = int(values["samples"])
        self.estimator.set_state(parts.get("estimator", {}))
