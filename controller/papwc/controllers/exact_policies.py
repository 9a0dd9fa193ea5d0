"""The exact-model controller's three ways of planning a pulse, each a policy with its state.

A policy answers one question -- which pulse for the error e? -- with a :class:`Plan` (its
width in samples and its signed height) or a :class:`Refusal` (why none: a
:class:`~papwc.controllers.interface.Reason` code). It keeps what it learned of the table in
its own named state (part of the controller's :meth:`~papwc.controllers.base.
PulseControllerBase.state`, so PulseController.fmu's get/set state carries it). The
controller (:class:`papwc.controllers.exact.ExactController`) holds the model all three
plan with -- Eq. (3) fitted to its pulses (:class:`~papwc.controllers.exact_fit.
PulseModelEstimator`), corrected by the nearest pulses measured -- and picks the policy by
one rule (:meth:`~papwc.controllers.exact.ExactController.choose`):

* :class:`FittedModel` plans on the fitted Eq. (3): the fastest pulse that moves
  ``trust*abs(e)``, a two-pulse move below the smallest pulse, probes of the breakaway
  bracket;
* :class:`Cautious` takes over after pulses the model missed (``misses``): only the smallest
  pulse toward the target, and only while it cannot end farther than the table is;
* :class:`Evidence` plans one-sample pulses on the evidence of where the table breaks away:
  for the lowest breakaway force still possible, at an excess that moves the table at most
  ``trust*abs(e)`` if it breaks away there (a table that breaks away higher moves less).
  On its move curve (:class:`~papwc.controllers.breakaway.BreakawayEvidence`) once the
  breakaway showed smooth, else on Eq. (2) at the breakaway force -- where the model finds
  no pulse that helps at the start of a maneuver.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, NamedTuple

from ..model.pulse import bisect_increasing
from .breakaway import BreakawayEvidence
from .budget import PLAN_RESERVE
from .interface import Reason
from .sequencer import RUNAWAY_FACTOR, Z_DECIDE

if TYPE_CHECKING:
    from .exact import ExactController

__all__ = ["Cautious", "Evidence", "FittedModel", "Plan", "Policy", "Refusal"]

#: Two-pulse moves (away, then back) started from an error no smaller than
#: TWO_PULSE_PROGRESS of the smallest one of the maneuver started from (beyond two counts,
#: where the encoder shows the progress), TWO_PULSE_HUNT of them, are a hunt: no further one
#: is made. Each way out goes far beyond 1.5*abs(e) (realism_mc_fresh rigid-s1-d002: 196 N
#: out by 34 um, back to 0.5-3 um, 16 times in one maneuver); one or two more may land (a
#: drive's ringing).
TWO_PULSE_PROGRESS = 0.8
TWO_PULSE_HUNT = 3
#: A two-pulse move (away, then back) is begun only with this many samples left of the
#: maneuver's time budget (two one-sample pulses, each coasting and read at rest).
TWO_PULSE_SAMPLES = 10
#: Relative error of the last prediction beyond which planned pulses stay near those tried.
TRIED_AFTER = 0.5
#: Largest step above the highest height tried (of at least the planned width) while the
#: model has not yet predicted a pulse well (relative).
TRIED_STEP = 0.1
#: Largest step of a probe of f_s above the highest height known not to move (relative);
#: the cautious policy's step above a one-sample pulse that crept.
PROBE_STEP = 0.1
#: Relative model error from which, after a missed pulse, only the smallest pulse is made.
CAUTIOUS = 0.5
#: Consecutive pulses that the model misses by more than 100 % after which it is rejected:
#: only the smallest pulse is made from then on (while it can bring the mass nearer).
REJECT_AFTER = 3
#: Largest planned displacement relative to the farthest a pulse in the history moved.
EXPLORE = 3.0
#: Trust (relative) of a pulse wider than every pulse in the history.
NEW_WIDTH = 2.0 / 3.0
#: Relative model error (misfit over the history, or of the last prediction) above which
#: a pulse wider than any made is planned with ``NEW_WIDTH`` of the trust.
EXACT_ENOUGH = 0.2
#: A pulse wider than the widest in the history is at most this many times as wide (and at
#: most one sample wider for narrow ones): at one height its move grows about as the width
#: squared, so at most 2.25 times the widest one's.
WIDER = 1.5
#: A fit on sliding pulses of one width that lies more than this many prior standard
#: deviations from the settings' estimates is taken as a plant unlike Eq. (3)
#: (:meth:`FittedModel.unlike_eq3`).
IMPLAUSIBLE = 2.0
#: Step of a one-sample pulse above the highest height that did not move (relative).
LB_STEP = 0.002
#: One-sample pulses whose implied breakaway forces are kept.
IMPLIED = 8
#: Smallest relative margin below the lowest breakaway seen, where a new one may lie.
LB_MARGIN = 0.03
#: A single-sample pulse near breakaway that moved less than this fraction of the
#: prediction counts as not having moved (the Stribeck evidence PAPWC uses too).
FAR_LESS = 0.25
#: One-sample pulses that crept (moved less than FAR_LESS of Eq. (3)) that show a
#: smooth breakaway.
CREEPS = 2
#: A move planned on the evidence is at most this many times the farthest it holds.
EV_EXTRAPOLATE = 2.0
#: Pulses planned on the evidence that fell short of their plan alike (within a factor
#: STEADY, each below SHORT of it) after which the planned move is raised, at most
#: BOOST_MAX times.
SHORTFALLS = 3
STEADY = 2.0
SHORT = 0.5
BOOST_MAX = 4.0
#: A one-sample move not seen (within 3 standard deviations of a measured displacement)
#: but above this many of them may have been a move: it proves nothing of the breakaway.
UNSURE = 2.0


class Plan(NamedTuple):
    """A pulse: ``n`` samples (>= 1) at the height ``f_p`` (N, signed: toward the target or,
    the first of a two-pulse move, away from it)."""

    n: int
    f_p: float


class Refusal(NamedTuple):
    """No pulse: why (a :class:`~papwc.controllers.interface.Reason` code)."""

    reason: int


class Policy:
    """A way of planning a pulse, with its own state (see the module).

    Parameters
    ----------
    law : ExactController
        The controller it plans for: the model (``estimator``, ``displacement``), the trust
        region, the sequencer and the settings.

    Attributes
    ----------
    name : str
        Its name: the prefix of its state in the controller's (``law.<name>.<field>``).
    """

    name = "policy"

    def __init__(self, law: ExactController) -> None:
        self.law = law

    def plan(self, e: float) -> Plan | Refusal:
        """The pulse for the error e (m), or why none."""
        raise NotImplementedError

    def reset(self) -> None:
        """A new maneuver from rest (what it learned of the model is kept)."""

    def state(self) -> dict[str, Any]:
        """Its state by name: numbers, or lists of numbers."""
        raise NotImplementedError

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state` (ValueError if it does not fit)."""
        raise NotImplementedError


