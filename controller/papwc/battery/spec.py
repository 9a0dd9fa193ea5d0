"""The controller spec a battery is judged by: its targets (data, here only), figures, verdicts.

The requirements are those of the controller spec (issue 43, docs/_incoming/43-the-bound.md);
each is one or more :class:`Target` in :data:`REQUIREMENTS`: a figure of
``spec.csv``, as a count or as a share of another, held to a bound, for the controller kinds
and the cases it judges. :func:`spec_rows` counts the figures per battery, case and
controller and gives each requirement its verdict where a target of it applies:
``met``, ``MISSED``, or empty (no target of it applies there). Hard requirements judge
every case; statistical ones the rigid cases (no flexible drive, ``plant.m_d = 0``).

- last iteration of each run: within 1 um, within one count (of the runs with a count),
  within 1e-7 m (of the runs on an ideal encoder), within 20 um, the settle time (median
  and p95, ``inf`` for a run that did not end ``settled``), false ``settled``,
  ``time_ended``;
- every iteration (maneuver): those that ended farther than they started, or called
  ``settled`` outside the success tolerance;
- every pulse that moved (``d != 0``), against its bound ``bound_m``
  (:mod:`papwc.results.pulses`, classes of :func:`papwc.results.pulses.pulse_class`):
  beyond it at abs(e) >= 50 um, planned pulses beyond it at abs(e) >= 1 um, the share
  beyond it and the count beyond three times it at 1 <= abs(e) < 50 um, the share beyond
  it below 1 um and the count that moved more than 20 um there.

:func:`compare_rows` sets two batteries' spec.csv side by side (``papwc spec``): the
figures on the files a controller was tuned on and on the same files with other seeds.
"""

from __future__ import annotations

import math
import os
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from papwc.battery.plan import RunSpec, get_field
from papwc.battery.schema import Battery
from papwc.errors import BatteryError
from papwc.results.pulses import NEAR_M, pulse_class

__all__ = ["COMPANION_SUFFIXES", "COMPARED", "COMPARE_COLUMNS", "R7_SHARE_OF_T",
           "REQUIREMENTS", "SPEC_COLUMNS", "Target", "beside_markdown", "companion_base",
           "compare_markdown", "compare_rows", "hard_pulses", "read_spec", "spec_markdown",
           "spec_rows", "verdicts"]

#: The error band of a success, m (within 1 um), and the near-target band of the spec.
WITHIN_1UM = 1e-6
#: The success band of the ideal encoder, m.
WITHIN_IDEAL = 1e-7
#: PAPWC's success band, m.
WITHIN_20UM = 2e-5
#: Below 1 um, no pulse may move more than this, m (R5).
NEAR_MOVE_MAX = 2e-5
#: At 1 <= abs(e) < 50 um no pulse may exceed this multiple of its bound (R4s).
MID_RATIO_MAX = 3.0
#: A pulse whose ratio exceeds 1 by more than this (rounding) is beyond its bound.
RATIO_SLACK = 1e-9
#: Maneuvers at least this long are the 10 s batteries of R2; shorter ones R1's, s.
LONG_MANEUVER_S = 10.0
#: R7: every kind's worst update takes at most this share of its sample period T.
R7_SHARE_OF_T = 0.5


