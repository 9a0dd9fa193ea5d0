"""The battery's spec figures (spec.csv, summary.md) and pulses.csv on crafted records: every
count is given a value of its own, so that a count that is wrong shows."""

from __future__ import annotations

import csv
import math
import tomllib

import pytest
from harness import TABLE_1_TOML

from papwc.battery import parse_battery, plan_runs, result_rows
from papwc.battery.journal import record_problem
from papwc.battery.report import pulse_rows, write_outputs
from papwc.battery.spec import (
    REQUIREMENT_IDS,
    REQUIREMENTS,
    SPEC_COLUMNS,
    beside_markdown,
    companion_base,
    compare_markdown,
    compare_rows,
    spec_rows,
    verdicts,
)
from papwc.results.pulses import ROW_COLUMNS

BATTERY = 'name = "spec"\n' + TABLE_1_TOML + """\
x_resolution = 1e-7
[maneuver]
x_ref = 0.01
duration = 2.0
iterations = 2
[[controller]]
kind = "exact"
label = "exact"
tolerance = 1e-7
[cases]
counted = {}
ideal = { "plant.x_resolution" = 0.0 }
[sweep]
"maneuver.x_ref" = [1e-2, 1e-3, 5e-5, 2e-5]
"""


def _iteration(k: int, e: float, outcome: str = "settled", reason: str = "within_tolerance",
               settle: float = math.nan, farther: bool = False, span: float = math.nan) -> dict:
    return {"iteration": k, "final_error_m": e, "pulses": 3, "settle_time_s": settle,
            "limit_cycle": False, "cycle_p2p_m": 0.0, "b_hat": 1.0, "f_c_hat": 90.0,
            "outcome": outcome, "outcome_reason": reason, "pulse_ratio": 0.5,
            "ends_farther": farther, "settled_span_m": span, "error": ""}


def _pulse(k: int, e: float, d: float, ratio: float, samples: int = 1,
           amplitude: float = 140.0) -> dict:
    return {"iteration": k, "pulse": 1, "t_s": 0.1, "samples": samples,
            "amplitude_N": amplitude, "e_m": e, "d_m": d, "band_top_N": 140.0,
            "u_break_N": 140.0, "quantum_m": 1e-7,
            "bound_m": abs(d) / ratio if ratio else 1.0, "ratio": ratio}


#: Last iterations of the four runs of a case: (final error, outcome, reason, settle time).
LAST = [(5e-8, "settled", "within_tolerance", 0.2, 0.0),
        (9e-8, "settled", "within_tolerance", 0.5, 2e-7),  # moved two counts after: hunting
        (-8e-7, "stopped", "time_ended", math.nan, math.nan),
        (1e-4, "settled", "within_tolerance", 1.0, 5e-8)]
#: Pulses of the first run, one of each kind the spec tells apart (the band top and
#: u_break at 140 N).
PULSES = [
    _pulse(1, 6e-5, 1e-4, 1.2),  # abs(e) >= 50 um, beyond its bound
    _pulse(1, -1e-4, -5e-5, 0.3),  # abs(e) >= 50 um, within
    _pulse(1, 5e-6, 1e-5, 1.3, samples=2),  # planned (2 samples) at 1-50 um, beyond
    _pulse(1, -5e-6, -2e-6, 0.2, amplitude=-150.0),  # planned (above u_break), within
    _pulse(2, 2e-6, 3e-5, 4.0),  # one sample at 1-50 um, beyond three times its bound
    _pulse(2, 2e-6, 4e-6, 1.0 + 1e-10),  # ... beyond only by rounding: within
    _pulse(2, 5e-7, 2.5e-5, 12.0),  # below 1 um, beyond, moving more than 20 um
    _pulse(2, 5e-7, 0.0, 0.0),  # below 1 um, did not move: not counted
    _pulse(2, -2e-7, -1e-7, 0.3),  # below 1 um, within
]


@pytest.fixture
def crafted():
    battery = parse_battery(tomllib.loads(BATTERY), "spec.toml")
    runs = plan_runs([battery])
    records = {}
    for spec in runs:
        i = ["s0", "s1", "s2", "s3"].index(spec.run_id.split("-")[1])
        e, outcome, reason, settle, span = LAST[i]
        its = [_iteration(1, 1e-3, farther=(i == 3)),
               _iteration(2, e, outcome, reason, settle, span=span)]
        ctrl = {"label": "exact", "kind": "exact", "tolerance": 1e-7, "error": "",
                "iterations": its, "pulses": PULSES if i == 0 else []}
        records[(spec.battery, spec.run_id)] = {
            "type": "run", "battery": spec.battery, "run_id": spec.run_id,
            "run_hash": spec.run_hash, "params": spec.data, "status": "ok", "message": "",
            "controllers": [ctrl]}
    # one run of the ideal-encoder case failed
    failed = next(s for s in runs if s.run_id == "ideal-s3")
    records[(failed.battery, failed.run_id)].update(status="error", message="boom",
                                                     controllers=[])
    for record in records.values():
        assert record_problem(record) is None
    return battery, runs, records


