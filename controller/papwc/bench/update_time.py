"""``papwc bench`` section: each controller kind's ``update`` against its sample period (R7).

A controller that needs more than its sample period to decide cannot run at that rate,
in Python, in PulseController.fmu or on a drive. Every registered kind is run in closed
loop on the shipped files that name it (:data:`FILES`: realism.toml, the first draws of
realism_mc.toml, the 1 kHz PID of realism_1khz.toml and realism_mc_1khz.toml, the dual
loop on flexible_dual.toml and realism_mc_dual.toml, the 1 kHz hybrid on
realism_mc_hybrid.toml; every case, target and seed that
draws something, the first :data:`DRAWS` draws, 3 iterations), on the native
FrictionPlant.fmu, and the thread CPU
time (:func:`time.thread_time_ns`) of each call of its ``update`` is recorded. Per kind and
sample period T: the median, the 99th percentile and the largest, the updates beyond T/2,
and the verdict of R7: the largest at most :data:`papwc.battery.spec.R7_SHARE_OF_T` times T.

Two things are kept out of the figure that are not the controller's. The bench's own
objects are frozen out of the garbage collector's generations during each run
(:func:`gc.freeze`), so that a collection inside an update scans what a controller's
process would hold, not the bench's millions of recorded times; and so is the trace the
master records as the run goes on (a list per slave and sample: every
:data:`FREEZE_EVERY` updates, outside the time measured; at T = 1 ms a collection that
scanned a 6000-sample trace took 0.3 to 0.9 ms inside an update of 0.01 ms). And a run with
an update above T/4 is made again (:data:`REPEATS` times at most), each update keeping its least
time: on a shared or virtual machine a thread's CPU time also counts what the machine took
from it (a 1 kHz PID update measured 0.14 ms at most in one pass, 20 ms once in the next).

``--quick``: the first target, seed and draw of each case only.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

from papwc.bench import BenchContext, Row, register_section

#: The shipped files measured (every controller kind registered must be in one of them).
FILES = ("realism.toml", "realism_mc.toml", "realism_1khz.toml", "realism_mc_1khz.toml",
         "flexible_dual.toml", "realism_mc_dual.toml", "realism_mc_hybrid.toml")
#: Draws of each Monte Carlo file measured (the first ones).
DRAWS = 2
#: Most times a run is made (see :func:`update_times`).
REPEATS = 3
#: Updates after which the objects made since are frozen out of the garbage collector's
#: generations (the master's trace of the run, see :func:`_timed_run`).
FREEZE_EVERY = 256


def selected_runs(files: Iterable[str | Path], quick: bool = False) -> list:
    """The scenarios measured, as :class:`papwc.scenario.Scenario` in file order: every run
    of each battery file but, of a Monte Carlo, only the first :data:`DRAWS` draws;
    ``quick``: the first value of every swept field (target, seed) and the first draw."""
    from papwc.battery import load_battery, plan_runs
    from papwc.resources import scenario_file
    from papwc.scenario import parse_scenario

    out = []
    seen = set()
    for name in files:
        path = Path(name)
        battery = load_battery(path if path.is_file() else scenario_file(str(name)))
        draws = 1 if quick else DRAWS
        for spec in plan_runs([battery]):
            if spec.error or spec.order[2] >= draws or (quick and spec.order[1] > 0):
                continue
            scenario = parse_scenario(spec.data, f"{battery.source} run {spec.run_id}")
            same = _without_unused_seeds(scenario)
            if same not in seen:  # a seed that draws nothing repeats a run exactly
                seen.add(same)
                out.append(scenario)
    return out


def _without_unused_seeds(scenario) -> str:
    """The scenario's runs as text, less the seeds that draw nothing in it."""
    import json

    plant = dict(scenario.plant)
    if not any(plant.get(name, 0.0) > 0.0 for name in ("f_s_spread", "noise_std",
                                                         "x_d_noise_std")):
        plant.pop("seed", None)
    maneuver = dict(vars(scenario.maneuver))
    if not maneuver["noise_std"] > 0.0:
        maneuver.pop("noise_seed")
    controllers = [s.to_mapping(with_none=True) for s in scenario.controllers]
    return json.dumps([plant, maneuver, controllers, list(scenario.labels)], sort_keys=True,
                      default=repr)