@dataclass(frozen=True)
class Target:
    """One bound of a requirement on one figure of spec.csv.

    Attributes
    ----------
    requirement : str
        Its id (``"R1"``, ...).
    figure : str
        The spec.csv column it bounds.
    of : str
        The column it is a share of ("" for the count itself); no runs or pulses there: the
        target does not apply.
    at_least, at_most : float
        The bound (NaN: none).
    kinds : tuple of str
        The controller kinds it judges (empty: every kind).
    hard : bool
        Hard (every case) or statistical (the rigid cases).
    maneuvers : str
        ``"short"`` (maneuvers under :data:`LONG_MANEUVER_S`), ``"long"`` or ``"any"``.
    """

    requirement: str
    figure: str
    of: str = ""
    at_least: float = math.nan
    at_most: float = math.nan
    kinds: tuple[str, ...] = ()
    hard: bool = False
    maneuvers: str = "any"

    def applies(self, kind: str, rigid: bool, duration: float) -> bool:
        """Whether it judges a controller of ``kind`` on a case (rigid or not) of maneuvers
        ``duration`` (s) long."""
        if self.kinds and kind not in self.kinds:
            return False
        if not (self.hard or rigid):
            return False
        long = duration >= LONG_MANEUVER_S
        return {"any": True, "short": not long, "long": long}[self.maneuvers]

    def value(self, row: dict) -> float:
        """The figure it bounds in a spec row (a share with ``of``; NaN: nothing to count)."""
        if not self.of:
            return float(row[self.figure])
        n = row[self.of]
        return row[self.figure] / n if n else math.nan

    def met(self, value: float) -> bool:
        """Whether ``value`` meets it."""
        return not (value < self.at_least or value > self.at_most)

    def text(self) -> str:
        """``figure/of >= 0.85`` and the like."""
        what = f"{self.figure}/{self.of}" if self.of else self.figure
        op, bound = (">=", self.at_least) if self.at_least == self.at_least else (
            "<=", self.at_most)
        return f"{what} {op} {bound:g}"


_EXACT = ("exact",)
_HYBRID = ("hybrid",)
#: The spec's requirements, in order (issue 43's table; R7 is papwc bench's, F2 and A are
#: not judged here), then issue 46's hybrid (H: within 1 um and one count in 2 s, no ramp
#: beyond its bound at abs(e) >= 1 um, no hunting after it settled).
REQUIREMENTS: tuple[Target, ...] = (
    Target("R1", "within_1um", "runs", at_least=0.85, kinds=_EXACT, maneuvers="short"),
    Target("R1", "within_count", "counted_runs", at_least=0.50, kinds=_EXACT,
           maneuvers="short"),
    Target("R2", "within_1um", "runs", at_least=0.95, kinds=_EXACT, maneuvers="long"),
    Target("R2", "within_count", "counted_runs", at_least=0.80, kinds=_EXACT,
           maneuvers="long"),
    Target("R2", "within_1e7", "ideal_runs", at_least=0.95, kinds=_EXACT, maneuvers="long"),
    Target("R3", "farther", at_most=0.0, hard=True),
    Target("R3", "false_settled_any", at_most=0.0, hard=True),
    Target("R4h", "far_beyond", at_most=0.0, hard=True),
    Target("R4h", "planned_beyond", at_most=0.0, hard=True),
    Target("R4s", "mid_beyond", "mid_pulses", at_most=0.01),
    Target("R4s", "mid_beyond_3x", at_most=0.0),
    Target("R5", "runaway_near", "pulses_near", at_most=0.05),
    Target("R5", "near_over_20um", at_most=0.0, hard=True),
    Target("R6", "settle_median_s", at_most=1.0, kinds=_EXACT),
    Target("R6", "settle_p95_s", at_most=2.0, kinds=_EXACT),
    Target("P", "within_20um", "runs", at_least=0.95, kinds=("papwc",)),
    # issue 46's 1 kHz pulse hybrid
    Target("H", "within_1um", "runs", at_least=0.99, kinds=_HYBRID, maneuvers="short"),
    Target("H", "within_count", "counted_runs", at_least=0.90, kinds=_HYBRID,
           maneuvers="short"),
    Target("H", "runaway_far", at_most=0.0, kinds=_HYBRID, hard=True),
    Target("H", "hunting", at_most=0.0, kinds=_HYBRID, hard=True),
)
#: The requirement ids, in order (spec.csv has a verdict column for each).
REQUIREMENT_IDS: tuple[str, ...] = tuple(dict.fromkeys(t.requirement for t in REQUIREMENTS))