def test_spec_counts_each_figure(crafted) -> None:
    battery, runs, records = crafted
    rows = result_rows([battery], runs, records)
    by_case = {r["case"]: r for r in spec_rows([battery], runs, records, rows)}
    counted, ideal = by_case["counted"], by_case["ideal"]
    assert counted == {
        "battery": "spec", "case": "counted", "controller": "exact", "kind": "exact",
        "seed_offset": 0, "rigid": True, "duration_s": 2.0,
        "runs": 4, "errors": 0,
        "within_1um": 3,  # 5e-8, 9e-8 and 8e-7 m
        "counted_runs": 4, "within_count": 2,  # 5e-8 and 9e-8 m
        "ideal_runs": 0, "within_1e7": 0,
        "within_20um": 3,
        "settle_median_s": 0.75,  # of 0.2, 0.5, 1.0 (a false settled) and inf (time ended)
        "settle_p95_s": math.inf,
        "pulses_far": 6, "runaway_far": 3, "pulses_near": 2, "runaway_near": 1,
        "largest_runaway_m": 1e-4,
        "far_pulses": 2, "far_beyond": 1, "planned_pulses": 2, "planned_beyond": 1,
        "mid_pulses": 4, "mid_beyond": 2, "mid_beyond_3x": 1, "near_over_20um": 1,
        "maneuvers": 8, "farther": 1,
        "false_settled": 1,  # settled at 1e-4 m with tolerance 1e-7 m
        "false_settled_any": 5,  # and every first iteration, settled at 1e-3 m
        "time_ended": 1,
        "settled_late": 3, "hunting": 1,  # 2e-7 m after settled, more than a count
        "R1": "MISSED", "R2": "", "R3": "MISSED", "R4h": "MISSED", "R4s": "MISSED",
        "R5": "MISSED", "R6": "MISSED", "P": "", "H": "",
    }
    # the ideal encoder has no count; the failed run counts as a run, not a success
    assert ideal["runs"] == 4 and ideal["errors"] == 1 and ideal["within_1um"] == 3
    assert ideal["counted_runs"] == 0 and ideal["within_count"] == 0
    assert ideal["ideal_runs"] == 4 and ideal["within_1e7"] == 2
    assert ideal["settle_median_s"] == 0.5 and ideal["settle_p95_s"] == math.inf
    assert ideal["maneuvers"] == 6 and ideal["farther"] == 0 and ideal["time_ended"] == 1
    assert ideal["false_settled_any"] == 3
    # on the ideal encoder "a count" is 1e-7 m; the failed run is not counted
    assert ideal["settled_late"] == 2 and ideal["hunting"] == 1
    assert set(counted) == set(SPEC_COLUMNS)


def _row(kind: str = "exact", rigid: bool = True, duration: float = 2.0, **figures) -> dict:
    """A spec row that meets every target, with ``figures`` replaced."""
    row = {"kind": kind, "rigid": rigid, "duration_s": duration, "runs": 20,
           "within_1um": 20, "counted_runs": 20, "within_count": 20, "ideal_runs": 0,
           "within_1e7": 0, "within_20um": 20, "farther": 0, "false_settled_any": 0,
           "far_beyond": 0, "planned_beyond": 0, "mid_pulses": 200, "mid_beyond": 0,
           "mid_beyond_3x": 0, "pulses_near": 100, "runaway_near": 0, "near_over_20um": 0,
           "settle_median_s": 0.5, "settle_p95_s": 1.5, "pulses_far": 300, "runaway_far": 0,
           "settled_late": 20, "hunting": 0}
    row.update(figures)
    return row