def _numbers(values: Mapping[str, Any], name: str, where: str, size: int | None = None,
             most: int | None = None) -> list[float]:
    """``values[name]`` as floats: exactly ``size`` of them, or at most ``most``."""
    out = [float(v) for v in values[name]]
    if size is not None and len(out) != size:
        raise ValueError(f"law.{where}.{name} holds {len(out)} numbers, not {size}")
    if most is not None and len(out) > most:
        raise ValueError(f"law.{where}.{name} holds {len(out)} numbers, at most {most}")
    return out


class FittedModel(Policy):
    """Plans on Eq. (3) fitted to the pulses, corrected by the nearest ones measured.

    A single pulse of ``trust*abs(e)`` when that is at least the smallest pulse (one sample at
    ``f_floor``, d_small): the fewest samples whose height lies in ``[f_floor, f_p_max]``,
    wider than any made only within ``EXPLORE`` times the farthest move (and with
    ``NEW_WIDTH`` of the trust while the model errs by more than ``EXACT_ENOUGH``), at most
    ``WIDER`` times as wide as the widest while the fit looks unlike Eq. (3), and near the
    pulses tried after a prediction missed by more than ``TRIED_AFTER``. Below d_small: the
    smallest pulse toward the target where it lands within ``abs(e)/2``; a two-pulse move
    (away by d_small, back by ``abs(e) + d_small``) where the trust and the maneuver's start
    allow, but not after ``TWO_PULSE_HUNT`` in a row that did not bring the table nearer (a
    hunt); a probe of the breakaway bracket below ``f_floor``. It refuses (``no_move_helps``)
    below what a move can achieve: half the resolution, or the model's relative error times
    the move.

    Attributes
    ----------
    errors : list of float
        Relative errors of the last two predictions (a priori, beyond the noise).
    fine_error : float
        Relative error of the last single-sample pulse planned right after another (the
        way back of a two-pulse move).
    after_single : bool
        The last pulse had one sample.
    two_best : float
        The smallest error a two-pulse move of this maneuver started from, m (0: none).
    two_fails : int
        This maneuver's two-pulse moves since that one that started from no smaller error
        (``TWO_PULSE_HUNT`` of them: no further one); ``two_out``: the last pulse was the
        way out of one, ``two_counted``: counted so.
    """

    name = "fitted"
    FIELDS = ("errors", "fine_error", "after_single", "two")

    def __init__(self, law: ExactController) -> None:
        super().__init__(law)
        self.errors = [1.0, 1.0]
        self.fine_error = 1.0
        self.after_single = False
        self.reset()

    def reset(self) -> None:
        self.two_best = 0.0
        self.two_fails = 0
        self.two_out = self.two_counted = False

    def rel(self) -> float:
        """Relative error expected of the model: the smaller of the fit's misfit and the
        last two predictions' larger error (at least 1e-9)."""
        return max(min(self.law.estimator.rel_misfit, max(self.errors)), 1e-9)

    def _hunting(self, d: float) -> bool:
        """Whether a two-pulse move from the error d (m) would hunt: ``TWO_PULSE_HUNT`` of this
        maneuver's two-pulse moves that moved the table started from errors no smaller than
        ``TWO_PULSE_PROGRESS`` of the smallest one started from before (beyond two counts,
        where the encoder shows the progress). If not, it counts this one."""
        retry = (self.two_best > 0.0 and d >= TWO_PULSE_PROGRESS * self.two_best
                 and d > 2.0 * self.law.estimator.x_resolution)
        if retry and self.two_fails >= TWO_PULSE_HUNT:
            return True
        self.two_fails = self.two_fails + 1 if retry else 0
        self.two_counted = retry
        self.two_best = min(self.two_best, d) if self.two_best > 0.0 else d
        self.two_out = True
        return False

    def moved(self, visible: bool) -> None:
        """A pulse ended, having moved the table ``visible``-ly or not: a way out that did
        not move made no two-pulse move (it is not counted)."""
        if self.two_out and not visible and self.two_counted:
            self.two_fails -= 1
        self.two_out = self.two_counted = False

    def judge(self, n: int, r: float) -> None:
        """A pulse of n samples moved with the relative error r against its prediction."""
        self.errors = [self.errors[-1], min(r, 1e3)]
        if n == 1 and self.after_single:
            self.fine_error = min(r, 1e3)

    def plan(self, e: float) -> Plan | Refusal:
        law = self.law
        est = law.estimator
        f_lo = law.f_floor
        d = abs(e)
        d_small = law.displacement(1, f_lo)
        trust = law.trust()
        rel = self.rel()
        toward = math.copysign(1.0, e)
        if trust * d >= d_small:
            if d <= max(0.5 * est.x_resolution, rel * d):
                return Refusal(Reason.NO_MOVE_HELPS)
            n, f_p, goal = self.plan_width(trust * d, f_lo)
            n, f_p = self._within_tried(n, f_p, goal, f_lo)
            return Plan(n, toward * f_p)
        if d_small <= 1.5 * d or abs(d_small - d) <= rel * d_small:
            return Plan(1, toward * f_lo)  # the smallest pulse toward: it lands within d/2
        two = d + d_small
        # the way back is planned from where the way out ended: its error is what counts
        rel_back = max(min(rel, self.fine_error), 1e-9)
        if (trust * two >= d_small and d > max(0.5 * est.x_resolution, rel_back * two)
                and d + d_small / trust <= abs(law.seq.e0)):
            if law.budget_spent(TWO_PULSE_SAMPLES * law.T):
                return Refusal(Reason.PULSE_BUDGET)  # no time left to come back
            if self._hunting(d):
                return Refusal(Reason.NO_MOVE_HELPS)
            return Plan(1, -toward * f_lo)  # away by d_small; back by d + d_small next
        # A height below the lowest known to move may move the mass less: a probe of f_s
        # toward the target, planned to move trust*|e| if it moves at all.
        f_probe_lo = max(est.f_s_lo, est.f_c_hat) * (1.0 + 1e-9)
        if f_probe_lo < f_lo:
            if law.displacement(1, f_probe_lo) < trust * d:
                return Plan(1, toward * law._amplitude(trust * d, 1, f_probe_lo, f_lo))
            # the smallest pulse that may move: just above the highest height that did not
            f_probe = min(f_lo, max(est.f_s_lo * (1.0 + 2.0 * law.f_s_tol), f_probe_lo))
            if f_probe < f_lo and law.displacement(1, f_probe) <= RUNAWAY_FACTOR * d:
                return Plan(1, toward * f_probe)  # (moving as predicted, within the bound)
        # (the smallest pulse toward the target predicted to move 1.5 to 2 times abs(e) would
        # land nearer, but beyond the bound 1.5*abs(e) a pulse is held to)
        return Refusal(Reason.NO_MOVE_HELPS)

    def plan_width(self, goal: float, f_lo: float) -> tuple[int, float, float]:
        """The fastest pulse for ``goal`` (m) above ``f_lo`` (N), and the goal it was planned
        for: wider than any pulse in the history (where the model extrapolates), for at most
        ``EXPLORE`` times the farthest any moved, and with ``NEW_WIDTH`` of it while the
        model's misfit or its last prediction's error is above ``EXACT_ENOUGH``."""
        law = self.law
        est = law.estimator
        n, f_p = law.plan_displacement(goal, f_lo)
        if est.pulses and n > est.widest:
            goal = self._explored(goal)
            if max(est.rel_misfit, self.errors[-1]) > EXACT_ENOUGH:
                goal *= NEW_WIDTH
            n, f_p = law.plan_displacement(goal, f_lo)
            if n > est.widest and self.unlike_eq3():
                # a fit to sliding pulses of one width cannot tell how the move grows with
                # the width (a lag, Stribeck make it grow faster than Eq. (3)): at most
                # WIDER times as wide (one sample wider) as the widest made, no higher than
                # the highest of that width, as high as the model says for the goal below that
                n = min(n, max(est.widest + 1, int(WIDER * est.widest)))
                f_top = max((abs(f) for n_i, f, _ in est.pulses if n_i == est.widest),
                            default=law.settings.f_p_max)
                f_p = (f_top if law.displacement(n, f_top) < goal
                       else law._amplitude(goal, n, min(f_lo, f_top), f_top))
        return n, f_p, goal

    def unlike_eq3(self) -> bool:
        """Whether the fit rests on sliding pulses of one width and lies more than
        ``IMPLAUSIBLE`` prior standard deviations from the settings' estimates: a plant
        unlike Eq. (3) (a lag, Stribeck) fitted by a mass, friction and viscous damping it
        does not have (measured: c 4,000-18,000 N.s/m, f_c 14-49 N for a table of 700 and
        100), whose moves at other widths it does not know."""
        est = self.law.estimator
        if len({n_i for n_i, _, _ in est.pulses if n_i > 1}) >= 2:
            return False
        return est.prior_distance() > IMPLAUSIBLE

    def _explored(self, d: float) -> float:
        """d (m), at most ``EXPLORE`` times the farthest any pulse in the history moved."""
        moved = [d_i for _, _, d_i in self.law.estimator.pulses]
        return min(d, EXPLORE * max(moved)) if moved else d

    def _within_tried(self, n: int, f_p: float, d: float, f_lo: float) -> tuple[int, float]:
        """The planned pulse (n samples, height f_p > 0 N, for d m), kept near those tried.

        After a pulse the model missed by more than ``TRIED_AFTER``, a pulse is no wider
        than the widest in the history and no higher than ``1 + TRIED_STEP`` times the
        highest of at least its width (but at least ``f_lo``): on a plant unlike Eq. (3) a
        model fitted to one or two pulses says little about a pulse unlike them.
        """
        law = self.law
        est = law.estimator
        if self.errors[-1] <= TRIED_AFTER or not est.pulses:
            return n, f_p
        if n > est.widest:
            n = est.widest
            f_p = law._amplitude(d, n, f_lo, law.settings.f_p_max)
        f_seen = max(f_i for n_i, f_i, _ in est.pulses if n_i >= n)
        return n, min(f_p, max(f_lo, f_seen * (1.0 + TRIED_STEP)))

    def state(self) -> dict[str, Any]:
        return {"errors": list(self.errors), "fine_error": self.fine_error,
                "after_single": int(self.after_single),
                "two": [self.two_best, float(self.two_fails), float(self.two_out),
                        float(self.two_counted)]}

    def set_state(self, values: Mapping[str, Any]) -> None:
        self.errors = _numbers(values, "errors", self.name, size=2)
        self.fine_error = float(values["fine_error"])
        self.after_single = bool(values["after_single"])
        best, fails, out, counted = _numbers(values, "two", self.name, size=4)
        self.two_best, self.two_fails = best, int(fails)
        self.two_out, self.two_counted = bool(out), bool(counted)


