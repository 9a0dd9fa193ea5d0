"""``papwc bench --realism``: the wall time of the realism battery on 2 local workers."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from papwc.bench import BenchContext, Row, register_section

#: The whole realism battery must finish within this time on 2 workers, s.
REALISM_SECONDS_GOAL = 600.0


@register_section("Realism battery: scenarios/realism.toml on 2 local workers", option="realism")
def realism_wall_time(context: BenchContext) -> list[Row]:
    """Run ``scenarios/realism.toml`` (every case, target and seed) on 2 workers; time it."""
    from papwc.battery import BatteryError, load_battery, run_battery
    from papwc.resources import scenario_file

    fmu = context.fmu("FrictionPlant.fmu")
    battery = load_battery(scenario_file("realism.toml"))
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        start = time.perf_counter()
        outcome = run_battery([battery], Path(tmp), fmu, workers=2, progress=False)
        wall = time.perf_counter() - start
    if outcome.computed != outcome.runs:
        raise BatteryError("bench realism: not every run was computed")
    verdict = "met" if wall <= REALISM_SECONDS_GOAL else "MISSED"
    context.notes.append(
        f"{outcome.runs} runs x {len(battery.data['controller'])} controllers x "
        f"{battery.data['maneuver']['iterations']} iterations; wall time of run_battery "
        "(planning, workers, report and plots)")
    return [
        Row("runs", outcome.runs, ""),
        Row("runs with status error", len(outcome.failed), ""),
        Row("computing (workers started to last run)", outcome.run_seconds, "s"),
        Row("wall time", wall, "s"),
        Row(f"goal: wall time at most ({verdict})", REALISM_SECONDS_GOAL, "s"),
    ]