@pytest.mark.parametrize(("figures", "requirement", "verdict"), [
    ({}, "R1", "met"),
    ({"within_1um": 17}, "R1", "met"),  # 85 %
    ({"within_1um": 16}, "R1", "MISSED"),
    ({"within_count": 9}, "R1", "MISSED"),  # 45 % < 50 %
    ({"counted_runs": 0, "within_count": 0}, "R1", "met"),  # no count: its 1 um target alone
    ({"duration": 10.0}, "R1", ""),  # a 10 s battery is R2's
    ({"duration": 10.0, "within_1um": 19}, "R2", "met"),  # 95 %
    ({"duration": 10.0, "within_count": 15}, "R2", "MISSED"),  # 75 % < 80 %
    ({"duration": 10.0, "ideal_runs": 20, "within_1e7": 18}, "R2", "MISSED"),
    ({"kind": "papwc"}, "R1", ""),
    ({"farther": 1}, "R3", "MISSED"),
    ({"false_settled_any": 1, "rigid": False}, "R3", "MISSED"),  # hard: every case
    ({"far_beyond": 1}, "R4h", "MISSED"),
    ({"planned_beyond": 1, "kind": "pid"}, "R4h", "MISSED"),
    ({"mid_beyond": 2}, "R4s", "met"),  # 1 %
    ({"mid_beyond": 3}, "R4s", "MISSED"),
    ({"mid_beyond_3x": 1}, "R4s", "MISSED"),
    ({"mid_beyond": 3, "rigid": False}, "R4s", ""),  # statistical: rigid cases only
    ({"mid_pulses": 0}, "R4s", "met"),  # no share without pulses: the 3x count alone
    ({"runaway_near": 5}, "R5", "met"),  # 5 %
    ({"runaway_near": 6}, "R5", "MISSED"),
    ({"near_over_20um": 1, "rigid": False}, "R5", "MISSED"),
    ({"settle_median_s": 1.01}, "R6", "MISSED"),
    ({"settle_p95_s": math.inf}, "R6", "MISSED"),
    ({"kind": "pid", "settle_p95_s": math.inf}, "R6", ""),
    ({"kind": "papwc", "within_20um": 19}, "P", "met"),
    ({"kind": "papwc", "within_20um": 18}, "P", "MISSED"),
    ({"kind": "papwc", "within_20um": 18, "rigid": False}, "P", ""),
    ({"kind": "hybrid"}, "H", "met"),
    ({"kind": "hybrid", "within_1um": 19}, "H", "MISSED"),  # 95 % < 99 %
    ({"kind": "hybrid", "within_count": 17}, "H", "MISSED"),  # 85 % < 90 %
    ({"kind": "hybrid", "within_count": 17, "rigid": False}, "H", "met"),  # statistical
    ({"kind": "hybrid", "runaway_far": 1, "rigid": False}, "H", "MISSED"),  # hard
    ({"kind": "hybrid", "hunting": 1, "rigid": False}, "H", "MISSED"),  # hard
    ({"kind": "pid", "hunting": 1}, "H", ""),  # the hybrid's requirement
])
def test_each_requirement_is_judged_where_its_target_applies(figures, requirement, verdict):
    kind = figures.pop("kind", "exact")
    rigid = figures.pop("rigid", True)
    duration = figures.pop("duration", 2.0)
    assert verdicts(_row(kind, rigid, duration, **figures))[requirement] == verdict


def test_the_targets_are_data_with_one_verdict_column_each() -> None:
    assert REQUIREMENT_IDS == ("R1", "R2", "R3", "R4h", "R4s", "R5", "R6", "P", "H")
    assert set(REQUIREMENT_IDS) <= set(SPEC_COLUMNS)
    for target in REQUIREMENTS:
        assert target.figure in SPEC_COLUMNS and (not target.of or target.of in SPEC_COLUMNS)
        assert (target.at_least == target.at_least) != (target.at_most == target.at_most)


