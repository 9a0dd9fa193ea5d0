"""Run a scenario's controllers against the plant and write what ``papwc run`` writes."""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path

from papwc.errors import FmuError
from papwc.master import FmuSlave, PhysicsSlave, RunResult, Slave, run_controller, summarize
from papwc.output import write_rows
from papwc.scenario import Scenario

SUMMARY_COLUMNS = [
    "controller", "kind", "t_p_max", "iteration", "final_error_m", "pulses", "settle_time_s",
    "limit_cycle", "cycle_p2p_m", "b_hat", "f_c_hat", "status", "message",
]  # fmt: skip

def ensure_plant_fmu(fmu: str | os.PathLike | None, out: str | os.PathLike) -> Path:
    """The plant FMU to use: ``fmu`` if given, else one built from the current sources.

    Without ``fmu``: the checkout's build/FrictionPlant.fmu when it is current,
    else ``out/fmu/FrictionPlant.fmu`` (built there if missing or stale).
    """
    if fmu is not None:
        path = Path(fmu)
        if not path.is_file():
            raise FmuError(f"plant FMU {str(path)!r} does not exist")
        return path
    from papwc.fmubuild.fmus import current_fmu

    return current_fmu("FrictionPlant", Path(out) / "fmu")


def make_plant(scenario: Scenario, plant: str = "fmu", fmu: str | os.PathLike | None = None,
               unzip_dir: str | os.PathLike | None = None) -> Slave:
    """A plant with the scenario's parameters: ``"fmu"`` (an FMU file) or ``"physics"``.

    ``unzip_dir`` is an extracted copy of the FMU to use (a battery worker
    extracts it once).
    """
    slave = PhysicsSlave() if plant == "physics" else FmuSlave(fmu, unzip_dir=unzip_dir)
    slave.set_start_values(dict(scenario.plant))
    return slave


def run_scenario(scenario: Scenario, plant: str = "fmu", fmu: str | os.PathLike | None = None,
                 progress: Callable[[RunResult], None] | None = None,
                 unzip_dir: str | os.PathLike | None = None) -> list[RunResult]:
    """Run every controller of the scenario (each with a fresh plant instance).

    ``fmu`` is the plant FMU's path when ``plant`` is ``"fmu"`` (and
    ``unzip_dir`` an extracted copy of it, if there is one); ``progress`` is
    called with each controller's result as it finishes.
    """
    results = []
    for settings, label in zip(scenario.controllers, scenario.labels, strict=True):
        slave = make_plant(scenario, plant, fmu, unzip_dir)
        try:
            results.append(run_controller(slave, settings, scenario.maneuver, label))
        finally:
            slave.close()
        if progress is not None:
            progress(results[-1])
    return results


def summary_rows(results: list[RunResult]) -> list[dict]:
    """One row per controller and iteration (columns SUMMARY_COLUMNS)."""
    rows = []
    for r in results:
        for tr in r.traces:
            m = summarize(tr, r.settings.tolerance)
            rows.append({
                "controller": r.label, "kind": r.settings.kind, "t_p_max": r.settings.t_p_max,
                "iteration": tr.iteration, **m,
                "status": "error" if tr.error else "ok", "message": tr.error,
            })
        if r.error and (not r.traces or not r.traces[-1].error):
            rows.append({"controller": r.label, "kind": r.settings.kind,
                         "t_p_max": r.settings.t_p_max, "iteration": len(r.traces) + 1,
                         "status": "error", "message": r.error})
    return rows


def write_results(results: list[RunResult], out: Path) -> list[dict]:
    """Write summary.csv, trace_<controller>_it<N>.csv and the plots into ``out``."""
    from papwc.analysis import plots

    out.mkdir(parents=True, exist_ok=True)
    rows = summary_rows(results)
    write_rows(out / "summary.csv", rows, SUMMARY_COLUMNS)
    for r in results:
        for tr in r.traces:
            tr.to_csv(out / f"trace_{r.label}_it{tr.iteration}.csv")
    plots.run_plots(results, out)
    return rows


def format_table(rows: list[dict]) -> str:
    """The summary as a text table."""
    head = ("controller", "it", "final_error_m", "pulses", "settle_s", "limit_cycle",
            "b_hat", "f_c_hat", "status")
    lines = ["{:<18} {:>3} {:>14} {:>6} {:>9} {:>11} {:>9} {:>9} {}".format(*head)]
    def f(r: dict, key: str, fmt: str) -> str:
        v = r.get(key, math.nan)
        return format(v, fmt) if isinstance(v, float) else str(v)

    for r in rows:
        lines.append("{:<18} {:>3} {:>14} {:>6} {:>9} {:>11} {:>9} {:>9} {}".format(
            r["controller"], r["iteration"], f(r, "final_error_m", ".3e"), r.get("pulses", ""),
            f(r, "settle_time_s", ".2f"), str(r.get("limit_cycle", "")), f(r, "b_hat", ".4f"),
            f(r, "f_c_hat", ".2f"), r["status"] + (f" ({r['message']})" if r["message"] else "")))
    return "\n".join(lines)