class Cautious(Policy):
    """Plans when the fitted model is not to be trusted: only the smallest pulse toward the
    target (one sample at ``f_floor``), while it moves no farther than the error; after one
    of its pulses that did not move measurably (a creep: pre-sliding, a lag), one sample
    ``1 + PROBE_STEP`` times as high, while the model says that moves no farther than the
    error. It refuses (``model_rejected`` after ``REJECT_AFTER`` misses in a row, else
    ``no_move_helps``) when even that could overshoot.

    It is in force (:meth:`active`) after a pulse the model missed by more than 100 % while
    the model's relative error is ``CAUTIOUS`` or more, and after ``REJECT_AFTER`` such
    misses in a row whatever the error.

    Attributes
    ----------
    misses : int
        Consecutive pulses the model missed by more than 100 % (forgotten at a new maneuver).
    """

    name = "cautious"
    FIELDS = ("misses",)

    def __init__(self, law: ExactController) -> None:
        super().__init__(law)
        self.misses = 0

    def active(self, rel: float) -> bool:
        """Whether it plans, the model's relative error being rel."""
        return self.misses >= REJECT_AFTER or (self.misses > 0 and rel >= CAUTIOUS)

    def judge(self, r: float) -> None:
        """A pulse moved with the relative error r against its prediction."""
        self.misses = self.misses + 1 if r > 1.0 else 0

    def reset(self) -> None:
        self.misses = 0

    def plan(self, e: float) -> Plan | Refusal:
        law = self.law
        f_lo = law.f_floor
        d = abs(e)
        d_small = law.displacement(1, f_lo)
        toward = math.copysign(1.0, e)
        n_last, f_last = law.seq.last_pulse
        if (n_last == 1 and abs(f_last) >= f_lo and law.pulses
                and abs(law.seq.last_d) <= law.rest.band):
            # the last cautious pulse did not move measurably (a creep): 10 % higher,
            # while the model says it moves no farther than the error
            f_up = min(abs(f_last) * (1.0 + PROBE_STEP), law.settings.f_p_max)
            if law.displacement(1, f_up) <= d:
                return Plan(1, toward * f_up)
        if d_small <= d:
            return Plan(1, toward * f_lo)
        if self.misses >= REJECT_AFTER:
            return Refusal(Reason.MODEL_REJECTED)
        return Refusal(Reason.NO_MOVE_HELPS)

    def state(self) -> dict[str, Any]:
        return {"misses": self.misses}

    def set_state(self, values: Mapping[str, Any]) -> None:
        self.misses = int(values["misses"])