#: Columns of spec.csv (see :func:`spec_rows`).
SPEC_COLUMNS = ("battery", "case", "controller", "kind", "seed_offset", "rigid", "duration_s",
                "runs", "errors", "within_1um", "counted_runs", "within_count", "ideal_runs",
                "within_1e7", "within_20um", "settle_median_s", "settle_p95_s",
                "pulses_far", "runaway_far", "pulses_near", "runaway_near",
                "largest_runaway_m", "far_pulses", "far_beyond", "planned_pulses",
                "planned_beyond", "mid_pulses", "mid_beyond", "mid_beyond_3x",
                "near_over_20um", "maneuvers", "farther", "false_settled",
                "false_settled_any", "time_ended", "settled_late", "hunting",
                *REQUIREMENT_IDS)


def _beyond(pulse: dict, factor: float = 1.0) -> bool:
    return float(pulse["ratio"]) > factor * (1.0 + RATIO_SLACK)


def hard_pulses(pulses: Sequence[dict]) -> list[dict]:
    """The pulses (rows of :meth:`papwc.results.pulses.PulseBound.rows`) a hard requirement
    forbids: beyond their bound at abs(e) >= 50 um or planned at abs(e) >= 1 um (R4h), or
    moving more than 20 um at abs(e) < 1 um (R5)."""
    out = []
    for p in pulses:
        which = pulse_class(float(p["e_m"]), int(p["samples"]), float(p["amplitude_N"]),
                            float(p["u_break_N"]))
        if (which in ("far", "planned") and _beyond(p)) or (
                which == "near" and abs(float(p["d_m"])) > NEAR_MOVE_MAX):
            out.append(p)
    return out


def _pulse_figures(pulses: list[dict]) -> dict:
    """The figures of the pulses that moved (see the module)."""
    moving = [p for p in pulses if float(p["d_m"]) != 0.0]
    classes = {"far": [], "planned": [], "mid": [], "near": []}
    for p in moving:
        classes[pulse_class(float(p["e_m"]), int(p["samples"]), float(p["amplitude_N"]),
                            float(p["u_break_N"]))].append(p)
    far = [p for p in moving if abs(float(p["e_m"])) >= NEAR_M]
    near = classes["near"]
    mid = classes["planned"] + classes["mid"]
    return {
        "pulses_far": len(far), "runaway_far": sum(1 for p in far if _beyond(p)),
        "pulses_near": len(near), "runaway_near": sum(1 for p in near if _beyond(p)),
        "largest_runaway_m": max((abs(float(p["d_m"])) for p in moving if _beyond(p)),
                                 default=0.0),
        "far_pulses": len(classes["far"]),
        "far_beyond": sum(1 for p in classes["far"] if _beyond(p)),
        "planned_pulses": len(classes["planned"]),
        "planned_beyond": sum(1 for p in classes["planned"] if _beyond(p)),
        "mid_pulses": len(mid), "mid_beyond": sum(1 for p in mid if _beyond(p)),
        "mid_beyond_3x": sum(1 for p in mid if _beyond(p, MID_RATIO_MAX)),
        "near_over_20um": sum(1 for p in near if abs(float(p["d_m"])) > NEAR_MOVE_MAX),
    }


def verdicts(row: dict) -> dict[str, str]:
    """Each requirement's verdict on a spec row: ``met``, ``MISSED`` or "" (no target of it
    applies there)."""
    out = dict.fromkeys(REQUIREMENT_IDS, "")
    for target in REQUIREMENTS:
        if not target.applies(row["kind"], row["rigid"], row["duration_s"]):
            continue
        value = target.value(row)
        if value != value:
            continue
        if not target.met(value):
            out[target.requirement] = "MISSED"
        elif not out[target.requirement]:
            out[target.requirement] = "met"
    return out


