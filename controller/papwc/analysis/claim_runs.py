"""Running the paper's scenario for its claims: each role under each reading once, in one
process or several, the FMU extracted once.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from papwc.analysis.readings import Reading, apply_reading
from papwc.analysis.run_metrics import FIXED, ROLES, RunMetrics, role_of, run_metrics
from papwc.controllers.settings import ControllerSettings
from papwc.master import RunResult

__all__: list[str] = []  # used by papwc.analysis.claims only


@dataclass(frozen=True)
class _Task:
    """One controller run: a role under the overrides of its kind."""

    role: str
    overrides: tuple[tuple[str, Any], ...]


def _role_settings(scenario, role: str) -> tuple[ControllerSettings, str] | None:
    base = role[:-len(FIXED)] if role.endswith(FIXED) else role
    for settings, label in zip(scenario.controllers, scenario.labels, strict=True):
        if role_of(settings) == base:
            if role.endswith(FIXED):
                return (apply_reading(settings, {"update_covariance": False}),
                        label + "_fixed_covariance")
            return settings, label
    return None


def _roles(scenario) -> list[str]:
    present = {role_of(s) for s in scenario.controllers}
    out = [r for r in ROLES if r in present]
    return out + [r + FIXED for r in out if r.startswith("papwc")]


def _run_task(scenario, task: _Task, plant: str, fmu: str | None,
              unzip_dir: str | None) -> RunMetrics:
    from papwc.master import run_controller
    from papwc.scenario_run import make_plant

    settings, label = _role_settings(scenario, task.role)
    settings = apply_reading(settings, dict(task.overrides))
    problems = settings.problems()
    if problems:
        return run_metrics(RunResult(label, settings, error=problems[0][1]))
    slave = make_plant(scenario, plant, fmu, unzip_dir)
    try:
        return run_metrics(run_controller(slave, settings, scenario.maneuver, label))
    except Exception as exc:  # noqa: BLE001 - a failing run is a claim not reproduced
        return run_metrics(RunResult(label, settings, error=f"{type(exc).__name__}: {exc}"))
    finally:
        slave.close()


def _run_batch(scenario, tasks: list[_Task], plant: str, fmu: str | None,
               unzip_dir: str | None) -> list[RunMetrics]:
    return [_run_task(scenario, t, plant, fmu, unzip_dir) for t in tasks]


class _Runs:
    """Runs of the scenario under readings, each run once (FMU extracted once)."""

    def __init__(self, scenario, plant: str = "fmu", fmu: str | os.PathLike | None = None,
                 known: Mapping[str, RunMetrics] | None = None) -> None:
        self.scenario = scenario
        self.plant = plant
        self.fmu = None if fmu is None else str(fmu)
        self.roles = _roles(scenario)
        self.cache: dict[_Task, RunMetrics] = {}
        for role, metrics in (known or {}).items():
            self.cache[_Task(role, ())] = metrics
        self._unzip: str | None = None

    def tasks(self, reading: Reading) -> dict[str, _Task]:
        """The run of every role under ``reading``."""
        return {role: _Task(role, tuple(sorted(reading.overrides(role.split("_")[0]).items())))
                for role in self.roles}

    def metrics(self, reading: Reading) -> dict[str, RunMetrics]:
        """Metrics of every role under ``reading`` (running what is not cached)."""
        tasks = self.tasks(reading)
        self.run([t for t in tasks.values() if t not in self.cache])
        return {role: self.cache[t] for role, t in tasks.items()}

    def run(self, tasks: Sequence[_Task], workers: int = 1) -> None:
        """Run ``tasks`` (in ``workers`` processes if more than one) into the cache."""
        tasks = list(dict.fromkeys(t for t in tasks if t not in self.cache))
        if not tasks:
            return
        unzip = self._unzip_dir()
        if workers <= 1:
            for t in tasks:
                self.cache[t] = _run_task(self.scenario, t, self.plant, self.fmu, unzip)
            return
        from concurrent.futures import ProcessPoolExecutor, as_completed

        from papwc.battery.engines import mp_context

        size = max(1, min(32, len(tasks) // (8 * workers) or 1))
        batches = [tasks[i:i + size] for i in range(0, len(tasks), size)]
        done, start, next_report = 0, time.perf_counter(), 0.1
        with ProcessPoolExecutor(max_workers=workers, mp_context=mp_context()) as pool:
            futures = {pool.submit(_run_batch, self.scenario, b, self.plant, self.fmu, unzip): b
                       for b in batches}
            for fut in as_completed(futures):
                for t, m in zip(futures[fut], fut.result(), strict=True):
                    self.cache[t] = m
                done += len(futures[fut])
                if done >= next_report * len(tasks) or done == len(tasks):
                    print(f"  {done}/{len(tasks)} runs ({time.perf_counter() - start:.0f} s)",
                          flush=True)
                    next_report = done / len(tasks) + 0.1

    def _unzip_dir(self) -> str | None:
        if self.plant != "fmu" or self._unzip is not None:
            return self._unzip
        from fmpy import extract

        self._unzip = tempfile.mkdtemp(prefix="papwc_claims_")
        extract(self.fmu, unzipdir=self._unzip)
        return self._unzip

    def close(self) -> None:
        """Remove the extracted FMU."""
        if self._unzip is not None:
            shutil.rmtree(self._unzip, ignore_errors=True)
            self._unzip = None
