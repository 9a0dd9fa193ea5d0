"""What planning for the lowest breakaway still possible reaches when the table is known.

The measurement behind the README's note on the bounds of the exact-model controller on the
Monte Carlo's rigid tables. Those tables (the rigid draws of ``scenarios/realism_mc_fresh.toml``
and ``scenarios/realism_mc_lugre_fresh.toml``: Stribeck friction, ripple, an actuator lag,
random stiction or LuGre pre-sliding, each drawn) are stepped with the model layer's plant
(:class:`papwc.model.dynamics.Plant`). The *planner* knows a model of the table -- the plant's
parameters, or some of them wrong (:data:`MODELS`) -- but never the breakaway force drawn at
the present stick, and reads the table's true position (no encoder: a ceiling). From rest at
``E0`` from the target it repeats, while ``|e|`` is above ``STOP`` and the time allows:

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
how many reached 1 um within ``BUDGET`` s, the median time, the pulses, how many of the
pulses that moved at ``|e| >= 1 um`` and below went beyond ``1.5*|e|`` plus one count (the
runaway bound of R4 and R5) with the largest such move, and the processor time a pulse took
(the planning's simulations and the table's step). The rows say whether R1 and R4 are
within reach of the policy on these tables, and which of the table's parameters a controller
must learn for them.

Run ``python -m papwc.studies.ceiling [--tables N]`` (N: at most that many tables of each
file; twelve to sixteen minutes for all on two cores); it prints one line per model and file.
"""

from __future__ import annotations

import itertools
import math
import os
import statistics
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import NamedTuple

from papwc.battery.plan import plan_runs
from papwc.battery.schema import load_battery
from papwc.model.dynamics import Plant
from papwc.model.plant import plant_problems
from papwc.resources import scenario_file
from papwc.studies.counts import MOVED, parse_count

__all__ = ["BUDGET", "E0", "MODELS", "Approach", "Model", "approach", "beyond", "main", "tables"]

#: Scenario files whose rigid draws are the tables.
FILES = ("realism_mc_fresh.toml", "realism_mc_lugre_fresh.toml")
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


class Model(NamedTuple):
    """What the planner is told of the table: ``told`` fields replace the table's, ``scale``
    fields are the table's times a factor, and it does not see moves up to ``unseen`` (m; 0:
    it sees every stick anew). With ``guard``, no pulse above a proof may move the table
    beyond the runaway bound if the table stuck anew unseen and broke away at the lowest
    force the spread allows. The fields of ``learn`` the planner does not know: it learns
    them over :data:`GRIDS` from its pulses (:class:`Approach`)."""

    label: str
    told: dict[str, float] = {}
    scale: dict[str, float] = {}
    unseen: float = 0.0
    guard: bool = False
    learn: tuple[str, ...] = ()

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
)
#: What a planner learns a field over: values from the one under which a pulse moves the
#: table farthest (no lag; friction falling off at the lowest speed) to the least far,
#: spanning the Monte Carlo's ranges.
GRIDS = {
    "tau_u": tuple(k * 5e-4 for k in range(11)),
    "v_s": tuple(2e-4 * 1.5**k for k in range(9)),
}
#: Relative tolerance of a candidate's move against a pulse's measured one (at 0.05 the
#: LuGre tables, whose breakaway is not redrawn, kept candidates that ran away).
CONSISTENT = 0.1
#: Largest number of tables taken of each file.
TABLES_MAX = 1000


def pulse(plant: Plant, height: float) -> float:
    """Apply one sample at ``height`` (N) to ``plant``, then no force for ``WAIT`` samples;
    the move, m."""
    x0 = plant.x
    plant.step(height, T)
    for _ in range(WAIT):
        plant.step(0.0, T)
    return plant.x - x0