def update_times(scenarios: Sequence, plant: str = "fmu", fmu: str | Path | None = None,
                 unzip_dir: str | Path | None = None, repeats: int = REPEATS
                 ) -> dict[tuple[str, float], list[int]]:
    """Thread CPU time (ns) of every ``update`` call, by (kind, T), over every controller of
    ``scenarios`` run in closed loop (each iteration of each maneuver).

    A run with an update above a quarter of T is run again, up to ``repeats`` times in all,
    and each call keeps its least time: the runs are deterministic, so call i is the same
    work each time, and what a repetition does not show again was the machine's (another
    process, the hypervisor), not the controller's.
    """
    from papwc.battery.spec import R7_SHARE_OF_T

    out: dict[tuple[str, float], list[int]] = {}
    for scenario in scenarios:
        T = scenario.maneuver.T
        for settings, label in zip(scenario.controllers, scenario.labels, strict=True):
            times = _timed_run(scenario, settings, label, plant, fmu, unzip_dir)
            for _ in range(repeats - 1):
                if max(times, default=0) * 1e-9 <= 0.5 * R7_SHARE_OF_T * T:
                    break
                again = _timed_run(scenario, settings, label, plant, fmu, unzip_dir)
                if len(again) != len(times):
                    raise ValueError(f"bench: {label} on {scenario.name} made another number "
                                     "of updates when run again: the run is not deterministic")
                times = [min(a, b) for a, b in zip(times, again, strict=True)]
            out.setdefault((settings.kind, T), []).extend(times)
    return out


def _timed_run(scenario, settings, label: str, plant: str, fmu, unzip_dir) -> list[int]:
    """Thread CPU time (ns) of each ``update`` of one controller's closed-loop run."""
    from papwc.controllers import make_controller
    from papwc.master.closed_loop import run_closed_loop
    from papwc.master.slave import ControllerSlave
    from papwc.scenario_run import make_plant, release_plant

    clock = time.thread_time_ns
    times: list[int] = []
    controller = make_controller(settings, scenario.maneuver.T)
    update = controller.update

    def timed(t: float, x_meas: float, x_ref: float) -> float:
        if len(times) % FREEZE_EVERY == 0:
            # the trace the master records grows by a list per slave and sample: frozen
            # out of the collector's way as it grows (outside the time measured)
            gc.freeze()
        start = clock()
        u = update(t, x_meas, x_ref)
        times.append(clock() - start)
        return u

    controller.update = timed  # the instance's own: the slave calls it
    slave = make_plant(scenario, plant, fmu, unzip_dir)
    # The bench's own objects (earlier runs' garbage, the lists of times) kept out of the
    # collector's way: a collection inside an update then costs what it would in a process
    # holding the controller and its loop only.
    gc.collect()
    gc.freeze()
    try:
        run_closed_loop(slave, ControllerSlave(controller), scenario.maneuver, settings, label)
    finally:
        gc.unfreeze()
        release_plant(slave, fmu, unzip_dir)
    return times


def percentile(values: Sequence[int], share: float) -> float:
    """The value below which ``share`` of ``values`` lie (the nearest rank, the higher one)."""
    ordered = sorted(values)
    return float(ordered[min(len(ordered) - 1, max(0, math.ceil(share * len(ordered)) - 1))])


def update_rows(times: dict[tuple[str, float], list[int]]) -> list[Row]:
    """Rows per kind and T: updates, median, p99, max (ms), updates beyond T/2, R7's verdict."""
    import statistics

    from papwc.battery.spec import R7_SHARE_OF_T

    rows = []
    for (kind, T), ns in sorted(times.items(), key=lambda item: (item[0][0], -item[0][1])):
        if not ns:
            continue
        limit = R7_SHARE_OF_T * T
        worst = max(ns) * 1e-9
        head = f"{kind} at T = {T * 1e3:g} ms"
        verdict = "met" if worst <= limit else "MISSED"
        rows += [Row(f"{head}: updates", len(ns), ""),
                 Row(f"{head}: median", statistics.median(ns) * 1e-6, "ms"),
                 Row(f"{head}: p99", percentile(ns, 0.99) * 1e-6, "ms"),
                 Row(f"{head}: max", worst * 1e3, "ms"),
                 Row(f"{head}: updates beyond T/2", sum(1 for t in ns if t * 1e-9 > limit), ""),
                 Row(f"{head}: R7 goal, max at most T/2 ({verdict})", limit * 1e3, "ms")]
    return rows


@register_section("Controller update time against the sample period (R7, thread CPU time)")
def update_time(context: BenchContext) -> list[Row]:
    """Every controller kind on the shipped files that name it (see the module)."""
    from papwc.battery.worker import _extract
    from papwc.controllers import CONTROLLER_KINDS

    fmu = context.fmu("FrictionPlant.fmu")
    scenarios = selected_runs(FILES, context.quick)
    start = time.perf_counter()
    times = update_times(scenarios, "fmu", fmu, _extract(str(fmu)))
    wall = time.perf_counter() - start
    missing = sorted(set(CONTROLLER_KINDS) - {kind for kind, _ in times})
    which = ("the first target, seed and draw of each case" if context.quick
             else f"every case, target and seed that draws something, the first {DRAWS} "
             "draws")
    context.notes.append(f"{len(scenarios)} runs of {', '.join(FILES)} ({which}), 3 "
                         f"iterations each, native plant; {wall:.0f} s")
    if missing:
        context.notes.append("kinds in no measured file (not measured): " + ", ".join(missing))
    return update_rows(times)
