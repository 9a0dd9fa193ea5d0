"""What planning for the lowest breakaway still possible reaches when the table is known.

The measurement behind the README's note on the bounds of the exact-model controller on the
Monte Carlo's rigid tables. Those tables (the rigid draws of ``scenarios/realism_mc_fresh.toml``
and ``scenarios/realism_mc_lugre_fresh.toml``: Stribeck friction, ripple, an actuator lag,
random stiction or LuGre pre-sliding, each drawn) are stepped with the model layer's plant
(:class:`papwc.model.dynamics.Plant`). The *planner* knows a model of the table -- the plant's
parameters, or some of them wrong (:data:`MODELS`) -- but never the breakaway force drawn at
the present stick, and reads the table's true position (no encoder: a ceiling; one row reads
it through the table's encoder instead). From rest at ``E0`` from the target it repeats, while
``|e|`` is above ``STOP`` and the time allows:

* plan one sample, the highest height whose move on the model, with the breakaway at the
  lowest force still possible, is at most ``|e|`` (each candidate simulated on a copy of the
  plant's state; if the table breaks away higher, the same pulse moves it less);
* apply it, then no force for ``WAIT`` samples (``CYCLE`` s a pulse, as the exact-model
  controller's pulses near breakaway take);
* a pulse that did not move the table proves that the breakaway lies at
  or above the least force at which the model says that height does not move (bisection),
  until the table moves; a move starts the proof anew from the lowest breakaway the model's
  spread allows, ``f_s*(1 - f_s_spread)``. The planner sees every move, however short (the
  table stuck anew: its breakaway was drawn again), except in the rows that do not see moves
  up to ``MOVED``: there a proof outlives a move below it, as on an encoder of 0.1 um (and,
  guarded, no pulse above a proof may pass the runaway bound should it no longer hold).

This is the policy the issue on controllers from parts names, with the model in place of what
the exact-model controller learns. For each model it prints, over the distinct rigid tables,
how many reached 1 um within ``BUDGET`` s, the median time, the pulses, how many of the pulses
that moved at ``|e| >= 1 um`` and below went beyond ``1.5*|e|`` plus one count (the runaway
bound of R4 and R5) with the largest such move, and the processor time a pulse took (the
planning's simulations and the table's step); for the rows that do not see every move (through
the encoder, or moves up to ``MOVED``), how many pulses it took for held had moved the table,
and how many runaways at ``|e| >= 1 um`` came after such a pulse on their stick. The rows say
whether R1 and R4 are within reach of the policy on these tables, and which of the table's
parameters a controller must learn for them. Rows 13-16 learn the lag and v_s from the
pulses, the last three of them not told where the breakaway is drawn either (:class:`Approach`),
from the moves alone or from the first reading after each pulse as well: what a controller must
read to learn them. (The planner's simulations start from the table's state at rest, as every row's
do: the ripple's phase there is known to it.) Rows 17-21 do the same on the one-pulse model of
:mod:`papwc_studies.one_pulse` (:class:`FastApproach`), ``f_c`` learned too in rows 18, 19 and
21, rows 19-21 through the table's encoder; row 21 learns ``f_c`` within the band the
exact-model controller's slides after its wide pulses leave on the table
(:func:`papwc_studies.sliding.f_c_band`). Rows 22 and 23 are rows 2 and 3 through the
table's encoder itself (its count and noise): the table told, unguarded and guarded. Rows
24-27, through the encoder too, are not told where the breakaway is drawn (they take a fresh
stick's lowest breakaway from the moves, as the exact-model controller does): told the rest of
the table (24); told what ``papwc identify`` fits, the mass, the friction, the damping, the lag
and the Stribeck curve, and no ripple (25); told what it finds on a 60 s log of the table
(26: :func:`identified`, about 2 min a table; not on LuGre tables, which it does not model),
and the same but the table's v_s (27). Row 28 is told what ``papwc identify`` finds since
issue 46, the friction ripple and the stiction band too (its middle and half-width as ``f_s``
and ``f_s_spread``: where the breakaway is drawn, as rows 1-23 are told the table's), from
a log made under another seed.

Run ``python -m papwc_studies.ceiling [--tables N] [--rows K,L,...] [--files A,B,...]`` (N: at
most that many tables of each file; K, L: the rows of :data:`MODELS` by number from 1; A, B:
the scenario files, by default :data:`FILES`, or the Monte Carlo's own, ``realism_mc.toml``
and ``realism_mc_lugre.toml``); it prints one line per model and file.
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import signal
import statistics
import time
from collections.abc import Callable, Sequence
from multiprocessing import Pool
from typing import NamedTuple

from papwc.battery.plan import plan_runs
from papwc.battery.schema import load_battery
from papwc.limits import whole_number
from papwc.model.dynamics import Plant
from papwc.model.plant import plant_problems
from papwc_studies import scenario_path
from papwc_studies.counts import MOVED
from papwc_studies.one_pulse import CONSISTENT, FRESH_MARGIN, FRESH_MOVES, Candidates, TableEvidence
from papwc_studies.sliding import f_c_band

__all__ = ["BUDGET", "E0", "FILE_CHOICES", "FILES", "MODELS", "Approach", "FastApproach", "Model",
           "approach", "beyond", "files", "halve", "identified", "main", "pulse", "pulse_path",
           "rows", "runaway", "tables"]

#: Scenario files whose rigid draws are the tables (by default), and those ``--files`` may name:
#: the Monte Carlo's files, whose rigid draws are stick–slip or LuGre tables.
FILES = ("realism_mc_fresh.toml", "realism_mc_lugre_fresh.toml")
FILE_CHOICES = FILES + ("realism_mc.toml", "realism_mc_lugre.toml")
#: Start: at rest this far from the target, m (the Monte Carlo's shortest maneuver).
E0 = 5e-5
#: Time the approach may take, s (the Monte Carlo's maneuvers).
BUDGET = 2.0
#: Sample period, s, and samples with no force after each pulse.
T = 0.01
WAIT = 5
#: Time a pulse takes, s.
CYCLE = (1 + WAIT) * T
#: The approach ends at ``|e|`` at most this, m (half the 1 um goal).
STOP = 5e-7
#: Largest height, N (the Monte Carlo's f_p_max).
F_P_MAX = 300.0
#: Encoder count of the runaway bound, m.
COUNT = 1e-7
#: Bisection steps of a planned height and of a proof.
STEPS = 18
#: The fields ``papwc identify`` fits (v_s and tau_u where it chooses the Stribeck curve and
#: the lag).
IDENTIFIED = ("m", "f_c", "c", "v_s", "tau_u")
#: The fields it fits since issue 46 as well: the friction ripple and the stiction band (its
#: middle and half-width, as f_s and f_s_spread).
IDENTIFIED_WITH_BAND = IDENTIFIED + ("ripple", "ripple_period", "ripple_phase", "f_s",
                                     "f_s_spread")


class Model(NamedTuple):
    """What the planner is told of the table: ``told`` fields replace the table's, ``scale``
    fields are the table's times a factor, and it does not see moves up to ``unseen`` (m; 0:
    it sees every stick anew). With ``guard``, no pulse above a proof may move the table
    beyond the runaway bound if the table stuck anew unseen and broke away at the lowest
    force the spread allows. The fields of ``learn`` the planner does not know: it learns
    them over :data:`GRIDS` from its pulses (:class:`Approach`). Without ``band`` it is not
    told where the breakaway is drawn (``f_s`` and ``f_s_spread``): it takes the lowest
    breakaway of a fresh stick from the moves it made, as the exact-model controller does.
    With ``first`` it also reads the table one sample after each pulse (the first reading
    after the pulse's sample), and keeps only the candidates that explain that reading too.
    With ``encoder`` it reads the table through its encoder (resolution and noise, both
    told) instead of its true position (:meth:`Approach.run`). With ``fast`` its candidates
    are tables of the one-pulse model (:class:`FastApproach`); with ``slid`` too, their
    ``f_c`` lies within the band the slides of the exact-model controller's wide pulses
    leave on the table (:func:`papwc_studies.sliding.f_c_band`). The fields of ``identified`` it is
    told as ``papwc identify`` finds them on a log of the table (:func:`identified`)."""

    label: str
    told: dict[str, float] = {}
    scale: dict[str, float] = {}
    unseen: float = 0.0
    guard: bool = False
    learn: tuple[str, ...] = ()
    band: bool = True
    first: bool = False
    encoder: bool = False
    fast: bool = False
    slid: bool = False
    identified: tuple[str, ...] = ()

    def params(self, table: dict[str, float]) -> dict[str, float]:
        """The model's plant parameters for the table's."""
        out = {**table, **self.told}
        for name, factor in self.scale.items():
            out[name] = table.get(name, 0.0) * factor
        return out


#: The planner's models.
MODELS = (
    Model("the table"),
    Model(f"the table, moves up to {MOVED * 1e9:g} nm not seen", unseen=MOVED),
    Model(f"the table, moves up to {MOVED * 1e9:g} nm not seen, guarded", unseen=MOVED,
          guard=True),
    Model("the lag not known (tau_u = 0)", told={"tau_u": 0.0}),
    Model("the lag 50 % short", scale={"tau_u": 0.5}),
    Model("the lag 50 % long", scale={"tau_u": 1.5}),
    Model("Stribeck not known (v_s = 0)", told={"v_s": 0.0}),
    Model("Stribeck v_s 10 % high", scale={"v_s": 1.1}),
    Model("Stribeck v_s 25 % low", scale={"v_s": 0.75}),
    Model("stiction spread at the range's top (15 %)", told={"f_s_spread": 0.15}),
    Model("the ripple not known (0)", told={"ripple": 0.0}),
    Model("f_c at the controllers' estimate (80 N)", told={"f_c": 80.0}),
    Model("the lag and v_s learned from the pulses", learn=("tau_u", "v_s")),
    Model("the lag and v_s learned, f_s and its spread not told", learn=("tau_u", "v_s"),
          band=False),
    Model("the lag and v_s learned, f_s and its spread not told, the first reading read",
          learn=("tau_u", "v_s"), band=False, first=True),
    Model("the same, through the table's encoder", learn=("tau_u", "v_s"), band=False,
          first=True, encoder=True),
    Model("the lag and v_s learned on the one-pulse model, f_s and its spread not told, the "
          "first reading read", learn=("tau_u", "v_s"), band=False, first=True, fast=True),
    Model("the same, f_c learned too", learn=("tau_u", "v_s", "f_c"), band=False, first=True,
          fast=True),
    Model("the same, through the table's encoder", learn=("tau_u", "v_s", "f_c"), band=False,
          first=True, encoder=True, fast=True),
    Model("the lag and v_s learned on the one-pulse model, f_c told, through the table's "
          "encoder", learn=("tau_u", "v_s"), band=False, first=True, encoder=True, fast=True),
    Model("the lag, v_s and f_c learned on the one-pulse model, f_c within the band the "
          "controller's slides leave, through the table's encoder",
          learn=("tau_u", "v_s", "f_c"), band=False, first=True, encoder=True, fast=True,
          slid=True),
    Model("the table, through the table's encoder", encoder=True),
    Model("the table, through the table's encoder, guarded", encoder=True, guard=True),
    Model("the table but where the breakaway is drawn, through the table's encoder",
          band=False, encoder=True),
    Model("the table's m, f_c, c, lag and v_s (what papwc identify fits), not the ripple nor "
          "where the breakaway is drawn, through the table's encoder", told={"ripple": 0.0},
          band=False, encoder=True),
    Model("what papwc identify finds on a 60 s log of the table, not where the breakaway is "
          "drawn, through the table's encoder", told={"ripple": 0.0}, band=False,
          encoder=True, identified=IDENTIFIED),
    Model("the same but the table's v_s", told={"ripple": 0.0}, band=False, encoder=True,
          identified=tuple(name for name in IDENTIFIED if name != "v_s")),
    Model("what papwc identify finds on a 60 s log of the table with the ripple and the "
          "stiction band (issue 46), the breakaway drawn within that band, through the table's "
          "encoder", encoder=True, identified=IDENTIFIED_WITH_BAND),
)
#: What a planner learns a field over: values from the one under which a pulse moves the
#: table farthest (no lag; friction falling off at the lowest speed) to the least far,
#: spanning the Monte Carlo's ranges.
GRIDS = {
    "tau_u": tuple(k * 5e-4 for k in range(11)),
    "v_s": tuple(2e-4 * 1.5**k for k in range(9)),
    "f_c": tuple(60.0 + 5.0 * k for k in range(15)),
}
# The tolerance of a candidate's move against a pulse's measured one (CONSISTENT), and the
# recent moves and margin of a fresh stick's lowest breakaway, are those of
# papwc_studies.one_pulse (at a tolerance of 0.05 the LuGre tables, whose breakaway is not
# redrawn, kept candidates that ran away; the margin is the exact-model controller's).

#: Through the encoder: the readings at rest averaged (the last of the ``WAIT`` after a
#: pulse), and the standard deviations of a move and of a first reading beyond which the
#: planner takes them for more than noise.
REST_READS = 3
Z_NOISE = 3.0
#: Largest number of tables taken of each file.
TABLES_MAX = 1000


def pulse_path(plant: Plant, height: float, readings: list[float] | None = None
               ) -> tuple[float, float]:
    """Apply one sample at ``height`` (N) to ``plant``, then no force for ``WAIT`` samples;
    the move at the end of the pulse's sample (the first reading after it) and at the end,
    m. With ``readings``, the encoder's reading (:meth:`Plant.x_meas`, m) after each sample
    is appended to it."""
    x0 = plant.x
    first = 0.0
    for k, u in enumerate((height,) + (0.0,) * WAIT):
        plant.step(u, T)
        if k == 0:
            first = plant.x - x0
        if readings is not None:
            readings.append(plant.x_meas())
    return first, plant.x - x0


def pulse(plant: Plant, height: float) -> float:
    """Apply one sample at ``height`` (N) to ``plant``, then no force for ``WAIT`` samples;
    the move, m."""
    return pulse_path(plant, height)[1]


def halve(inside: Callable[[float], bool], lo: float, hi: float) -> tuple[float, float]:
    """``STEPS`` halvings of ``[lo, hi]``, keeping ``lo`` where ``inside`` holds and ``hi``
    where it does not; the bracket left."""
    for _ in range(STEPS):
        mid = 0.5 * (lo + hi)
        if inside(mid):
            lo = mid
        else:
            hi = mid
    return lo, hi


def tables(name: str) -> list[dict[str, float]]:
    """The plant parameters of the distinct rigid draws of ``scenarios/<name>`` (SI units)."""
    battery = load_battery(scenario_path(name))
    out: list[dict[str, float]] = []
    for run in plan_runs([battery]):
        if run.case != "rigid" or run.error:
            continue
        params = dict(run.data["plant"])
        if params not in out:
            out.append(params)
    return out


class Approach:
    """One approach to the target: the table, the planner's model, and what happened.

    Parameters
    ----------
    params : dict
        The table's plant parameters.
    told : Model
        What the planner is told of the table (default: the table).

    Notes
    -----
    A field the planner learns (``told.learn``) starts as every value of its grid; each pulse
    keeps the combinations (candidates) under which it could have happened: one that moved
    the table by ``d`` moves the candidate between ``(1 - CONSISTENT)*d`` and
    ``(1 + CONSISTENT)*d`` for some breakaway the spread allows (the lowest moves it farthest,
    the highest least), one that did not leaves the candidate at rest at the highest. If none
    is left, the candidates stay as they were. The planner plans on the corner of those left
    whose pulses move the table farthest (the lowest value of each field), so if the table is
    among them a pulse moves it no farther than planned.

    Not told the breakaway's band (``told.band`` false), a candidate is kept while some
    breakaway above the sliding friction ``f_c`` explains the move (and, reading the first
    reading, ``told.first``, that reading too, within the same tolerance); a pulse that did
    not move keeps every candidate (the breakaway may be as high as any). For each corner of
    the candidates left (the lowest and highest value of each field) the lowest breakaway of
    a fresh stick is the lowest of those the recent moves imply on it, lowered by their spread
    over their number (at least ``FRESH_MARGIN`` of it), never below ``f_c``; on a stick that
    held, the proofs of its pulses on that corner; the pulse is the lowest the corners plan.
    """

    def __init__(self, params: dict[str, float], told: Model = MODELS[0]) -> None:
        self.unseen = told.unseen
        self.guard = told.guard
        model = told.params(params)
        for where, fields in (("table", params), ("model", model)):
            problems = plant_problems(fields)
            if problems:
                raise ValueError(f"the {where}: {problems[0]}")
        self.table = Plant(params)
        self.model = Plant(model)
        self.model_params = model
        self.learn = told.learn
        self.band = told.band
        self.first = told.first
        self.encoder = told.encoder
        #: What a measured move and a first reading may be off by, m: a fiftieth of
        #: ``MOVED`` on the true position; through the encoder, ``Z_NOISE`` standard
        #: deviations of the noise on them and a count.
        sigma = params.get("noise_std", 0.0) if self.encoder else 0.0
        count = params.get("x_resolution", 0.0) if self.encoder else 0.0
        self.slack_d = (Z_NOISE * sigma * math.sqrt(2.0 / REST_READS) + count
                        if self.encoder else MOVED * 0.02)
        self.slack_first = (Z_NOISE * sigma * math.sqrt(1.0 + 1.0 / REST_READS) + count
                            if self.encoder else MOVED * 0.02)
        #: Candidates still consistent with the pulses: indices into each learned grid.
        self.alive: list[tuple[int, ...]] = list(itertools.product(
            *(range(len(GRIDS[name])) for name in self.learn)))
        self._candidates: dict[tuple[int, ...], Plant] = {}
        self._corner: tuple[int, ...] = ()
        self.f_c = model["f_c"]
        if self.band:
            self.lowest = model["f_s"] * (1.0 - model.get("f_s_spread", 0.0))
            self.highest = model["f_s"] * (1.0 + model.get("f_s_spread", 0.0))
        else:
            # friction holds the table at least at f_c; it may break away as high as a pulse
            self.lowest = self.f_c
            self.highest = F_P_MAX
        #: Without the band: the moves (state, height, move) and the pulses that did not move
        #: on the present stick (state, height), and the breakaways each corner implies.
        self.moves: list[tuple[dict, float, float]] = []
        self.held: list[tuple[dict, float]] = []
        self._implied: dict[tuple[tuple[int, ...], int], float] = {}
        self._proofs: dict[tuple[tuple[int, ...], int], float] = {}
        #: Time taken (s), the error at the end (m), and the processor time the planning and
        #: the table took (s).
        self.time = 0.0
        self.cpu = 0.0
        self.error = math.inf
        #: Each pulse: the error before it and its move, m.
        self.record: list[tuple[float, float]] = []
        #: Each pulse: whether, since the planner last saw the table move, a pulse it took
        #: for one that held had moved the table (unseen: the proofs of the present stick no
        #: longer held); and how many pulses it took for held, how many of those had moved it.
        self.broken_before: list[bool] = []
        self.taken_held = 0
        self.moved_unseen = 0

    @property
    def pulses(self) -> int:
        """Pulses made."""
        return len(self.record)

    def candidate(self, key: tuple[int, ...]) -> Plant:
        """The model with the learned fields at the grid points ``key``."""
        if key not in self._candidates:
            values = {name: GRIDS[name][i] for name, i in zip(self.learn, key, strict=True)}
            self._candidates[key] = Plant({**self.model_params, **values})
        return self._candidates[key]

    def corner(self) -> Plant:
        """The model planned on: the lowest grid point of each learned field among the
        candidates left (the model itself when nothing is learned)."""
        if self.learn:
            key = tuple(min(k[i] for k in self.alive) for i in range(len(self.learn)))
            if key != self._corner:
                self._corner = key
                self.model = self.candidate(key)
        return self.model

    def corners(self) -> list[tuple[int, ...]]:
        """The lowest and highest grid point of each learned field among the candidates
        left, combined (the key ``()`` when nothing is learned)."""
        ends = [sorted({min(k[i] for k in self.alive), max(k[i] for k in self.alive)})
                for i in range(len(self.learn))]
        return list(itertools.product(*ends))

    def sift(self, state: dict, height: float, first: float, d: float, moved: bool) -> None:
        """Keep the candidates under which the pulse (``height`` N from ``state``, a move of
        ``d`` m, ``first`` m at its first reading, seen to move or not) could have
        happened."""
        if not self.learn:
            return
        if not self.band and not moved:
            return  # the breakaway may be as high as any pulse: every candidate is kept
        sign = math.copysign(1.0, height)
        left = []
        for key in self.alive:
            model = self.candidate(key)
            if not self.band:
                if self.explains(state, height, first, d, model):
                    left.append(key)
                continue
            least = sign * self.move(state, self.highest, height, model)
            if not moved:
                if least == 0.0:
                    left.append(key)
                continue
            most = sign * self.move(state, self.lowest, height, model)
            if (least <= sign * d * (1.0 + CONSISTENT) + self.slack_d
                    and most >= sign * d * (1.0 - CONSISTENT) - self.slack_d):
                left.append(key)
        if left:
            self.alive = left

    def explains(self, state: dict, height: float, first: float, d: float,
                 model: Plant) -> bool:
        """Whether some breakaway above ``f_c`` moves ``model`` by ``d`` (m) within the
        tolerance, and, reading the first reading, moves it by ``first`` (m) there too (a
        first reading of at most twice ``slack_first`` is not compared)."""
        sign = math.copysign(1.0, height)
        if (sign * self.move(state, self.f_c, height, model)
                < sign * d * (1.0 - CONSISTENT) - self.slack_d):
            return False  # even breaking away at f_c it does not move that far
        if not self.first or abs(first) <= 2.0 * self.slack_first:
            return True  # (a first reading within twice its slack tells no candidate apart)
        b = self.implied_on(state, height, d, model)
        model.set_state(state)
        model.f_s_now = b
        at_first = pulse_path(model, height)[0]
        return abs(at_first - first) <= CONSISTENT * abs(first) + self.slack_first

    def implied_on(self, state: dict, height: float, d: float, model: Plant) -> float:
        """Breakaway (N, between ``f_c`` and the height) at which ``model`` moves ``d`` (m)
        from ``state`` (bisection: a higher breakaway moves it less)."""
        sign = math.copysign(1.0, height)
        lo, hi = halve(lambda b: sign * self.move(state, b, height, model) > sign * d,
                       self.f_c, max(abs(height), self.f_c))
        return 0.5 * (lo + hi)

    def move(self, state: dict, breakaway: float, height: float,
             model: Plant | None = None) -> float:
        """The move (m) of one sample at ``height`` (N) from ``state`` with the breakaway at
        ``breakaway`` (N), read ``WAIT`` samples later, on ``model`` (default: the
        planner's)."""
        model = self.model if model is None else model
        model.set_state(state)
        model.f_s_now = breakaway
        return pulse(model, height)

    def plan(self, state: dict, breakaway: float, e: float, model: Plant | None = None
             ) -> float:
        """Height (N, along e) of the highest one-sample pulse whose move at ``breakaway`` is
        at most ``|e|``, on ``model`` (default: the planner's)."""
        sign = math.copysign(1.0, e)
        if sign * self.move(state, breakaway, sign * F_P_MAX, model) <= abs(e):
            return sign * F_P_MAX
        lo, _ = halve(lambda h: sign * self.move(state, breakaway, sign * h, model) <= abs(e),
                      0.0, F_P_MAX)
        return sign * lo

    def proof(self, state: dict, height: float, breakaway: float,
              model: Plant | None = None) -> float:
        """Least breakaway (N) at which the model says ``height`` does not move the table
        from ``state``, searched above ``breakaway``, on ``model`` (default: the
        planner's)."""
        return halve(lambda b: self.move(state, b, height, model) != 0.0,
                     breakaway, max(self.highest, breakaway))[1]

    def fresh(self, key: tuple[int, ...]) -> float:
        """Lowest breakaway (N) of a fresh stick on the candidate ``key``, from the recent
        moves (not told the band)."""
        model = self.candidate(key)
        start = max(len(self.moves) - FRESH_MOVES, 0)
        seen = []
        for i in range(start, len(self.moves)):
            if (key, i) not in self._implied:
                state, height, d = self.moves[i]
                self._implied[key, i] = self.implied_on(state, height, d, model)
            seen.append(self._implied[key, i])
        if not seen:
            return self.f_c
        low = min(seen)
        return max(low - max((max(seen) - low) / len(seen), FRESH_MARGIN * low), self.f_c)

    def plan_open(self, state: dict, e: float) -> float:
        """Not told the band: the lowest height (N, along e) the corners plan, each for its
        lowest breakaway still possible."""
        heights = []
        for key in self.corners():
            model = self.candidate(key)
            breakaway = self.fresh(key)
            for j, (held_state, held) in enumerate(self.held):
                if (key, j) not in self._proofs:
                    self._proofs[key, j] = self.proof(held_state, held, self.f_c, model)
                breakaway = max(breakaway, self._proofs[key, j])
            heights.append(self.plan(state, breakaway, e, model))
        return min(heights, key=abs)

    def run(self, e0: float = E0, budget: float = BUDGET) -> Approach:
        """Approach a target ``e0`` (m) away, for at most ``budget`` s.

        The planner's error and moves are the table's true ones, or, through the encoder
        (``encoder``), read: the position at rest is the mean of the last ``REST_READS``
        readings after a pulse, a move the change of that mean, the first reading the one
        after the pulse's sample less the mean before; a move within ``slack_d`` of none is
        taken for none. The record holds the true error and move.
        """
        start = time.process_time()
        table = self.table
        readings = []
        for _ in range(WAIT):
            table.step(0.0, T)
            readings.append(table.x_meas())
        rest = statistics.fmean(readings[-REST_READS:])
        target = table.x + e0
        breakaway = self.lowest
        broken = False
        while self.time + CYCLE <= budget + 1e-12:
            e = target - table.x
            seen = target - rest if self.encoder else e
            if abs(seen) <= STOP:
                break
            state = table.state()
            self.corner()
            if self.band:
                height = self.plan(state, breakaway, seen)
            else:
                height = self.plan_open(state, seen)
            if self.guard and breakaway > self.lowest:
                bound = self.plan(state, self.lowest,
                                  math.copysign(1.5 * abs(seen) + COUNT, seen))
                height = math.copysign(min(abs(height), abs(bound)), seen)
            draws = table.stick_draws
            readings: list[float] | None = [] if self.encoder else None
            first, d = pulse_path(table, height, readings)
            self.time += CYCLE
            self.record.append((e, d))
            self.broken_before.append(broken)
            if readings is not None:
                before, rest = rest, statistics.fmean(readings[-REST_READS:])
                first, d_seen = readings[0] - before, rest - before
                moved = abs(d_seen) > self.slack_d
            else:
                d_seen = d
                moved = (abs(d) > self.unseen if self.unseen else
                         (d != 0.0 or table.stick_draws != draws))
            self.sift(state, height, first, d_seen, moved)
            self.corner()
            if moved:
                broken = False
                breakaway = self.lowest
                self.moves.append((state, height, d_seen))
                self.held = []
                self._proofs.clear()
            else:
                self.taken_held += 1
                if d != 0.0:
                    # taken for held, it moved the table: the proofs of this stick are broken
                    self.moved_unseen += 1
                    broken = True
                self.held.append((state, height))
                if self.band:
                    breakaway = self.proof(state, height, breakaway)
        self.error = abs(target - table.x)
        self.cpu = time.process_time() - start
        return self


class FastApproach(Approach):
    """:class:`Approach` not told the breakaway's band, whose candidates are tables of the
    one-pulse model (:class:`papwc_studies.one_pulse.TableEvidence`: the table's ``m``, ``c``
    and Stribeck exponent told, its ripple and LuGre's bristles not modelled), ``f_c``
    learned where ``told.learn`` names it. A move rules out the candidates that cannot make
    it, the first readings those that fit them worst (a chi-square); the pulse is planned
    on every candidate left.
    """

    def __init__(self, params: dict[str, float], told: Model) -> None:
        if told.band or not told.learn:
            raise ValueError("the one-pulse model's planner learns, not told the band")
        super().__init__(params, told)
        self.alive = []  # the candidates are those of ``evidence``
        grids = {name: GRIDS[name] for name in told.learn}
        if told.slid:
            # f_c within the band the exact-model controller's slides leave on this table
            lo, hi = f_c_band(params)
            grids["f_c"] = tuple(f for f in grids["f_c"] if lo <= f <= hi) or (
                min(grids["f_c"], key=lambda f: abs(f - 0.5 * (lo + hi))),)
        self.evidence = TableEvidence(grids, self.model_params, T)

    @property
    def tables(self) -> Candidates:
        """The candidate tables."""
        return self.evidence.tables

    def corner(self) -> Plant:
        """The planner's plant (unused: the candidates are planned on the one-pulse
        model)."""
        return self.model

    def sift(self, state: dict, height: float, first: float, d: float, moved: bool) -> None:
        """Keep the candidates that explain a move; note a pulse that held."""
        sign = math.copysign(1.0, height)
        if moved:
            # (without the first reading, no residual of it counts)
            self.evidence.observe_move(
                height, sign * first, sign * d,
                self.slack_first / Z_NOISE if self.first else math.inf, self.slack_d / Z_NOISE)
        else:
            self.evidence.observe_held(height)

    def plan_open(self, state: dict, e: float) -> float:
        """The lowest height (N, along e) the candidates left plan, each for its lowest
        breakaway still possible."""
        return math.copysign(self.evidence.plan(abs(e), F_P_MAX)[0], e)


def runaway(e: float, d: float) -> bool:
    """Whether a pulse fired at the error e moved the table d (both m) beyond the runaway
    bound ``1.5*|e|`` plus one count."""
    return abs(d) > 1.5 * abs(e) + COUNT


def beyond(record: Sequence[tuple[float, float]], far: bool) -> tuple[int, int, float]:
    """Of the pulses of ``record`` ((e, d) in m) that moved, fired at ``|e| >= 1 um`` (``far``)
    or below: how many, how many moved beyond the runaway bound (:func:`runaway`), and the
    largest move of those (m, 0: none)."""
    moving = [(e, d) for e, d in record if d != 0.0 and (abs(e) >= 1e-6) == far]
    out = [abs(d) for e, d in moving if runaway(e, d)]
    return len(moving), len(out), max(out, default=0.0)


def identified(params: dict[str, float], fields: tuple[str, ...] = IDENTIFIED
               ) -> dict[str, float]:
    """What ``papwc identify`` finds on the table: the ``fields`` it fits, from a log of its
    excitation with the defaults of ``papwc identify --design`` (60 s at 100 Hz) applied to
    the table and read through its encoder; a deviation not chosen at its value of none (0).
    For the fields of :data:`IDENTIFIED_WITH_BAND` the log is made under another seed (that
    of ``[battery] identify_first``), so that it does not see the draws the approach meets."""
    from papwc.battery.identify_first import excitation_seed
    from papwc.identify import DESIGN_DURATION, DESIGN_F_P_MAX, DESIGN_T, DESIGN_TRAVEL
    from papwc.identify.excitation import apply_to_plant, design
    from papwc.identify.fit import identify

    u = design(DESIGN_T, DESIGN_F_P_MAX, DESIGN_TRAVEL, DESIGN_DURATION)
    if fields == IDENTIFIED_WITH_BAND:
        params = {**params, "seed": excitation_seed(params.get("seed", 0))}
    found = identify(apply_to_plant(u, DESIGN_T, params)).plant
    return {name: float(found.get(name, 0.0)) for name in fields}


def approach(params: dict[str, float], told: Model) -> Approach:
    """:meth:`Approach.run` from ``E0`` within ``BUDGET`` (a worker's task); told what
    ``papwc identify`` finds on the table first where the model says so."""
    if told.identified:
        found = identified(params, IDENTIFIED_WITH_BAND if "f_s_spread" in told.identified
                           else IDENTIFIED)
        told = told._replace(told={**told.told,
                                   **{name: found[name] for name in told.identified}})
    return (FastApproach if told.fast else Approach)(params, told).run()


def _ignore_interrupt() -> None:
    """Initializer of the study's worker processes: they ignore Ctrl-C, which the terminal
    sends to the whole process group; the main process is interrupted, says so in one line,
    and the pool's exit terminates them."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def rows(text: str) -> tuple[int, ...]:
    """An argparse type: row numbers of :data:`MODELS` (1-based), separated by commas."""
    parse = whole_number(1, len(MODELS))
    out = tuple(parse(part.strip()) for part in text.split(","))
    if len(set(out)) != len(out):
        raise argparse.ArgumentTypeError(f"{text!r} names a row twice")
    return out


def files(text: str) -> tuple[str, ...]:
    """An argparse type: scenario files of :data:`FILE_CHOICES`, separated by commas."""
    out = tuple(part.strip() for part in text.split(","))
    for name in out:
        if name not in FILE_CHOICES:
            raise argparse.ArgumentTypeError(
                f"{name!r} is not one of {', '.join(FILE_CHOICES)}")
    if len(set(out)) != len(out):
        raise argparse.ArgumentTypeError(f"{text!r} names a file twice")
    return out


def main(argv: Sequence[str] | None = None) -> None:
    """Print, per file and model, what the approaches reached.

    ``argv`` (default ``sys.argv[1:]``): ``--tables N`` (1 to ``TABLES_MAX``: at most N
    tables of each file, default all), ``--rows K,L,...`` (the models of :data:`MODELS`
    by number from 1, default all, each once), ``--files A,B,...`` (the scenario files whose
    rigid draws are the tables, of :data:`FILE_CHOICES`, default :data:`FILES`); anything
    else is refused (exit 2).
    """
    parser = argparse.ArgumentParser(
        prog="python -m papwc_studies.ceiling",
        description="what one-sample pulses planned for the lowest breakaway still possible "
                    "reach on the Monte Carlo's rigid tables when the planner knows the table "
                    "or learns part of it")
    parser.add_argument("--tables", type=whole_number(1, TABLES_MAX), default=TABLES_MAX,
                        help=f"tables of each file (1 to {TABLES_MAX}, default all)")
    parser.add_argument("--rows", type=rows, default=tuple(range(1, len(MODELS) + 1)),
                        help=f"the models by number, 1 to {len(MODELS)}, separated by commas "
                             "(default all)")
    parser.add_argument("--files", type=files, default=FILES,
                        help="the scenario files whose rigid draws are the tables, separated "
                             f"by commas: {', '.join(FILE_CHOICES)} (default "
                             f"{','.join(FILES)})")
    args = parser.parse_args(argv)
    count = args.tables
    models = [MODELS[k - 1] for k in args.rows]
    print(f"from rest {E0 * 1e6:g} um from the target, {BUDGET:g} s, one pulse per "
          f"{CYCLE:g} s, ending at |e| <= {STOP * 1e6:g} um; the planner reads the true "
          "position (through the table's encoder where its row says so)")
    workers = min(2, os.cpu_count() or 1)
    with Pool(workers, initializer=_ignore_interrupt) as pool:
        for name in args.files:
            found = tables(name)[:count]
            for told in models:
                if "f_s_spread" in told.told and not any(p.get("f_s_spread") for p in found):
                    continue  # LuGre: no random stiction to take wider
                if told.identified and any(p.get("sigma_0") for p in found):
                    continue  # LuGre: papwc identify has no model of it
                done = pool.starmap(approach, [(params, told) for params in found])
                reached = sum(a.error <= 1e-6 for a in done)
                times = [a.time for a in done if a.error <= 1e-6]
                median = f"{statistics.median(times):.2f} s" if times else "-"
                record = [pulse for a in done for pulse in a.record]
                runaways = []
                for far in (True, False):
                    moving, out, largest = beyond(record, far)
                    runaways.append(f"{out}/{moving}" + (f" (largest {largest * 1e6:.1f} um)"
                                                         if out else ""))
                unseen = ""
                if told.encoder or told.unseen:
                    after = sum(1 for a in done
                                for (e, d), broken in zip(a.record, a.broken_before, strict=True)
                                if broken and abs(e) >= 1e-6 and runaway(e, d))
                    unseen = (f"; taken for held {sum(a.taken_held for a in done)} pulses, "
                              f"{sum(a.moved_unseen for a in done)} of them moved the table; "
                              f"runaways at |e| >= 1 um after such a pulse on the same stick "
                              f"{after}")
                print(f"{name}, {told.label}: within 1 um {reached}/{len(done)}, median "
                      f"{median}, {len(record)} pulses, runaways at |e| >= 1 um "
                      f"{runaways[0]}, below {runaways[1]}; "
                      f"{1e3 * sum(a.cpu for a in done) / max(len(record), 1):.0f} ms "
                      f"of processor time a pulse{unseen}")


if __name__ == "__main__":
    import sys

    from papwc.exit_status import run_command

    sys.exit(run_command("python -m papwc_studies.ceiling", main))
