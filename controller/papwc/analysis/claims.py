"""The simulation claims of the paper's Section 4, each with a computed metric and criterion.

Every claim is evaluated on runs of the paper's scenario: its value under the
scenario's settings (the *default reading*) and, where that does not reproduce
it, under a *reading*: other values of the settings the paper leaves open
(K_c, the initial covariance, the pulse fed to the estimator, the treatment of
the amplitude floor, ...), applied to every controller of a kind. The readings
are found by :func:`search_readings` (``papwc reproduce --readings``); the ones
it found are kept in :data:`KNOWN_READINGS` and re-run by every ``papwc
reproduce``, so that the claims table always shows measured values.

Controllers take a *role* by kind and pulse-width bound: ``pwc_bounded``,
``pwc_unbounded``, ``papwc_bounded``, ``papwc_unbounded``; the paper's last
claim also runs each PAPWC without updating its covariance (role suffix
``_fixed_covariance``).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from papwc.analysis.claim_runs import _Runs
from papwc.analysis.paper import d_min
from papwc.analysis.readings import (
    KNOWN_BEST,
    KNOWN_READINGS,
    SEARCH_GRID,
    Reading,
    search_range_text,
)
from papwc.analysis.run_metrics import (
    FIRST_PULSES,
    FIXED,
    ROLES,
    RunMetrics,
    adaptation_per_pulse,
    pulse_list,
    role_of,
    run_metrics,
    sign_switches,
)
from papwc.controllers.settings import SETTINGS_BY_NAME
from papwc.master import RunResult
from papwc.model.pulse import b_coulomb

if TYPE_CHECKING:
    from papwc.scenario import Scenario

__all__ = [
    "CLAIMS",
    "CLAIMS_COLUMNS",
    "KNOWN_BEST",
    "KNOWN_READINGS",
    "SEARCH_GRID",
    "Claim",
    "ClaimRow",
    "ClaimsTable",
    "Reading",
    "RunMetrics",
    "adaptation_per_pulse",
    "claims_markdown",
    "evaluate_claims",
    "pulse_list",
    "run_metrics",
    "search_readings",
    "sign_switches",
]

#: Columns of ``claims.csv``.
CLAIMS_COLUMNS = ["claim", "metric", "paper", "default_value", "reproduced_by_default",
                  "reading", "reading_value", "reproduced_by_reading"]

#: The paper's error band of its PAPWC simulation, m (Section 4).
PAPER_TOLERANCE = 2e-5
#: "Much faster": at least this ratio of the adaptation speeds.
MUCH_FASTER = 2.0
#: Relative tolerance of "peak-to-peak = d_min".
D_MIN_RTOL = 0.01


# --- the claims -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Context:
    """The paper's reference values for the scenario: b (m/s**2), d_min of Eq. (19) (m)."""

    b: float
    d_min: float


@dataclass(frozen=True)
class Outcome:
    """A claim's value under one reading and whether it holds (None: cannot be evaluated)."""

    value: str
    holds: bool | None


@dataclass(frozen=True)
class Claim:
    """One simulation claim of Section 4.

    ``evaluate(metrics, context)`` gets the metrics by role (every role of
    ``roles`` present) and returns the claim's value and whether it holds.
    """

    key: str
    claim: str
    metric: str
    paper: str
    roles: tuple[str, ...]
    evaluate: Callable[[Mapping[str, RunMetrics], Context], Outcome]

    @property
    def kinds(self) -> frozenset[str]:
        """Controller kinds whose settings the claim depends on."""
        return frozenset(r.split("_")[0] for r in self.roles)

    def outcome(self, metrics: Mapping[str, RunMetrics], context: Context) -> Outcome:
        """The claim on ``metrics``; "n/a" when a role is missing, "run failed" on an error."""
        missing = [r for r in self.roles if r not in metrics]
        if missing:
            return Outcome("n/a: the scenario has no " + ", ".join(missing) + " controller",
                           None)
        failed = [metrics[r] for r in self.roles if metrics[r].error]
        if failed:
            return Outcome(f"run failed: {failed[0].label}: {failed[0].error}", False)
        return self.evaluate(metrics, context)


def _widths(widths: tuple[int, ...]) -> str:
    return "{" + ", ".join(str(w) for w in widths) + "}" if widths else "none"


