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
from papwc.battery.report import SPEC_COLUMNS, pulse_rows, spec_rows, write_outputs
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
               settle: float = math.nan, farther: bool = False) -> dict:
    return {"iteration": k, "final_error_m": e, "pulses": 3, "settle_time_s": settle,
            "limit_cycle": False, "cycle_p2p_m": 0.0, "b_hat": 1.0, "f_c_hat": 90.0,
            "outcome": outcome, "outcome_reason": reason, "pulse_ratio": 0.5,
            "ends_farther": farther, "error": ""}


def _pulse(k: int, e: float, d: float, ratio: float) -> dict:
    return {"iteration": k, "pulse": 1, "t_s": 0.1, "samples": 1, "amplitude_N": 140.0,
            "e_m": e, "d_m": d, "smallest_m": 1e-7, "bound_m": abs(d) / ratio if ratio else 1.0,
            "ratio": ratio}


#: Last iterations of the four runs of a case: (final error, outcome, reason, settle time).
LAST = [(5e-8, "settled", "within_tolerance", 0.2), (9e-8, "settled", "within_tolerance", 0.5),
        (-8e-7, "stopped", "time_ended", math.nan), (1e-4, "settled", "within_tolerance", 1.0)]
#: Pulses of the first run: fired at abs(e) >= 1 um (one runaway, one within, one that
#: exceeds 1 only by the replay's rounding), below (one runaway, one that did not move, one
#: within).
PULSES = [_pulse(1, 5e-6, 1e-5, 1.2), _pulse(1, -5e-6, -2e-6, 0.2), _pulse(1, 2e-6, 4e-6, 1.0
          + 1e-10), _pulse(2, 5e-7, 3e-6, 2.5), _pulse(2, 5e-7, 0.0, 0.0),
          _pulse(2, -2e-7, -1e-7, 0.3)]


@pytest.fixture
def crafted():
    battery = parse_battery(tomllib.loads(BATTERY), "spec.toml")
    runs = plan_runs([battery])
    records = {}
    for spec in runs:
        i = ["s0", "s1", "s2", "s3"].index(spec.run_id.split("-")[1])
        e, outcome, reason, settle = LAST[i]
        its = [_iteration(1, 1e-3, farther=(i == 3)), _iteration(2, e, outcome, reason, settle)]
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
        "runs": 4, "errors": 0,
        "within_1um": 3,  # 5e-8, 9e-8 and 8e-7 m
        "counted_runs": 4, "within_count": 2,  # 5e-8 and 9e-8 m
        "settle_median_s": 0.75,  # of 0.2, 0.5, 1.0 (a false settled) and inf (time ended)
        "settle_p95_s": math.inf,
        "pulses_far": 3, "runaway_far": 1, "pulses_near": 2, "runaway_near": 1,
        "largest_runaway_m": 1e-5,
        "maneuvers": 8, "farther": 1,
        "false_settled": 1,  # settled at 1e-4 m with tolerance 1e-7 m
        "time_ended": 1,
    }
    # the ideal encoder has no count; the failed run counts as a run, not a success
    assert ideal["runs"] == 4 and ideal["errors"] == 1 and ideal["within_1um"] == 3
    assert ideal["counted_runs"] == 0 and ideal["within_count"] == 0
    assert ideal["settle_median_s"] == 0.5 and ideal["settle_p95_s"] == math.inf
    assert ideal["maneuvers"] == 6 and ideal["farther"] == 0 and ideal["time_ended"] == 1
    assert set(counted) == set(SPEC_COLUMNS)


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
    assert [r["run_id"] for r in got] == ["counted-s0"] * 6 + ["ideal-s0"] * 6
    assert [float(r["ratio"]) for r in got[:6]] == [p["ratio"] for p in PULSES]
    assert got[0]["run_hash"] == runs[0].run_hash and got[0]["iteration"] == "1"
    with open(tmp_path / "spec.csv", newline="") as f:
        spec = list(csv.DictReader(f))
    assert [(r["case"], r["runaway_far"], r["runaway_near"]) for r in spec] == [
        ("counted", "1", "1"), ("ideal", "1", "1")]
    text = (tmp_path / "summary.md").read_text()
    assert ("| counted | exact | 4 | 3 of 4 (75.0%) | 2 of 4 (50.0%) | 0.750 | inf | "
            "1 of 3 (33.3%) | 1 of 2 (50.0%) | 1e-05 | 1 of 8 | 1 | 1 |") in text
    assert "| ideal | exact | 4 | 3 of 4 (75.0%) | – |" in text


def test_a_record_with_malformed_pulses_is_not_used(crafted) -> None:
    _, _, records = crafted
    record = dict(next(iter(records.values())))
    record["controllers"] = [{**record["controllers"][0], "pulses": [{"ratio": "x"}]}]
    assert record_problem(record) == "a controller's pulses are not a list of pulse rows"
    record["controllers"] = [{**record["controllers"][0], "pulses": {}}]
    assert record_problem(record) == "a controller's pulses are not a list of pulse rows"
