"""``papwc bench --realism``: the wall time of the realism battery on 2 local workers."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from papwc.bench import BenchContext, Row, register_section

#: The whole realism battery must finish within this time on 2 workers, s.
REALISM_SECONDS_GOAL = 600.0


def _run(battery, fmu: Path) -> tuple[object, float, list[dict[str, str]]]:
    """Run ``battery`` on 2 workers with plant ``fmu``: (outcome, wall time s, results.csv)."""
    import csv

    from papwc.battery import run_battery

    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        start = time.perf_counter()
        outcome = run_battery([battery], Path(tmp), fmu, workers=2, progress=False)
        wall = time.perf_counter() - start
        (results,) = Path(tmp).rglob("results.csv")
        with open(results, newline="") as f:
            rows = list(csv.DictReader(f))
    return outcome, wall, rows


def max_difference(a: list[dict[str, str]], b: list[dict[str, str]]) -> float:
    """Largest abs(difference) between two results.csv (inf where a text or a row differs)."""
    if len(a) != len(b):
        return float("inf")
    worst = 0.0
    for row_a, row_b in zip(a, b, strict=True):
        for key, value in row_a.items():
            other = row_b.get(key)
            if value == other:
                continue
            try:
                worst = max(worst, abs(float(value) - float(other)))
            except (TypeError, ValueError):
                return float("inf")
    return worst


#: The native plant's battery must be at least this many times as fast as the pythonfmu one's.
NATIVE_SPEEDUP_GOAL = 10.0
#: ... with every value of results.csv within this (m).
NATIVE_RESULTS_TOL = 1e-12


@register_section("Realism battery: scenarios/realism.toml on 2 local workers", option="realism")
def realism_wall_time(context: BenchContext) -> list[Row]:
    """Run ``scenarios/realism.toml`` (every case, target and seed) on 2 workers with the
    native plant and with the pythonfmu plant; time both, compare results.csv."""
    from papwc.battery import BatteryError, load_battery
    from papwc.bench.native_step import PYTHONFMU_PLANT
    from papwc.resources import scenario_file

    battery = load_battery(scenario_file("realism.toml"))
    outcome, wall, rows = _run(battery, context.fmu("FrictionPlant.fmu"))
    py_outcome, py_wall, py_rows = _run(battery, context.fmu(PYTHONFMU_PLANT))
    if outcome.computed != outcome.runs or py_outcome.computed != py_outcome.runs:
        raise BatteryError("bench realism: not every run was computed")
    verdict = "met" if wall <= REALISM_SECONDS_GOAL else "MISSED"
    speedup = py_wall / wall
    difference = max_difference(rows, py_rows)
    fast = "met" if speedup >= NATIVE_SPEEDUP_GOAL else "MISSED"
    same = "met" if difference <= NATIVE_RESULTS_TOL else "MISSED"
    context.notes.append(
        f"{outcome.runs} runs x {len(battery.data['controller'])} controllers x "
        f"{battery.data['maneuver']['iterations']} iterations; wall time of run_battery "
        "(planning, workers, report and plots), native plant first, then pythonfmu")
    return [
        Row("runs", outcome.runs, ""),
        Row("runs with status error (native)", len(outcome.failed), ""),
        Row("computing (workers started to last run), native", outcome.run_seconds, "s"),
        Row("wall time, native", wall, "s"),
        Row(f"goal: wall time at most ({verdict})", REALISM_SECONDS_GOAL, "s"),
        Row("wall time, pythonfmu", py_wall, "s"),
        Row("speed-up native over pythonfmu", speedup, "x"),
        Row(f"goal: speed-up at least ({fast})", NATIVE_SPEEDUP_GOAL, "x"),
        Row("largest |difference| in results.csv", difference, ""),
        Row(f"goal: at most ({same})", NATIVE_RESULTS_TOL, "m"),
    ]