class Evidence(Policy):
    """Plans one-sample pulses on the evidence of where the table breaks away (see the
    module): for the lowest breakaway force still possible, at the excess that moves the
    table at most ``trust*abs(e)`` if it breaks away there.

    On its move curve (``on_curve``: the breakaway showed smooth, see
    :meth:`~papwc.controllers.exact.ExactController.on_evidence`) every one-sample pulse is
    planned so (a move the model plans wider is the fitted model's); else it plans only where
    the fitted model refuses at the start of a maneuver (:meth:`start`), on Eq. (2) with the
    friction at that breakaway force.

    Attributes
    ----------
    breakaway : BreakawayEvidence
        The heights that did not move, the moves near breakaway and their curve.
    f_lb : float
        Highest one-sample height that did not move the table since it last moved, N (0:
        none): the breakaway force lies above it until the table moves again.
    implied : list of float
        Breakaway forces the last one-sample pulses that moved imply, N (newest last).
    planned : tuple
        The last one-sample pulse it planned: (n, height N, prediction m); (0, 0, 0): none.
    plan_e : float
        The error the last pulse planned on the curve was planned for, m.
    ev_lo : float
        The lowest breakaway still possible when the present pulse was planned on the
        curve, N (0: it was not).
    creeps : int
        One-sample pulses that moved far less than Eq. (3) says a table breaking away at
        once moves (``CREEPS`` of them make the breakaway smooth).
    moved : bool
        A pulse of this maneuver moved the table visibly.
    shortfall : list of float
        Moves over their plans of the last pulses planned on the curve that moved.
    """

    name = "evidence"
    FIELDS = ("f_lb", "implied", "planned", "plan_e", "ev_lo", "creeps", "moved", "shortfall")

    def __init__(self, law: ExactController) -> None:
        super().__init__(law)
        s = law.settings
        self.breakaway = BreakawayEvidence(s.f_c_est, s.m_est, law.T, law.ops)
        self.f_lb = 0.0
        self.implied: list[float] = []
        self.planned: tuple[int, float, float] = (0, 0.0, 0.0)
        self.plan_e = 0.0
        #: The pulse before the present plan was one of its one-sample pulses (derived at
        #: each plan from ``planned``: not state).
        self.planned_last = False
        self.ev_lo = 0.0
        self.creeps = 0
        self.moved = False
        self.shortfall: list[float] = []

    def reset(self) -> None:
        """The table has moved since the last pulse: its breakaway force is drawn anew, so
        the heights that did not move prove nothing any more (``f_lb`` = 0)."""
        self.f_lb = 0.0
        self.breakaway.table_moved()
        self.ev_lo = 0.0
        self.moved = False

    def begin(self) -> None:
        """A plan begins: the last pulse's plan is forgotten (``planned_last`` says whether
        it was one of this policy's)."""
        self.planned_last = self.planned[0] == 1
        self.planned = (0, 0.0, 0.0)
        self.ev_lo = 0.0

    # -- planning --------------------------------------------------------------------------
    def plan(self, e: float) -> Plan | Refusal:
        """On the curve: a one-sample pulse for the lowest breakaway still possible; a
        wider one as the fitted model plans it (:meth:`FittedModel.plan_width`, the same
        limits to a width never made). Refuses (``no_move_helps``) within half a count or
        the tolerance."""
        law = self.law
        if abs(e) <= max(0.5 * law.estimator.x_resolution, law.settings.tolerance):
            return Refusal(Reason.NO_MOVE_HELPS)
        toward = math.copysign(1.0, e)
        n, f_p, goal = law.fitted.plan_width(law.trust() * abs(e), law.f_floor)
        if n > 1:
            return Plan(n, toward * f_p)
        self.plan_e = abs(e)
        return Plan(1, toward * self._curve_height(goal, f_p))

    def start(self, e: float, refusal: Refusal) -> Plan | Refusal:
        """Where the fitted model refuses (``refusal``: ``no_move_helps`` or
        ``model_rejected``) at the start of a maneuver or right after a pulse of its own:
        one sample for the lowest breakaway force still possible (:meth:`f_b_low`), the
        highest that moves at most ``trust*abs(e)`` if the table broke away there
        (:meth:`lowest_breakaway_move`); else ``refusal``."""
        law = self.law
        if (abs(e) <= max(0.5 * law.estimator.x_resolution, law.settings.tolerance)
                or not (law.pulses == 0 or self.planned_last)):
            return refusal
        f_b = self.f_b_low()
        if not f_b > 0.0:
            return refusal
        f_max = law.settings.f_p_max
        f_min = min(f_b * (1.0 + LB_STEP), f_max)
        goal = law.trust() * abs(e)

        def move(h: float) -> float:
            return self.lowest_breakaway_move(h, f_b)

        if move(f_min) > goal:
            return refusal  # even the lowest such pulse would go beyond the trust region
        # the highest height that moves at most trust*|e| if the table broke away at f_b
        f = f_max if move(f_max) <= goal else bisect_increasing(move, goal, f_min, f_max)[0]
        self.planned = (1, f, move(f))
        return Plan(1, math.copysign(f, e))

    def _curve_height(self, goal: float, f_model: float) -> float:
        """Height (N) of one sample that moves the table at most ``goal`` (m), planned for
        the lowest breakaway force still possible (:meth:`BreakawayEvidence.lowest`).

        Its excess over that force moves the table ``goal`` on the curve of the evidence
        that moves it least far for it (:meth:`BreakawayEvidence.plan_excess`; before the
        evidence has a curve, half of that on Eq. (2) with the friction at the breakaway
        force): if the table breaks away higher, the pulse moves it less. A pulse that does
        not move raises that lowest force until the table moves. A move beyond
        ``EV_EXTRAPOLATE`` times the farthest creep the evidence holds is planned by the
        model (``f_model``, N) where it learned one-sample pulses, no higher than the
        creeps' curve allows; else no farther than that reach.
        """
        law = self.law
        ev = self.breakaway
        low = self.lowest_breakaway()
        if not low > 0.0:
            est = law.estimator
            low = max(est.f_s_lo, est.f_c_hat)
        planned = goal
        goal *= self._boost()
        reach = EV_EXTRAPOLATE * ev.farthest()
        if ev.fitted and goal > reach:
            # beyond the creeps the evidence holds: as far as Eq. (3) and the one-sample
            # pulses it learned say, where it learned some, but no higher than the creeps'
            # curve allows; else no farther than the evidence reaches
            if any(n_i == 1 for n_i, _, _ in law.estimator.pulses):
                f = min(low + ev.plan_excess(goal), abs(f_model))
                f = max(f, low + ev.plan_excess(reach))
            else:
                f = low + ev.plan_excess(reach)
                planned = min(planned, reach)
        else:
            f = low + ev.plan_excess(goal)
        if law.band[1] > 0.0:
            f = min(f, low + law.band[1])  # at most the band's width above the lowest
        f = min(f, law.settings.f_p_max)
        self.ev_lo = low
        self.planned = (1, f, planned)
        return f

    def _boost(self) -> float:
        """Factor on the move planned on the curve: the recent ones all fell as short of
        their plan (within ``STEADY`` of each other, and below ``SHORT``) and no pulse
        has failed to move the table (pre-sliding: it creeps wherever it is pushed, the same
        each time) -- the planned move over the longest of their shares of it, at most
        ``BOOST_MAX``; else 1."""
        shares = self.shortfall
        if self.breakaway.held or len(shares) < SHORTFALLS or not min(shares) > 0.0:
            return 1.0
        if max(shares) > SHORT or max(shares) > STEADY * min(shares):
            return 1.0
        return min(1.0 / max(shares), BOOST_MAX)

    def lowest_breakaway(self) -> float:
        """The lowest breakaway force still possible now on the evidence, N (0: none): above
        the highest height that did not move since the table moved, and the identified
        band's floor where it is given (``f_b_floor``); else the lowest a fresh stick may
        have on the moves (:meth:`BreakawayEvidence.lowest`)."""
        floor = self.law.band[0]
        if floor > 0.0:
            return max(self.breakaway.f_lb, floor)
        return self.breakaway.lowest()

    def f_b_low(self) -> float:
        """The lowest breakaway force still possible now, N (0: no evidence yet).

        ``f_lb`` (a one-sample pulse at that height did not move since the table last
        moved); right after a move (the breakaway is drawn anew), the lowest of the
        breakaway forces the last one-sample pulses implied (:attr:`implied`), lowered
        by their relative spread (at least ``LB_MARGIN``); without those, the same from
        the fit's bracket and f_c.
        """
        if self.law.band[0] > 0.0:
            return max(self.f_lb, self.law.band[0])
        if self.f_lb > 0.0:
            return self.f_lb
        lo = min(self.implied, default=0.0)
        hi = max(self.implied, default=0.0)
        if not lo > 0.0:
            # no breakaway seen between two heights: below the fit's bracket and f_c
            est = self.law.estimator
            lo = hi = max(est.f_s_lo, est.f_c_hat) if est.pulses else 0.0
            if not lo > 0.0:
                return 0.0
        # the breakaway is drawn anew: below the lowest seen by the spread seen
        spread = max((hi - lo) / hi, LB_MARGIN)
        return lo * (1.0 - spread)

    def lowest_breakaway_move(self, f: float, f_b: float) -> float:
        """Displacement of one sample at height f (N) if the table broke away at f_b (N), m.

        Eq. (2): the friction at f_b throughout (at the low speeds of a pulse near
        breakaway the friction stays near the breakaway force), no viscous damping, and the
        smaller of the learned mass and ``m_est`` (a fit fooled by a plant unlike Eq. (3)
        does not make the move look shorter than it may be).
        """
        law = self.law
        m = min(law.estimator.m_hat, law.settings.m_est)
        return law.eq3(f, law.T, m, f_b, 0.0) if f > f_b else 0.0

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

    # -- learning --------------------------------------------------------------------------
    def learn_move(self, n: int, f_p: float, d: float, d_along: float, pred: float,
                   visible: bool, noise: float) -> bool:
        """The breakaway evidence of a pulse (n samples, f_p N) that moved d (m; d_along
        along it), predicted to move pred (m), ``visible`` beyond ``noise`` (m); True if
        it was planned on the curve (its learning ends here)."""
        law = self.law
        ev = self.breakaway
        if n == 1 and math.isfinite(f_p) and math.isfinite(d_along):
            moved = visible and d_along > 0.0
            crept = moved and d_along < FAR_LESS * law._eq3_reach(abs(f_p))
            # a move too short to tell from the noise may have been one: it proves nothing of
            # the breakaway (the table may have stuck anew, lower)
            unsure = not moved and d_along > UNSURE * noise / Z_DECIDE
            ran = (self.ev_lo > 0.0 and not law.trust.flexible
                   and d_along > RUNAWAY_FACTOR * self.plan_e)
            if (moved and not crept and not ran) or unsure:
                ev.table_moved()  # a long move (the model's), or one that may have been
            else:
                # a creep, one that did not move, or, on a rigid table, a pulse of its own plan
                # that ran beyond 1.5 times the error it was planned for: its curve must learn
                # how far such pulses go (realism_mc_ideal_10s, offset 1000, rigid-s0-d000:
                # the curve of three creeps planned 268 N for 3.5 um, which moved 143 um, and
                # did so again 230 times, as long moves did not reach it; on a drive told its
                # mode a long move is the spring's sling, not the breakaway's excess)
                ev.observe(abs(f_p), d_along, moved, self.ev_lo)
            if crept and not ev.smooth:
                # far less than a table that breaks away at once moves: a smooth
                # breakaway (Stribeck friction, a lag), seen twice (once may be noise)
                self.creeps += 1
                ev.smooth = self.creeps >= CREEPS
            if self.ev_lo > 0.0:
                self.ev_lo = 0.0
                if pred > 0.0 and moved:
                    self.shortfall = (self.shortfall + [d_along / pred])[-SHORTFALLS:]
                if moved and not crept:
                    # a long move: Eq. (3) and its correction learn it
                    law.estimator.observe(n, f_p, d, PLAN_RESERVE)
                return True
        elif visible:
            ev.table_moved()
        return False

    def learn_bound(self, n: int, f_p: float, d_along: float, pred: float,
                    visible: bool) -> None:
        """What a pulse (n samples, f_p N) that moved d_along (m along it), predicted to
        move pred (m), proves of the breakaway force: above its height while the table did
        not move (``f_lb``), or where it broke away (:attr:`implied`)."""
        crept = (n == 1 and self.planned[0] == 1 and 0.0 < d_along < FAR_LESS * pred)
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
                        self.implied = (self.implied + [f_b])[-IMPLIED:]
                self.f_lb = 0.0
            elif n == 1:
                self.f_lb = max(self.f_lb, abs(f_p))

    # -- state -----------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "f_lb": self.f_lb, "implied": list(self.implied),
            "planned": [float(v) for v in self.planned], "plan_e": self.plan_e,
            "ev_lo": self.ev_lo,
            "creeps": self.creeps, "moved": int(self.moved), "shortfall": list(self.shortfall)}
        out.update({f"breakaway.{k}": v for k, v in self.breakaway.state().items()})
        return out

    def set_state(self, values: Mapping[str, Any]) -> None:
        self.f_lb = float(values["f_lb"])
        self.implied = _numbers(values, "implied", self.name, most=IMPLIED)
        n_plan, f_plan, pred = _numbers(values, "planned", self.name, size=3)
        self.planned = (int(n_plan), f_plan, pred)
        self.plan_e = float(values["plan_e"])
        self.ev_lo = float(values["ev_lo"])
        self.creeps = int(values["creeps"])
        self.moved = bool(values["moved"])
        self.shortfall = _numbers(values, "shortfall", self.name, most=SHORTFALLS)
        self.breakaway.set_state({k.split(".", 1)[1]: v for k, v in values.items()
                                  if k.startswith("breakaway.")})