def _limit_cycle_d_min(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    r = m["pwc_bounded"]
    ratio = r.cycle_p2p_m / c.d_min
    holds = r.limit_cycle and r.window_widths == (1,) and abs(ratio - 1.0) <= D_MIN_RTOL
    return Outcome(f"{ratio:.4f} (peak-to-peak {r.cycle_p2p_m:.4g} m, pulse widths "
                   f"{_widths(r.window_widths)} samples, limit cycle {r.limit_cycle})", holds)


def _unbounded_2t(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    r = m["pwc_unbounded"]
    ratio = r.cycle_p2p_m / c.d_min
    holds = r.limit_cycle and r.window_widths == (2,) and ratio > 1.0 + D_MIN_RTOL
    return Outcome(f"widths {_widths(r.window_widths)} samples; peak-to-peak "
                   f"{r.cycle_p2p_m:.4g} m = {ratio:.3f} d_min; limit cycle {r.limit_cycle}",
                   holds)


def _bounded_closer(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    bb, bu = m["pwc_bounded"].b_hat / c.b, m["pwc_unbounded"].b_hat / c.b
    return Outcome(f"b_hat/b {bb:.3f} bounded, {bu:.3f} unbounded",
                   abs(bb - 1.0) < abs(bu - 1.0))


def _final_error(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    rb, ru = m["papwc_bounded"], m["papwc_unbounded"]
    holds = all(abs(r.final_error_m) <= PAPER_TOLERANCE and not r.limit_cycle
                for r in (rb, ru))
    return Outcome(f"|e| {abs(rb.final_error_m):.3g} m bounded, {abs(ru.final_error_m):.3g} m "
                   f"unbounded; limit cycle {rb.limit_cycle}/{ru.limit_cycle}", holds)


def _ratio(a: float, b: float) -> float:
    """a / b; inf for a > 0 = b, NaN for 0/0 or a NaN."""
    if b == 0.0:
        return math.inf if a > 0.0 else math.nan
    return a / b


def _adapts_faster(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    qb = _ratio(m["papwc_bounded"].adaptation, m["pwc_bounded"].adaptation)
    qu = _ratio(m["papwc_unbounded"].adaptation, m["pwc_unbounded"].adaptation)
    holds = qb >= MUCH_FASTER and qu >= MUCH_FASTER
    return Outcome(
        f"ratio {qb:.2f} bounded ({m['papwc_bounded'].adaptation:.3g} / "
        f"{m['pwc_bounded'].adaptation:.3g} m/s²), {qu:.2f} unbounded "
        f"({m['papwc_unbounded'].adaptation:.3g} / {m['pwc_unbounded'].adaptation:.3g} m/s²)",
        holds)


def _two_pulses(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    r = m["papwc_unbounded"]
    holds = r.pulses == 2 and abs(r.final_error_m) <= PAPER_TOLERANCE
    return Outcome(f"{r.pulses} pulses ({r.signs or 'none'}), |e| {abs(r.final_error_m):.3g} m",
                   holds)


def _b_hat_above(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    q = m["papwc_unbounded"].b_hat / c.b
    return Outcome(f"b_hat/b = {q:.3f}", q > 1.0)


def _fewer_switches(m: Mapping[str, RunMetrics], c: Context) -> Outcome:
    on = m["papwc_bounded"].switches + m["papwc_unbounded"].switches
    off_b, off_u = m["papwc_bounded" + FIXED], m["papwc_unbounded" + FIXED]
    off = off_b.switches + off_u.switches
    return Outcome(
        f"{on} with update, {off} without; |e| without update {abs(off_b.final_error_m):.3g} m "
        f"bounded, {abs(off_u.final_error_m):.3g} m unbounded", on < off)


#: The simulation claims of Section 4, in the paper's order.
CLAIMS: tuple[Claim, ...] = (
    Claim("limit_cycle_d_min",
          "PWC, t_p,max = 0.03 s: the limit cycle around the reference is d_min of Eq. (19)",
          "PWC t_p,max = 0.03 s, last iteration: peak-to-peak of x over its last quarter / "
          "d_min(T) of Eq. (19), and the widths of the pulses there; reproduced if pulses of "
          "both signs, all one sample wide, ratio within 1 %",
          "limit cycle of amplitude d_min = 1.9e-4 m (Fig. 3)", ("pwc_bounded",),
          _limit_cycle_d_min),
    Claim("unbounded_2t_cycle",
          "PWC, t_p,max = ∞: overshoot larger than d_min because the pulse width is now 2T",
          "PWC t_p,max = ∞, last iteration: widths of the pulses in the last quarter and "
          "peak-to-peak of x there / d_min; reproduced if a limit cycle of pulses all two "
          "samples wide, ratio > 1.01",
          "overshoot > d_min, pulse width 2T (Fig. 3)", ("pwc_unbounded",), _unbounded_2t),
    Claim("bounded_b_hat_closer",
          "PWC: b_hat with bounded t_p,max ends closer to b than with t_p,max = ∞",
          "|b_hat/b - 1| at the end of the last iteration, PWC bounded vs unbounded; "
          "reproduced if smaller with the bound",
          "bounded closer to b (Fig. 7)", ("pwc_bounded", "pwc_unbounded"), _bounded_closer),
    Claim("papwc_final_error",
          "PAPWC: final error around zero, within the 2e-5 m band",
          "|x_ref - x| at the end of the last iteration, both PAPWC; reproduced if both "
          "<= 2e-5 m and no limit cycle",
          "final error around zero, at most 2e-5 m (Fig. 4)",
          ("papwc_bounded", "papwc_unbounded"), _final_error),
    Claim("papwc_adapts_faster",
          "PAPWC adapts much faster than PWC with the same initial covariance",
          f"mean |change of b_hat| per pulse over the first {FIRST_PULSES} pulses of "
          "iteration 1, PAPWC / PWC, for the bounded and the unbounded pair; reproduced if "
          f"both ratios >= {MUCH_FASTER:g}",
          "adaptation of PAPWC much faster (Fig. 7, 8)", ROLES, _adapts_faster),
    Claim("unbounded_two_pulses",
          "PAPWC, t_p,max = ∞: two pulses reach the reference in the 10th iteration",
          "pulses in the last iteration of PAPWC t_p,max = ∞ (their signs); reproduced if "
          "exactly 2 and |e| <= 2e-5 m at the end",
          "two pulses in the 10th iteration (Fig. 6)", ("papwc_unbounded",), _two_pulses),
    Claim("unbounded_b_hat_above_b",
          "PAPWC, t_p,max = ∞: b_hat ends above b",
          "b_hat/b at the end of the last iteration of PAPWC t_p,max = ∞; reproduced if > 1",
          "b_hat larger than b (Fig. 8)", ("papwc_unbounded",), _b_hat_above),
    Claim("covariance_update_fewer_switches",
          "PAPWC without updating the covariance: more sign switching of the pulses",
          "sign changes between consecutive pulses in the last iteration, both PAPWC summed, "
          "with P updated by Eq. (14) vs P kept at P(0) (update_covariance = false); "
          "reproduced if fewer with the update",
          "more sign switching without the update; final error not much affected",
          ("papwc_bounded", "papwc_unbounded", "papwc_bounded" + FIXED,
           "papwc_unbounded" + FIXED), _fewer_switches),
)


def claim_context(scenario: Scenario) -> Context:
    """b and d_min of Eq. (19) for the scenario's plant, PWC amplitude and sample period."""
    pwc = [s for s in scenario.controllers if s.kind == "pwc"]
    f_p = pwc[0].f_p_max if pwc else SETTINGS_BY_NAME["f_p_max"].default
    p, T = scenario.plant, scenario.maneuver.T
    return Context(b=b_coulomb(f_p, p["m"], p["f_c"]),
                   d_min=d_min(f_p, T, p["m"], p["f_c"], p["c"]))


# --- the table --------------------------------------------------------------------------------


@dataclass
class ClaimRow:
    """One row of the claims table."""

    claim: Claim
    default: Outcome
    reading: Reading | None = None
    reading_outcome: Outcome | None = None
    reading_note: str = ""
    also_holds: int | None = None

    def as_dict(self) -> dict[str, Any]:
        """The row with the columns of :data:`CLAIMS_COLUMNS`."""
        if self.reading is not None and self.reading_outcome is not None:
            reading = self.reading.text()
            if self.also_holds is not None:
                reading += f" (reproduces {self.also_holds}/{len(CLAIMS)} claims)"
            value, by_reading = self.reading_outcome.value, self.reading_outcome.holds
        else:
            reading, value, by_reading = self.reading_note, "", ""
        return {"claim": self.claim.claim, "metric": self.claim.metric,
                "paper": self.claim.paper, "default_value": self.default.value,
                "reproduced_by_default": _yes(self.default.holds), "reading": reading,
                "reading_value": value, "reproduced_by_reading": _yes(by_reading)}


@dataclass
class ClaimsTable:
    """The claims table and the reading that reproduces the most claims at once.

    ``best`` is that reading and ``best_holds`` the keys of the claims it
    reproduces (None if no reading was run); ``searched`` lists the readings
    searched (empty unless searched).
    """

    rows: list[ClaimRow]
    best: Reading | None = None
    best_holds: tuple[str, ...] = ()
    searched: list[dict[str, Any]] = dataclasses.field(default_factory=list)


def _yes(holds: bool | None | str) -> str:
    if isinstance(holds, str):
        return holds
    return "n/a" if holds is None else ("yes" if holds else "no")


def _all_outcomes(metrics: Mapping[str, RunMetrics], context: Context,
                  claims: Iterable[Claim] = CLAIMS) -> dict[str, Outcome]:
    return {c.key: c.outcome(metrics, context) for c in claims}


def _known_metrics(scenario, results: Iterable[RunResult]) -> dict[str, RunMetrics]:
    """Metrics of the runs already made of the scenario's own controllers, by role."""
    known: dict[str, RunMetrics] = {}
    for r in results:
        role = role_of(r.settings)
        if role is not None and role not in known and any(
                r.settings == s for s in scenario.controllers):
            known[role] = run_metrics(r)
    return known


def _default_of(scenario, kind: str, name: str) -> Any:
    """Setting ``name`` of the scenario's first controller of ``kind`` (or its default)."""
    for s in scenario.controllers:
        if s.kind == kind:
            return s.get(name)
    return SETTINGS_BY_NAME[name].default


def _rows_failing(default, rows: list[ClaimRow]):
    """Append a row per claim (its outcome with the scenario's settings) to ``rows``; yield
    ``(claim, row)`` for those the scenario does not reproduce (a reading is wanted)."""
    for claim in CLAIMS:
        row = ClaimRow(claim, default[claim.key])
        rows.append(row)
        if row.default.holds is False:
            yield claim, row


def evaluate_claims(scenario: Scenario, results: Iterable[RunResult] = (), plant: str = "fmu",
                    fmu: str | os.PathLike | None = None,
                    readings: Mapping[str, Reading | None] | None = None,
                    best: Reading | None = None) -> ClaimsTable:
    """The claims table: each claim under the scenario's settings and under a reading.

    Parameters
    ----------
    scenario : Scenario
        The paper's scenario (controllers take roles by kind and t_p_max).
    results : iterable of RunResult
        Runs of the scenario's controllers already made (reused as the default).
    plant : str
        ``"fmu"`` (FrictionPlant.fmu at ``fmu``) or ``"physics"`` (in-process).
    fmu : path, optional
        The plant FMU (``plant = "fmu"``).
    readings : mapping, optional
        For each claim key the reading to show where the default does not
        reproduce it, None for "none found" (default :data:`KNOWN_READINGS`).
    best : Reading, optional
        The reading known to reproduce the most claims at once (default
        :data:`KNOWN_BEST` when ``readings`` is not given); run and evaluated too.
    """
    if readings is None:
        readings, best = KNOWN_READINGS, KNOWN_BEST if best is None else best
    runs = _Runs(scenario, plant, fmu, _known_metrics(scenario, results))
    context = claim_context(scenario)
    try:
        default = _all_outcomes(runs.metrics(Reading()), context)
        rows: list[ClaimRow] = []
        for claim, row in _rows_failing(default, rows):
            reading = readings.get(claim.key)
            if reading is not None:
                outcomes = _all_outcomes(runs.metrics(reading), context)
                row.reading, row.reading_outcome = reading, outcomes[claim.key]
                row.also_holds = sum(1 for o in outcomes.values() if o.holds)
            elif claim.key in readings:
                row.reading_note = ("none found by papwc reproduce --readings; searched: "
                                    + search_range_text())
            else:
                row.reading_note = "not searched yet (papwc reproduce --readings)"
        table = ClaimsTable(rows)
        if best is not None:
            outcomes = _all_outcomes(runs.metrics(best), context)
            table.best = best
            table.best_holds = tuple(k for k, o in outcomes.items() if o.holds)
        return table
    finally:
        runs.close()


def grid_readings(scenario: Scenario, kind: str,
                  axes: Sequence[tuple[str, Sequence[Any]]]) -> list[Reading]:
    """Every combination of the values of ``axes`` as a reading of ``kind``.

    Settings equal to the scenario's are left out of each reading, so that the
    scenario's own values give the empty reading (listed first).
    """
    import itertools

    defaults = {kind: {name: _default_of(scenario, kind, name) for name, _ in axes}}
    names = [n for n, _ in axes]
    out = [Reading()]
    for values in itertools.product(*(v for _, v in axes)):
        out.append(Reading(**{kind: tuple(zip(names, values, strict=True))})
                   .relative_to(defaults))
    return list(dict.fromkeys(out))


def search_readings(scenario: Scenario, results: Iterable[RunResult] = (), plant: str = "fmu",
                    fmu: str | os.PathLike | None = None, workers: int = 1,
                    grid: Mapping[str, Sequence[tuple[str, Sequence[Any]]]] | None = None,
                    ) -> ClaimsTable:
    """Search the readings of ``grid`` (default :data:`SEARCH_GRID`) for each claim.

    Every combination of the values of one kind is a reading of that kind; a
    reading of the whole scenario combines one of each kind. For each claim the
    default does not reproduce, the reading chosen is, among those that
    reproduce it, the one that loses the fewest claims the default reproduces,
    then changes the fewest settings, then reproduces the most claims, then
    moves K_c least (then the first in the grid's order).

    Returns
    -------
    ClaimsTable
        The rows, the reading (one of each kind) that reproduces the most
        claims at once (then changes the fewest settings), and ``searched``:
        one row per reading of one kind (the other kind as in the scenario)
        with ``kind``, ``reading``, ``claims`` (how many it reproduces) and
        ``reproduced`` (their keys).
    """
    grid = SEARCH_GRID if grid is None else grid
    runs = _Runs(scenario, plant, fmu, _known_metrics(scenario, results))
    context = claim_context(scenario)
    kinds = ("pwc", "papwc")
    empty = Reading()
    singles = {kind: grid_readings(scenario, kind, grid[kind]) if kind in grid else [empty]
               for kind in kinds}
    try:
        tasks = [t for kind in kinds for r in singles[kind]
                 for role, t in runs.tasks(r).items() if role.startswith(kind + "_")]
        print(f"searching {len(singles['pwc']) + len(singles['papwc']) - 2} readings "
              f"({len(set(tasks) - set(runs.cache))} runs, {workers} worker(s)) ...",
              flush=True)
        runs.run(tasks, workers)
        base = runs.metrics(empty)
        default = _all_outcomes(base, context)
        by_default = {k for k, o in default.items() if o.holds}

        # Metrics and the outcomes of the claims of one kind, per reading of that kind.
        metrics = {kind: {r: {role: m for role, m in runs.metrics(r).items()
                              if role.startswith(kind + "_")} for r in singles[kind]}
                   for kind in kinds}
        single = {kind: [c for c in CLAIMS if c.kinds == {kind}] for kind in kinds}
        mixed = [c for c in CLAIMS if len(c.kinds) > 1]
        outcomes = {kind: {r: _all_outcomes({**base, **metrics[kind][r]}, context,
                                            single[kind]) for r in singles[kind]}
                    for kind in kinds}

        def all_outcomes(pwc: Reading, papwc: Reading) -> dict[str, Outcome]:
            both = {**base, **metrics["pwc"][pwc], **metrics["papwc"][papwc]}
            return {**outcomes["pwc"][pwc], **outcomes["papwc"][papwc],
                    **_all_outcomes(both, context, mixed)}

        searched = []
        for kind in kinds:
            for r in singles[kind][1:]:
                out = all_outcomes(r, empty) if kind == "pwc" else all_outcomes(empty, r)
                keys = [k for k, o in out.items() if o.holds]
                searched.append({"kind": kind, "reading": r.text(), "claims": len(keys),
                                 "reproduced": " ".join(keys)})

        def k_c_shift(r: Reading, kind: str) -> float:
            given = r.overrides(kind)
            return abs(float(given.get("K_c", 0.0)) - float(_default_of(scenario, kind, "K_c"))
                       ) if "K_c" in given else 0.0

        rows: list[ClaimRow] = []
        for claim, row in _rows_failing(default, rows):
            best = None
            for pwc in singles["pwc"] if "pwc" in claim.kinds else [empty]:
                for papwc in singles["papwc"] if "papwc" in claim.kinds else [empty]:
                    if claim.kinds == {"pwc"}:
                        holds = outcomes["pwc"][pwc][claim.key].holds
                    elif claim.kinds == {"papwc"}:
                        holds = outcomes["papwc"][papwc][claim.key].holds
                    else:
                        both = {**base, **metrics["pwc"][pwc], **metrics["papwc"][papwc]}
                        holds = claim.outcome(both, context).holds
                    if not holds:
                        continue
                    out = all_outcomes(pwc, papwc)
                    lost = sum(1 for k in by_default if not out[k].holds)
                    key = (lost, pwc.changes + papwc.changes,
                           -sum(1 for o in out.values() if o.holds),
                           round(k_c_shift(pwc, "pwc") + k_c_shift(papwc, "papwc"), 9))
                    if best is None or key < best[0]:
                        best = (key, Reading(pwc.pwc, papwc.papwc), out)
            if best is None:
                row.reading_note = "none found; searched: " + search_range_text(grid)
            else:
                row.reading, out = best[1], best[2]
                row.reading_outcome = out[claim.key]
                row.also_holds = sum(1 for o in out.values() if o.holds)
        table = ClaimsTable(rows, searched=searched)
        top = None
        for pwc in singles["pwc"]:
            for papwc in singles["papwc"]:
                out = all_outcomes(pwc, papwc)
                held = tuple(k for k, o in out.items() if o.holds)
                key = (-len(held), pwc.changes + papwc.changes)
                if top is None or key < top[0]:
                    top = (key, Reading(pwc.pwc, papwc.papwc), held)
        table.best, table.best_holds = top[1], top[2]
        return table
    finally:
        runs.close()


def claims_markdown(table: ClaimsTable, searched: bool = False) -> str:
    """The claims table as a Markdown section of ``report.md``."""
    rows = table.rows
    n_default = sum(1 for r in rows if r.default.holds)
    n_any = sum(1 for r in rows if r.default.holds or (r.reading_outcome is not None
                                                        and r.reading_outcome.holds))
    lines = [
        "## The paper's simulation claims (Section 4)",
        "",
        f"Reproduced by the scenario's settings: {n_default} of {len(rows)}; each by the "
        f"scenario's settings or by a reading of its own: {n_any} of {len(rows)}. A reading "
        "replaces settings the paper leaves open for every controller of a kind; "
        + ("it was found by the search of this run (readings.csv lists every reading "
           "searched)." if searched else
           "it is the one `papwc reproduce --readings` found, run again here."),
        "",
    ]
    if table.best is not None:
        lines += [
            f"The reading that reproduces the most claims at once"
            f"{' in this search' if searched else ' in the search'}: {table.best.text()}, "
            f"{len(table.best_holds)} of {len(rows)} ({', '.join(table.best_holds)}).", ""]
    lines += [
        "| " + " | ".join(CLAIMS_COLUMNS) + " |",
        "|" + "---|" * len(CLAIMS_COLUMNS),
    ]
    for row in rows:
        d = row.as_dict()
        lines.append("| " + " | ".join(str(d[c]).replace("|", "\\|") for c in CLAIMS_COLUMNS)
                     + " |")
    return "\n".join(lines) + "\n"


def write_claims(out: Path, scenario: Scenario, results: Sequence[RunResult],
                 fmu: str | os.PathLike, search: bool = False,
                 workers: int | None = None) -> str:
    """Evaluate the claims on the plant FMU, write ``claims.csv`` into ``out``.

    With ``search``, the readings of :data:`SEARCH_GRID` are searched in
    ``workers`` processes (default: the cores available) and ``readings.csv``
    lists every reading searched. Returns the claims section of ``report.md``.
    """
    from papwc.output_files import write_rows

    table = None
    if search:
        from concurrent.futures.process import BrokenProcessPool

        from papwc.battery.engines import default_workers

        try:
            table = search_readings(scenario, results, "fmu", fmu, workers or default_workers())
        except BrokenProcessPool:
            print("error: a worker process of the readings search died; the claims table "
                  "shows the known readings instead")
            search = False
        else:
            write_rows(out / "readings.csv", table.searched,
                       ["kind", "reading", "claims", "reproduced"])
    if table is None:
        table = evaluate_claims(scenario, results, "fmu", fmu)
    write_rows(out / "claims.csv", [r.as_dict() for r in table.rows], CLAIMS_COLUMNS)
    return claims_markdown(table, searched=search)
