"""``papwc bench`` section: battery throughput on local processes and on Dask.

The battery is ``scenarios/robustness.toml`` with fewer draws.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import statistics
import tempfile
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from papwc.battery import Battery, BatteryError, parse_battery, run_battery
from papwc.battery.dask_cluster import local_dask_cluster
from papwc.battery.engines import default_workers, mp_context
from papwc.bench import BenchContext, Row, register_section
from papwc.resources import scenario_file
from papwc.scenario import read_toml


def bench_battery(n: int) -> Battery:
    """``scenarios/robustness.toml`` with ``n`` draws, named ``bench``."""
    path = scenario_file("robustness.toml")
    data = read_toml(path, "battery")
    data["name"] = "bench"
    data["monte_carlo"]["n"] = n
    return parse_battery(data, f"{path} (n = {n})")


#: Goals: 2 local workers at least this many times as fast as 1 ...
SPEEDUP_GOAL = 1.8
#: ... and the Dask cluster (same number of worker processes) at most this multiple of
#: the local pool's time.
DASK_RATIO_GOAL = 1.2


def _spin(n: int) -> float:
    """CPU-bound control task of the benchmark: a pure-Python loop."""
    x = 0
    for i in range(n):
        x += i * i
    return float(x % 7)


def _control_speedup(n: int) -> float:
    """Speed-up of 4 pure-Python loops from 1 to 2 processes: what the machine gives now."""
    seconds = []
    for workers in (1, 2):
        with ProcessPoolExecutor(max_workers=workers, mp_context=mp_context()) as ex:
            list(ex.map(_spin, [1000] * workers))  # start the workers
            start = time.perf_counter()
            list(ex.map(_spin, [n] * 4))
            seconds.append(time.perf_counter() - start)
    return seconds[0] / seconds[1]


@register_section("Battery: runs per second, local pool (1 and 2 workers) and Dask")
def battery_throughput(context: BenchContext) -> list[Row]:
    """Battery throughput, local pool (1, 2 workers) and Dask.

    Runs scenarios/robustness.toml (3 controllers x 3 iterations per run) with 1
    and 2 local worker processes and on a Dask cluster of 2 worker processes
    (started with the ``dask`` CLI on 127.0.0.1), interleaved over rounds;
    times are medians of the computing phase (workers' start included, reports
    excluded). Each round also measures a control: the speed-up of a
    pure-Python loop from 1 to 2 processes, i.e. what the machine gives at the
    time. Then the time for 20, 40 and 80 runs with 2 local workers.

    Parameters
    ----------
    context : BenchContext
        Gives the FMU folder and ``quick``.
    """

    fmu = context.fmu("FrictionPlant.fmu")
    n_runs, rounds = (12, 1) if context.quick else (200, 2)
    sizes = (10, 20) if context.quick else (20, 40, 80)
    have_dask = importlib.util.find_spec("distributed") is not None
    times: dict[str, list[float]] = {"local 1": [], "local 2": []}
    if have_dask:
        times["dask 2"] = []
    else:
        context.notes.append("Dask not measured: dask[distributed] is not installed "
                             "(pip install 'papwc[dask]')")
    control: list[float] = []
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        def battery(n: int) -> Battery:
            return bench_battery(n)

        def timed(n: int, **kwargs) -> float:
            out = Path(tempfile.mkdtemp(dir=tmp))
            outcome = run_battery([battery(n)], out, fmu, progress=False, **kwargs)
            if outcome.failed:
                raise BatteryError(f"bench battery: {outcome.failed[0]}")
            return outcome.run_seconds

        timed(4, workers=1)  # warm-up: imports, page cache
        with contextlib.ExitStack() as stack:
            address = stack.enter_context(local_dask_cluster(n_workers=2, nthreads=1)) if (
                have_dask) else None
            for r in range(rounds):
                control.append(_control_speedup(1_000_000 if context.quick else 3_000_000))
                order = [name for name in ("local 1", "local 2", "dask 2") if name in times]
                for name in order[r % len(order):] + order[: r % len(order)]:
                    if name == "dask 2":
                        times[name].append(timed(n_runs, scheduler=address))
                    else:
                        times[name].append(timed(n_runs, workers=int(name[-1])))
        growth = {n: timed(n, workers=2) for n in sizes}
    med = {k: statistics.median(v) for k, v in times.items()}
    speedup = med["local 1"] / med["local 2"]
    v1 = "met" if speedup >= SPEEDUP_GOAL else "MISSED"
    context.notes.append(
        f"{n_runs} runs (scenarios/robustness.toml: 3 controllers x 3 iterations of 200 "
        "steps), "
        f"{rounds} interleaved round(s), medians; time from starting the workers (or "
        f"connecting to the scheduler) to the last run; {default_workers()} cores here; "
        "the control row is what two processes gain on this machine at the time (other "
        "load lowers it)")
    rows = [
        Row("local pool, 1 worker", n_runs / med["local 1"], "runs/s"),
        Row("local pool, 2 workers", n_runs / med["local 2"], "runs/s"),
        Row(f"speed-up 1 -> 2 workers (goal >= {SPEEDUP_GOAL}: {v1})", speedup, "x"),
    ]
    if have_dask:
        ratio = med["dask 2"] / med["local 2"]
        v2 = "met" if ratio <= DASK_RATIO_GOAL else "MISSED"
        rows += [
            Row("Dask, 2 worker processes x 1 thread", n_runs / med["dask 2"], "runs/s"),
            Row(f"Dask time / local time (goal <= {DASK_RATIO_GOAL}: {v2})", ratio, "x"),
        ]
    rows.append(Row("control: pure-Python loop, speed-up 1 -> 2 processes",
                    statistics.median(control), "x"))
    for n, seconds in growth.items():
        rows.append(Row(f"{n} runs, 2 local workers", seconds, "s"))
    first, last = sizes[0], sizes[-1]
    per_run = (growth[last] - growth[first]) / (last - first)
    rows.append(Row(f"marginal cost per run ({first} -> {last} runs)", per_run * 1e3, "ms"))
    rows.append(Row("fixed cost (intercept)", growth[first] - per_run * first, "s"))
    return rows


#: Goal: a worker's RSS grows by less than this over the memory section's battery, kB.
WORKER_GROWTH_GOAL_KB = 1024


def _descendants(pid: int) -> list[int]:
    """Process ids of the children of ``pid`` and of theirs (Linux /proc)."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                stat = Path(f"/proc/{entry}/stat").read_text()
                parents[int(entry)] = int(stat.rsplit(") ", 1)[1].split()[1])
    found, frontier = [], [pid]
    while frontier:
        frontier = [p for p, parent in parents.items() if parent in frontier]
        found += frontier
    return found