@pytest.mark.slow
def test_pulses_csv_and_spec_csv_are_written_with_the_runs_identification(crafted,
                                                                           tmp_path) -> None:
    battery, runs, records = crafted
    assert len(pulse_rows(runs, records, has_cases=True)) == 2 * len(PULSES)
    write_outputs(tmp_path, [battery], runs, records, "0" * 64)
    with open(tmp_path / "pulses.csv", newline="") as f:
        reader = csv.DictReader(f)
        got = list(reader)
    assert reader.fieldnames == ["battery", "run_id", "run_hash", "case", "controller", "kind",
                                 "iteration", *ROW_COLUMNS]
    assert [r["run_id"] for r in got] == ["counted-s0"] * 9 + ["ideal-s0"] * 9
    assert [float(r["ratio"]) for r in got[:9]] == [p["ratio"] for p in PULSES]
    assert got[0]["run_hash"] == runs[0].run_hash and got[0]["iteration"] == "1"
    with open(tmp_path / "spec.csv", newline="") as f:
        spec = list(csv.DictReader(f))
    assert [(r["case"], r["runaway_far"], r["runaway_near"], r["R4h"]) for r in spec] == [
        ("counted", "3", "1", "MISSED"), ("ideal", "3", "1", "MISSED")]
    text = (tmp_path / "summary.md").read_text()
    assert ("| counted | exact | 4 | 3 of 4 (75.0%) | 2 of 4 (50.0%) | – | 3 of 4 (75.0%) | "
            "0.750 | inf | 1 of 8 | 5 | 1 | 1 of 3 (33.3%) | R1 MISSED, R3 MISSED, R4h MISSED, "
            "R4s MISSED, R5 MISSED, R6 MISSED |") in text
    assert ("| counted | exact | 1 of 2 (50.0%) | 1 of 2 (50.0%) | 2 of 4 (50.0%) | 1 | "
            "1 of 2 (50.0%) | 1 | 0.0001 |") in text
    assert "| ideal | exact | 4 | 3 of 4 (75.0%) | – | 2 of 4 (50.0%) |" in text
    assert "- **R4h** (every kind): far_beyond <= 0 (hard, every case)" in text


def test_a_record_with_malformed_pulses_is_not_used(crafted) -> None:
    _, _, records = crafted
    record = dict(next(iter(records.values())))
    record["controllers"] = [{**record["controllers"][0], "pulses": [{"ratio": "x"}]}]
    assert record_problem(record) == "a controller's pulses are not a list of pulse rows"
    record["controllers"] = [{**record["controllers"][0], "pulses": {}}]
    assert record_problem(record) == "a controller's pulses are not a list of pulse rows"


@pytest.mark.slow
def test_a_seed_offset_is_written_beside_the_figures(crafted, tmp_path) -> None:
    battery, runs, records = crafted
    battery.seed_offset = 7
    write_outputs(tmp_path, [battery], runs, records, "0" * 64)
    for name in ("runs.csv", "spec.csv"):
        with open(tmp_path / name, newline="") as f:
            assert {r["seed_offset"] for r in csv.DictReader(f)} == {"7"}, name
    text = (tmp_path / "summary.md").read_text()
    assert "every seed offset by 7 (--seed-offset)" in text
    assert "### Spec (seed offset 7)" in text


def _spec_row(battery: str, case: str, controller: str, kind: str, **figures) -> dict:
    row = dict.fromkeys(SPEC_COLUMNS, 0)
    row.update(_row(kind=kind), battery=battery, case=case, controller=controller, maneuvers=60,
               settle_median_s=0.5, settle_p95_s=1.5, **figures)
    row.update(verdicts(row))
    return row


def test_companion_batteries_sit_beside_their_base_battery_case_by_case() -> None:
    """realism_mc_1khz and realism_mc_hybrid run realism_mc's tables: summary.md's table of
    every controller and papwc spec's comparison show their rows beside realism_mc's, case by
    case; a battery without a companion gets no such table."""
    assert companion_base("realism_mc_1khz") == "realism_mc"
    assert companion_base("realism_mc_lugre_hybrid") == "realism_mc_lugre"
    assert companion_base("realism_mc_fine") == "realism_mc_fine"  # another tier, not a twin
    spec = [_spec_row("mc", "rigid", "exact", "exact"), _spec_row("mc", "flexible", "exact",
                                                                    "exact"),
            _spec_row("mc_1khz", "rigid", "pid_1khz", "pid"),
            _spec_row("mc_1khz", "flexible", "pid_1khz", "pid"),
            _spec_row("mc_hybrid", "rigid", "hybrid", "hybrid", hunting=1, within_count=17)]
    lines = beside_markdown(spec)
    rows = [line for line in lines if line.startswith("| rigid") or line.startswith(
        "| flexible")]
    assert [r.split(" | ")[1:3] for r in rows] == [
        ["exact", "mc"], ["pid_1khz", "mc_1khz"], ["hybrid", "mc_hybrid"],
        ["exact", "mc"], ["pid_1khz", "mc_1khz"]]
    assert "### mc" in lines and "H MISSED" in rows[2] and "1 of 20 (5.0%)" in rows[2]
    assert beside_markdown([_spec_row("mc", "rigid", "exact", "exact")]) == []
    text = compare_markdown(compare_rows(spec, spec), "a", "b")
    assert "## mc\n" in text and "## mc_1khz" not in text
    assert "| rigid | pid_1khz | mc_1khz | 20/20 (100%) → 20/20 (100%) |" in text