def spec_rows(batteries: list[Battery], runs: list[RunSpec], records: dict,
              rows: list[dict]) -> list[dict]:
    """The spec's figures and verdicts per battery, case and controller (keys
    :data:`SPEC_COLUMNS`).

    From the last iteration of each run (``rows``: :func:`papwc.battery.report.result_rows`):
    ``runs``, ``errors`` (status error), ``within_1um`` (runs with status ok and abs(final
    error) <= 1 um), ``counted_runs`` and ``within_count`` (of the runs whose plant has an
    encoder count ``x_resolution`` > 0, those ending within one count), ``ideal_runs`` and
    ``within_1e7`` (of the runs on an ideal encoder, those within 1e-7 m),
    ``within_20um``, ``settle_median_s`` and ``settle_p95_s`` (over the runs with status
    ok, the settle time of a run that ended ``settled``, inf for one that did not),
    ``false_settled`` and ``time_ended``, ``settled_late`` and ``hunting`` (the runs called
    settled in the last 0.5 s, and those in which the table then moved more than one count,
    1e-7 m on an ideal encoder). Over every iteration: ``maneuvers``, ``farther``
    (ended farther from the target than they started) and ``false_settled_any``. Over
    every pulse that moved: ``pulses_far`` and ``runaway_far`` (fired at abs(e) >= 1 um,
    and those of them beyond their bound), ``pulses_near`` and ``runaway_near`` (the same
    below 1 um), ``largest_runaway_m``, and by the classes of
    :func:`papwc.results.pulses.pulse_class`: ``far_pulses``/``far_beyond`` (abs(e) >=
    50 um), ``planned_pulses``/``planned_beyond`` (planned, 1 to 50 um),
    ``mid_pulses``/``mid_beyond``/``mid_beyond_3x`` (every pulse at 1 to 50 um, beyond
    its bound, beyond three times it) and ``near_over_20um``. ``rigid``: no run of the
    case has a flexible drive; ``duration_s``: the longest maneuver; ``seed_offset``: the
    battery's (``papwc battery --seed-offset``). Then one verdict column per requirement
    (:func:`verdicts`).
    """
    import numpy as np

    by_name = {b.name: b for b in batteries}
    by_key = {(s.battery, s.run_id): s for s in runs}
    groups: dict[tuple, dict] = {}
    for r in rows:
        spec = by_key[(r["battery"], r["run_id"])]
        key = (r["battery"], r.get("case", ""), r["controller"])
        g = groups.setdefault(key, {"kind": r["kind"], "last": [], "all": [], "pulses": [],
                                    "rigid": True, "duration": 0.0})
        g["all"].append(r)
        g["rigid"] = g["rigid"] and not float(get_field(spec.data, "plant.m_d")) > 0.0
        g["duration"] = max(g["duration"], float(get_field(spec.data, "maneuver.duration")))
        if r["last_iteration"]:
            q = get_field(spec.data, "plant.x_resolution")
            g["last"].append((r, float(q) if q is not None else 0.0))
    for spec in runs:
        for c in records[(spec.battery, spec.run_id)]["controllers"]:
            key = (spec.battery, spec.case, c["label"])
            if key in groups:
                groups[key]["pulses"] += c.get("pulses", [])
    out = []
    for (battery, case, label), g in groups.items():
        ok = [(r, q) for r, q in g["last"] if r["status"] == "ok"]
        settle = [r["settle_time_s"] if r.get("outcome") == "settled" else math.inf
                  for r, _ in ok]
        done = [r for r in g["all"] if r["status"] == "ok"]
        row = {
            "battery": battery, "case": case, "controller": label, "kind": g["kind"],
            "seed_offset": by_name[battery].seed_offset, "rigid": g["rigid"],
            "duration_s": g["duration"],
            "runs": len(g["last"]), "errors": len(g["last"]) - len(ok),
            "within_1um": sum(1 for r, _ in ok if abs(r["final_error_m"]) <= WITHIN_1UM),
            "counted_runs": sum(1 for _, q in g["last"] if q > 0.0),
            "within_count": sum(1 for r, q in ok if q > 0.0 and abs(r["final_error_m"]) <= q),
            "ideal_runs": sum(1 for _, q in g["last"] if not q > 0.0),
            "within_1e7": sum(1 for r, q in ok if not q > 0.0
                              and abs(r["final_error_m"]) <= WITHIN_IDEAL),
            "within_20um": sum(1 for r, _ in ok if abs(r["final_error_m"]) <= WITHIN_20UM),
            "settle_median_s": float(statistics.median(settle)) if settle else math.nan,
            "settle_p95_s": (float(np.percentile(settle, 95, method="higher")) if settle
                             else math.nan),
            **_pulse_figures(g["pulses"]),
            "maneuvers": len(done),
            "farther": sum(1 for r in done if r.get("ends_farther") is True),
            "false_settled": sum(1 for r, _ in g["last"] if r.get("false_settled")),
            "false_settled_any": sum(1 for r in g["all"] if r.get("false_settled")),
            "time_ended": sum(1 for r, _ in ok if r.get("outcome_reason") == "time_ended"),
            **_hunting(ok),
        }
        row.update(verdicts(row))
        out.append(row)
    return out