def _rss_kb(pid: int) -> int | None:
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return None


@register_section("Battery workers' memory over a 2,000-run battery")
def battery_worker_memory(context: BenchContext) -> list[Row]:
    """RSS of each worker process while 2 local workers run a battery of 2,000 runs.

    The battery is scenarios/robustness.toml with 2,000 draws (100 with ``quick``), on the
    FMU folder's FrictionPlant.fmu; the workers' VmRSS is read from /proc every 0.25 s. The
    growth of a worker is its RSS at the end of the battery less its RSS once a tenth of the
    battery's time has passed (its imports and first run done).

    Parameters
    ----------
    context : BenchContext
        Gives the FMU folder and ``quick``.
    """
    if not Path("/proc/self/status").is_file():
        context.notes.append("workers' memory not measured: needs Linux's /proc")
        return []
    fmu = context.fmu("FrictionPlant.fmu")
    n_runs = 100 if context.quick else 2000
    samples: dict[int, list[tuple[float, int]]] = {}
    done = threading.Event()

    def watch() -> None:
        start = time.perf_counter()
        while not done.wait(0.25):
            for pid in _descendants(os.getpid()):
                rss = _rss_kb(pid)
                if rss is not None:
                    samples.setdefault(pid, []).append((time.perf_counter() - start, rss))

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
            outcome = run_battery([bench_battery(n_runs)], Path(tmp) / "out", fmu, workers=2,
                                  progress=False)
    finally:
        done.set()
        watcher.join()
    if outcome.failed:
        raise BatteryError(f"bench battery: {outcome.failed[0]}")
    # The workers are the processes that ran the whole battery and hold the most memory (the
    # forkserver and the resource tracker are the others).
    end = max((s[-1][0] for s in samples.values()), default=0.0)
    workers = sorted((s for s in samples.values() if s[0][0] <= 0.1 * end and len(s) >= 10),
                     key=lambda s: s[-1][1], reverse=True)[:2]
    if not workers:
        context.notes.append("workers' memory not measured: the battery ended too soon")
        return []
    growth = []
    for s in workers:
        at_tenth = next(rss for t, rss in s if t >= 0.1 * end)
        growth.append(s[-1][1] - at_tenth)
    worst = max(growth)
    verdict = "met" if worst < WORKER_GROWTH_GOAL_KB else "MISSED"
    context.notes.append(
        f"{n_runs} runs of scenarios/robustness.toml on 2 local workers; RSS of each worker from "
        "a tenth of the battery's time to its end")
    return [
        Row("worker RSS at the end (largest)", max(s[-1][1] for s in workers) / 1024, "MB"),
        Row(f"worker RSS growth, largest (goal < {WORKER_GROWTH_GOAL_KB} kB: {verdict})",
            float(worst), "kB"),
        Row("worker RSS growth per run (largest worker, its share of the runs)",
            worst / (0.9 * n_runs / len(workers)), "kB"),
    ]