def tables(name: str) -> list[dict[str, float]]:
    """The plant parameters of the distinct rigid draws of ``scenarios/<name>`` (SI units)."""
    battery = load_battery(scenario_file(name))
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
        #: Candidates still consistent with the pulses: indices into each learned grid.
        self.alive: list[tuple[int, ...]] = list(itertools.product(
            *(range(len(GRIDS[name])) for name in self.learn)))
        self._candidates: dict[tuple[int, ...], Plant] = {}
        self._corner: tuple[int, ...] = ()
        self.lowest = model["f_s"] * (1.0 - model.get("f_s_spread", 0.0))
        self.highest = model["f_s"] * (1.0 + model.get("f_s_spread", 0.0))
        #: Time taken (s), the error at the end (m), and the processor time the planning and
        #: the table took (s).
        self.time = 0.0
        self.cpu = 0.0
        self.error = math.inf
        #: Each pulse: the error before it and its move, m.
        self.record: list[tuple[float, float]] = []

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

    def sift(self, state: dict, height: float, d: float, moved: bool) -> None:
        """Keep the candidates under which the pulse (``height`` N from ``state``, a move of
        ``d`` m, seen to move or not) could have happened."""
        if not self.learn:
            return
        sign = math.copysign(1.0, height)
        left = []
        for key in self.alive:
            model = self.candidate(key)
            least = sign * self.move(state, self.highest, height, model)
            if not moved:
                if least == 0.0:
                    left.append(key)
                continue
            most = sign * self.move(state, self.lowest, height, model)
            if (least <= sign * d * (1.0 + CONSISTENT) + MOVED * 0.02
                    and most >= sign * d * (1.0 - CONSISTENT) - MOVED * 0.02):
                left.append(key)
        if left:
            self.alive = left

    def move(self, state: dict, breakaway: float, height: float,
             model: Plant | None = None) -> float:
        """The move (m) of one sample at ``height`` (N) from ``state`` with the breakaway at
        ``breakaway`` (N), read ``WAIT`` samples later, on ``model`` (default: the
        planner's)."""
        model = self.model if model is None else model
        model.set_state(state)
        model.f_s_now = breakaway
        return pulse(model, height)

    def plan(self, state: dict, breakaway: float, e: float) -> float:
        """Height (N, along e) of the highest one-sample pulse whose move at ``breakaway`` is
        at most ``|e|``."""
        sign = math.copysign(1.0, e)
        if sign * self.move(state, breakaway, sign * F_P_MAX) <= abs(e):
            return sign * F_P_MAX
        lo, hi = 0.0, F_P_MAX
        for _ in range(STEPS):
            mid = 0.5 * (lo + hi)
            if sign * self.move(state, breakaway, sign * mid) <= abs(e):
                lo = mid
            else:
                hi = mid
        return sign * lo

    def proof(self, state: dict, height: float, breakaway: float) -> float:
        """Least breakaway (N) at which the model says ``height`` does not move the table
        from ``state``, searched above ``breakaway``."""
        lo, hi = breakaway, max(self.highest, breakaway)
        for _ in range(STEPS):
            mid = 0.5 * (lo + hi)
            if self.move(state, mid, height) != 0.0:
                lo = mid
            else:
                hi = mid
        return hi

    def run(self, e0: float = E0, budget: float = BUDGET) -> Approach:
        """Approach a target ``e0`` (m) away, for at most ``budget`` s."""
        start = time.process_time()
        table = self.table
        for _ in range(WAIT):
            table.step(0.0, T)
        target = table.x + e0
        breakaway = self.lowest
        while self.time + CYCLE <= budget + 1e-12:
            e = target - table.x
            if abs(e) <= STOP:
                break
            state = table.state()
            self.corner()
            height = self.plan(state, breakaway, e)
            if self.guard and breakaway > self.lowest:
                bound = self.plan(state, self.lowest, math.copysign(1.5 * abs(e) + COUNT, e))
                height = math.copysign(min(abs(height), abs(bound)), e)
            draws = table.stick_draws
            d = pulse(table, height)
            self.time += CYCLE
            self.record.append((e, d))
            moved = (abs(d) > self.unseen if self.unseen else
                     (d != 0.0 or table.stick_draws != draws))
            self.sift(state, height, d, moved)
            self.corner()
            if moved:
                breakaway = self.lowest
            else:
                breakaway = self.proof(state, height, breakaway)
        self.error = abs(target - table.x)
        self.cpu = time.process_time() - start
        return self


def beyond(record: Sequence[tuple[float, float]], far: bool) -> tuple[int, int, float]:
    """Of the pulses of ``record`` ((e, d) in m) that moved, fired at ``|e| >= 1 um`` (``far``)
    or below: how many, how many moved beyond the runaway bound ``1.5*|e|`` plus one count,
    and the largest move of those (m, 0: none)."""
    moving = [(e, d) for e, d in record if d != 0.0 and (abs(e) >= 1e-6) == far]
    out = [abs(d) for e, d in moving if abs(d) > 1.5 * abs(e) + COUNT]
    return len(moving), len(out), max(out, default=0.0)


def approach(params: dict[str, float], told: Model) -> Approach:
    """:meth:`Approach.run` from ``E0`` within ``BUDGET`` (a worker's task)."""
    return Approach(params, told).run()


def main(argv: Sequence[str] | None = None) -> None:
    """Print, per file and model, what the approaches reached.

    ``argv`` (default ``sys.argv[1:]``): ``--tables N`` (1 to ``TABLES_MAX``: at most N
    tables of each file, default all); anything else is refused (exit 2).
    """
    count = parse_count(argv, "python -m papwc.studies.ceiling",
                        "what one-sample pulses planned for the lowest breakaway still "
                        "possible reach on the Monte Carlo's rigid tables when the planner "
                        "knows the table", "--tables", TABLES_MAX, TABLES_MAX,
                        "tables of each file")
    print(f"from rest {E0 * 1e6:g} um from the target, {BUDGET:g} s, one pulse per "
          f"{CYCLE:g} s, ending at |e| <= {STOP * 1e6:g} um; the planner reads the true "
          "position")
    workers = min(2, os.cpu_count() or 1)
    with ProcessPoolExecutor(workers) as pool:
        for name in FILES:
            found = tables(name)[:count]
            for told in MODELS:
                if "f_s_spread" in told.told and not any(p.get("f_s_spread") for p in found):
                    continue  # LuGre: no random stiction to take wider
                done = list(pool.map(approach, found, [told] * len(found)))
                reached = sum(a.error <= 1e-6 for a in done)
                times = [a.time for a in done if a.error <= 1e-6]
                median = f"{statistics.median(times):.2f} s" if times else "-"
                record = [pulse for a in done for pulse in a.record]
                runaways = []
                for far in (True, False):
                    moving, out, largest = beyond(record, far)
                    runaways.append(f"{out}/{moving}" + (f" (largest {largest * 1e6:.1f} um)"
                                                         if out else ""))
                print(f"{name}, {told.label}: within 1 um {reached}/{len(done)}, median "
                      f"{median}, {len(record)} pulses, runaways at |e| >= 1 um "
                      f"{runaways[0]}, below {runaways[1]}; "
                      f"{1e3 * sum(a.cpu for a in done) / max(len(record), 1):.0f} ms "
                      "of processor time a pulse")


if __name__ == "__main__":
    import sys

    from papwc.exit_status import run_command

    sys.exit(run_command("python -m papwc.studies.ceiling", main))