def _hunting(ok: list[tuple[dict, float]]) -> dict:
    """``settled_late``: the runs (last iteration, status ok) that the controller called
    settled in the last 0.5 s; ``hunting``: those in which the table then moved more than
    one count (``q``; 1e-7 m on an ideal encoder): ``settled_span_m``
    (:func:`papwc.results.summary.settled_span`)."""
    spans = []
    for r, q in ok:
        value = r.get("settled_span_m", "")
        span = math.nan if value in ("", None) else float(value)
        if span == span:
            spans.append((span, q if q > 0.0 else WITHIN_IDEAL))
    return {"settled_late": len(spans),
            "hunting": sum(1 for span, q in spans if span > q * (1.0 + RATIO_SLACK))}


def _share(n, of) -> str:
    n, of = int(n), int(of)
    return f"{n} of {of} ({n / of:.1%})" if of else "–"


def _fmt(x, spec: str) -> str:
    x = float(x)
    return "–" if math.isnan(x) else format(x, spec)


def _verdict_text(row: dict) -> str:
    return ", ".join(f"{rid} {row[rid]}" for rid in REQUIREMENT_IDS if row.get(rid)) or "–"


def requirements_markdown() -> list[str]:
    """Lines that list the targets (from :data:`REQUIREMENTS`)."""
    lines = []
    for rid in REQUIREMENT_IDS:
        targets = [t for t in REQUIREMENTS if t.requirement == rid]
        kinds = ", ".join(dict.fromkeys(k for t in targets for k in t.kinds)) or "every kind"
        parts = [t.text() + (" (hard, every case)" if t.hard else "") for t in targets]
        scope = {t.maneuvers for t in targets} - {"any"}
        when = (f"; maneuvers {'>=' if scope == {'long'} else '<'} {LONG_MANEUVER_S:g} s"
                if len(scope) == 1 else "")
        lines.append(f"- **{rid}** ({kinds}{when}): " + "; ".join(parts))
    return lines


def spec_markdown(battery: Battery, spec: list[dict]) -> list[str]:
    """Lines of summary.md's spec tables of one battery (from :func:`spec_rows`)."""
    mine = [r for r in spec if r["battery"] == battery.name]
    first = "| case " if battery.cases else ""
    rule = "|---" if battery.cases else ""

    def lead(r: dict) -> str:
        return (f"| {r['case']} " if battery.cases else "") + f"| {r['controller']} "

    offset = f" (seed offset {battery.seed_offset})" if battery.seed_offset else ""
    lines = [f"### Spec{offset}", "",
             "Verdicts where a target applies (`papwc.battery.spec.REQUIREMENTS`; hard ones "
             "on every case, statistical ones on the rigid cases):", "",
             *requirements_markdown(), "",
             "Last iteration of each run: within 1 um, within one encoder count (of the runs "
             "with a count), within 1e-7 m (of the runs on an ideal encoder), within 20 um, "
             "the settle time (median and p95 over the runs; inf: more than that share did "
             "not end `settled`), `time_ended`, the runs called settled in the last 0.5 s "
             "in which the table then moved more than one count (hunting). Every iteration: "
             "maneuvers that ended farther than they started, false `settled`.", "",
             first + "| controller | runs | within 1 um | within one count | within 1e-7 m "
             "(ideal) | within 20 um | settle median (s) | settle p95 (s) | farther | false "
             "settled | time_ended | hunting after settled | verdicts |",
             rule + "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in mine:
        lines.append(
            lead(r) + f"| {r['runs']} | {_share(r['within_1um'], r['runs'])} | "
            f"{_share(r['within_count'], r['counted_runs'])} | "
            f"{_share(r['within_1e7'], r['ideal_runs'])} | "
            f"{_share(r['within_20um'], r['runs'])} | "
            f"{_fmt(r['settle_median_s'], '.3f')} | {_fmt(r['settle_p95_s'], '.3f')} | "
            f"{r['farther']} of {r['maneuvers']} | {r['false_settled_any']} | "
            f"{r['time_ended']} | {_share(r['hunting'], r['settled_late'])} | "
            f"{_verdict_text(r)} |")
    lines += ["", "Pulses that moved, every iteration, against their bound `bound_m = "
              "max(1.5*abs(e) + one count, quantum_m)` (`papwc.results.pulses`; every pulse "
              "is in `pulses.csv`): beyond it at abs(e) >= 50 um (any width), planned pulses "
              "(two samples or more, or one above `u_break_N`) beyond it at 1 to 50 um, all "
              "pulses at 1 to 50 um beyond it and beyond three times it, pulses below 1 um "
              "beyond it and moving more than 20 um, the largest move of a pulse beyond it.",
              "",
              first + "| controller | beyond at >= 50 um | planned beyond at 1-50 um | "
              "beyond at 1-50 um | beyond 3x at 1-50 um | beyond below 1 um | moving > 20 um "
              "below 1 um | largest move beyond (m) |",
              rule + "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in mine:
        lines.append(
            lead(r) + f"| {_share(r['far_beyond'], r['far_pulses'])} | "
            f"{_share(r['planned_beyond'], r['planned_pulses'])} | "
            f"{_share(r['mid_beyond'], r['mid_pulses'])} | {r['mid_beyond_3x']} | "
            f"{_share(r['runaway_near'], r['pulses_near'])} | {r['near_over_20um']} | "
            f"{_fmt(r['largest_runaway_m'], '.3g')} |")
    return lines + [""]


#: The figures :func:`compare_rows` sets side by side: (label, figure, of) as in a Target.
COMPARED: tuple[tuple[str, str, str], ...] = (
    ("within 1 um", "within_1um", "runs"),
    ("within one count", "within_count", "counted_runs"),
    ("within 1e-7 m (ideal)", "within_1e7", "ideal_runs"),
    ("within 20 um", "within_20um", "runs"),
    ("settle median (s)", "settle_median_s", ""),
    ("settle p95 (s)", "settle_p95_s", ""),
    ("farther", "farther", ""),
    ("false settled", "false_settled_any", ""),
    ("beyond at >= 50 um", "far_beyond", ""),
    ("planned beyond at 1-50 um", "planned_beyond", ""),
    ("beyond at 1-50 um", "mid_beyond", "mid_pulses"),
    ("beyond 3x at 1-50 um", "mid_beyond_3x", ""),
    ("beyond below 1 um", "runaway_near", "pulses_near"),
    ("moving > 20 um below 1 um", "near_over_20um", ""),
    ("beyond at >= 1 um", "runaway_far", "pulses_far"),
    ("hunting after settled", "hunting", "settled_late"),
)


def compare_rows(tuned: Sequence[dict], other: Sequence[dict]) -> list[dict]:
    """Two spec.csv (as read by :func:`read_spec`) side by side: per battery, case and
    controller that either has, one row per figure of :data:`COMPARED` and one of verdicts.

    A battery of ``other`` is matched to one of ``tuned`` by its name, less the suffix a
    twin file adds (:data:`TWIN_SUFFIXES`). Keys: battery, case, controller, figure,
    tuned, other (as shown: a share, a count or seconds; "–" where a side has none).
    """
    def key(r: dict) -> tuple[str, str, str]:
        return (_base_name(r["battery"]), r.get("case", ""), r["controller"])

    mine = {key(r): r for r in tuned}
    theirs = {key(r): r for r in other}
    out = []
    for k in dict.fromkeys([*mine, *theirs]):
        a, b = mine.get(k), theirs.get(k)
        for label, figure, of in COMPARED:
            out.append({"battery": k[0], "case": k[1], "controller": k[2], "figure": label,
                        "tuned": _shown(a, figure, of), "other": _shown(b, figure, of)})
        out.append({"battery": k[0], "case": k[1], "controller": k[2], "figure": "verdicts",
                    "tuned": _verdict_text(a) if a else "–",
                    "other": _verdict_text(b) if b else "–"})
    return out


#: Figures spec.csv gained after its first form (issue 46): a spec.csv without them is read,
#: its cells shown "–".
_LATER = frozenset(("settled_late", "hunting"))

#: Columns of :func:`compare_rows`.
COMPARE_COLUMNS = ("battery", "case", "controller", "figure", "tuned", "other")


def read_spec(path: str | os.PathLike) -> list[dict]:
    """The rows of a battery's spec.csv (``path``: the file or the battery's folder).

    Raises
    ------
    BatteryError
        If it cannot be read or lacks a column :func:`compare_rows` reads (one line naming
        the file, what is wrong and what is expected).
    """
    import csv

    path = Path(path)
    if path.is_dir():
        path = path / "spec.csv"
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            rows = list(reader)
            columns = reader.fieldnames or []
    except FileNotFoundError:
        raise BatteryError(f"{path}: no such file; give a battery's output folder (it holds "
                           "spec.csv) or its spec.csv") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise BatteryError(f"{path}: cannot be read as a spec.csv: {exc}") from None
    needed = ["battery", "case", "controller", *dict.fromkeys(
        c for _, figure, of in COMPARED for c in (figure, of) if c and c not in _LATER)]
    missing = [c for c in needed if c not in columns]
    if missing:
        raise BatteryError(f"{path}: not a spec.csv of this papwc: column(s) "
                           f"{', '.join(missing)} missing (written by `papwc battery`)")
    return rows


#: Suffixes of twin battery names that measure the same files on other seeds.
TWIN_SUFFIXES = ("_fresh", "_oos")


def _base_name(name: str) -> str:
    for suffix in TWIN_SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def _shown(row: dict | None, figure: str, of: str) -> str:
    """A figure as :func:`compare_rows` shows it: ``n/N (p%)``, seconds, a count, or "–"."""
    if row is None or row.get(figure, "") in ("", None):
        return "–"
    if of:
        n, total = int(row[figure]), int(row[of])
        return f"{n}/{total} ({n / total:.0%})" if total else "–"
    value = float(row[figure])
    return _fmt(value, ".3f") if figure.endswith("_s") else f"{value:g}"


#: Suffixes of companion batteries: the same tables (plants, cases, grid, draws) with other
#: controllers or another sample period (``realism_mc_1khz.toml``, ``realism_mc_hybrid.toml``
#: beside ``realism_mc.toml``); the spec shows their rows beside the base battery's.
COMPANION_SUFFIXES = ("_1khz", "_hybrid")


def companion_base(name: str) -> str:
    """The battery whose tables a companion battery runs (``realism_mc`` for
    ``realism_mc_1khz``), else ``name``."""
    for suffix in COMPANION_SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def _beside(keys: Sequence[tuple[str, str, str]]) -> dict[str, list[tuple[str, str, str]]]:
    """(battery, case, controller) keys grouped by their base battery, each group ordered by
    case (in the order the cases first appear) and then as given."""
    groups: dict[str, list[tuple[str, str, str]]] = {}
    for key in keys:
        groups.setdefault(companion_base(key[0]), []).append(key)
    for base, group in groups.items():
        cases = list(dict.fromkeys(case for _, case, _ in group))
        groups[base] = sorted(group, key=lambda k: cases.index(k[1]))
    return groups


def beside_markdown(spec: list[dict]) -> list[str]:
    """Lines of summary.md's table of every controller side by side: per base battery with a
    companion (:data:`COMPANION_SUFFIXES`), each case's controllers of the base battery and of
    its companions, one row each (empty if no companion ran)."""
    by_key = {(r["battery"], r["case"], r["controller"]): r for r in spec}
    groups = {base: keys for base, keys in _beside(list(by_key)).items()
              if len({k[0] for k in keys}) > 1}
    if not groups:
        return []
    lines = ["## Every controller side by side", "",
             "The controllers of each battery and of its companions (the same tables with other "
             "controllers or sample periods: "
             + ", ".join(f"`*{s}`" for s in COMPANION_SUFFIXES)
             + "), case by case. Figures of the spec tables above.", ""]
    for base, keys in groups.items():
        lines += [f"### {base}", "",
                  "| case | controller | battery | within 1 um | within one count | within 20 um "
                  "| farther | false settled | beyond at >= 1 um | hunting after settled | "
                  "verdicts |",
                  "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|"]
        for key in keys:
            r = by_key[key]
            lines.append(
                f"| {r['case']} | {r['controller']} | {r['battery']} | "
                f"{_share(r['within_1um'], r['runs'])} | "
                f"{_share(r['within_count'], r['counted_runs'])} | "
                f"{_share(r['within_20um'], r['runs'])} | {r['farther']} of {r['maneuvers']} | "
                f"{r['false_settled_any']} | {_share(r['runaway_far'], r['pulses_far'])} | "
                f"{_share(r['hunting'], r['settled_late'])} | {_verdict_text(r)} |")
        lines.append("")
    return lines


def compare_markdown(rows: list[dict], tuned: str, other: str) -> str:
    """The side-by-side table of :func:`compare_rows` as Markdown: per battery (a companion's
    rows beside its base battery's, :data:`COMPANION_SUFFIXES`) one row per case and
    controller, each figure ``tuned → out of sample``."""
    labels = [label for label, _, _ in COMPARED] + ["verdicts"]
    lines = ["# Spec: tuned and out of sample", "",
             f"Tuned: `{tuned}`. Out of sample: `{other}`. Each cell: tuned → out of sample. "
             "A figure that does not carry over to the other seeds is not met.", ""]
    cells: dict[tuple[str, str, str], dict[str, str]] = {}
    for r in rows:
        cells.setdefault((r["battery"], r["case"], r["controller"]), {})[r["figure"]] = (
            f"{r['tuned']} → {r['other']}")
    for base, keys in _beside(list(cells)).items():
        several = len({k[0] for k in keys}) > 1
        lines += [f"## {base}", "", "| case | controller | " + ("battery | " if several else "")
                  + " | ".join(labels) + " |",
                  "|---|---|" + ("---|" if several else "") + "---:|" * (len(labels) - 1)
                  + "---|"]
        for key in keys:
            figures = cells[key]
            lines.append(f"| {key[1]} | {key[2]} | " + (f"{key[0]} | " if several else "")
                         + " | ".join(figures.get(label, "–") for label in labels) + " |")
        lines.append("")
    return "\n".join(lines)
