"""Running one run in a worker process: the FMU extracted once, every controller of the run."""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
import threading
import time
from pathlib import Path

from papwc.scenario import (
    parse_scenario,
)

# --- running one run (in a worker) ----------------------------------------------------------

_FMU_CACHE: dict[str, tuple[str, str]] = {}
_FMU_LOCK = threading.Lock()


#: Prefix of the temporary folders of a worker process; the process id follows it.
_TMP_PREFIX = "papwcbattery"


def _private_dir() -> str:
    """A temporary folder named after this process; those of dead processes are removed."""
    root = Path(tempfile.gettempdir())
    for entry in root.glob(f"{_TMP_PREFIX}*_*"):
        pid = entry.name[len(_TMP_PREFIX):].split("_", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            shutil.rmtree(entry, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f"{_TMP_PREFIX}{os.getpid()}_")


def _extract(fmu_path: str) -> str:
    """Extract an FMU into a private temporary folder removed when the process exits.

    A process killed before it could remove its folder leaves it behind; the
    next worker that extracts an FMU removes it.
    """
    from fmpy import extract

    unzip_dir = _private_dir()
    extract(fmu_path, unzipdir=unzip_dir)
    import atexit
    from multiprocessing import util

    atexit.register(shutil.rmtree, unzip_dir, True)
    util.Finalize(None, shutil.rmtree, args=(unzip_dir, True), exitpriority=10)
    return unzip_dir


def cached_plant(digest: str, fmu_path: str | None = None,
                 fmu_bytes: bytes | None = None) -> tuple[str, str]:
    """(fmu path, extracted folder) of the FMU with SHA-256 ``digest``, extracted once."""
    with _FMU_LOCK:
        if digest not in _FMU_CACHE:
            if fmu_path is None:
                folder = _private_dir()
                import atexit

                atexit.register(shutil.rmtree, folder, True)
                fmu_path = os.path.join(folder, "plant.fmu")
                with open(fmu_path, "wb") as f:
                    f.write(fmu_bytes)
            _FMU_CACHE[digest] = (fmu_path, _extract(fmu_path))
        return _FMU_CACHE[digest]


def execute_run(task: dict, fmu_path: str, unzip_dir: str) -> dict:
    """Run every controller of one resolved run against fresh plant instances.

    Parameters
    ----------
    task : dict
        From :meth:`RunSpec.task`.
    fmu_path, unzip_dir : str
        The plant FMU and an extracted copy of it.

    Returns
    -------
    dict
        The journal record: the task's ids and ``params``, ``status`` (``"ok"`` or
        ``"error"``), ``message``, and per controller its label, kind,
        tolerance, error and the metrics of every iteration (those of
        :func:`papwc.master.summarize`, the largest ratio of a pulse's
        displacement to its bound, :meth:`papwc.results.pulses.PulseBound.ratios` (the
        table's quantum computed once per run, on the FMU's C plant where it has one), and
        whether the iteration ended farther from the target than it started),
        and ``pulses``: every pulse of every iteration (:func:`pulse_rows`).
        Exceptions are caught and recorded, never raised.
    """
    from papwc.interrupts import RunTimeout
    from papwc.master.native_controller import fmu_controller_library
    from papwc.master.native_plant import plant_library
    from papwc.results.pulses import PulseBound
    from papwc.results.summary import summarize
    from papwc.scenario_run import run_scenario

    start, cpu_start = time.perf_counter(), time.process_time()
    record = {"type": "run", "battery": task["battery"], "run_id": task["run_id"],
              "run_hash": task["run_hash"], "params": task["data"], "status": "ok",
              "message": "", "controllers": []}
    if task.get("key"):
        record["key"] = task["key"]
    try:
        scenario = parse_scenario(task["data"], f"{task['source']} run {task['run_id']}")
        if task.get("identify_first"):
            problem = _identify_first(scenario, fmu_path, unzip_dir, record)
            if problem:
                record.update(status="error", message=problem)
                record["elapsed_s"] = time.perf_counter() - start
                record["cpu_s"] = time.process_time() - cpu_start
                return record
        results = run_scenario(scenario, "fmu", fmu_path, unzip_dir=unzip_dir,
                               timeout=task.get("timeout"),
                               library=fmu_controller_library(task.get("controller_fmu")))
        bound = PulseBound(scenario.plant, scenario.maneuver.T, plant_library(unzip_dir))
        for result in results:
            settings = result.settings
            iterations = []
            ratios = bound.ratios(result.traces)
            for trace, ratio in zip(result.traces, ratios, strict=True):
                metrics = summarize(trace, settings.tolerance)
                iterations.append({"iteration": trace.iteration, **metrics,
                                   "pulse_ratio": ratio, "ends_farther": ends_farther(trace),
                                   "error": trace.error})
            entry = {"label": result.label, "kind": settings.kind,
                     "tolerance": settings.tolerance, "error": result.error,
                     "iterations": iterations,
                     "pulses": pulse_rows(result.traces, bound)}
            warning = scenario.warnings_of(result.label)
            if warning:
                entry["warning"] = warning
            record["controllers"].append(entry)
            if result.error and record["status"] == "ok":
                record["status"] = "error"
                record["message"] = f"{result.label}: {result.error}"
        warnings = "; ".join(f"{label}: {text}" for label, text in scenario.warnings)
        if warnings and record["status"] == "ok":
            record["message"] = "warning: " + warnings
    except RunTimeout as exc:
        record.update(status="error", message=str(exc), controllers=[], transient=True)
    except Exception as exc:  # noqa: BLE001 - a failing run is recorded, the battery goes on
        record["status"] = "error"
        record["message"] = f"{type(exc).__name__}: {exc}"
    record["elapsed_s"] = time.perf_counter() - start
    record["cpu_s"] = time.process_time() - cpu_start  # (journal only: papwc bench reads it)
    return record


def _identify_first(scenario, fmu_path: str, unzip_dir: str, record: dict) -> str:
    """Identify the run's table (:mod:`papwc.battery.identify_first`) and give its
    controllers the identified plant; what was identified goes into ``record``. Returns ""
    or why the run cannot run (one line)."""
    from papwc.battery.identify_first import identified_table, model_of
    from papwc.errors import ScenarioError
    from papwc.master.native_plant import plant_library

    found = identified_table(scenario.plant, scenario.maneuver.T, fmu_path, unzip_dir,
                             plant_library(unzip_dir))
    record["identified"] = {k: v for k, v in found.items() if k != "model"}
    if "error" in found:
        return found["error"]
    model = model_of(found)
    record["identified"].update(model.record())
    try:
        model.give_to(scenario)
    except ScenarioError as exc:
        return f"identify_first: {exc}"
    return ""


def pulse_rows(traces, bound) -> list[dict]:
    """Every pulse of every iteration as a row of ``papwc run``'s pulses.csv, its iteration
    first (:meth:`papwc.results.pulses.PulseBound.rows` of ``bound``, the run's table)."""
    return [{"iteration": trace.iteration, **row} for trace in traces
            for row in bound.rows(trace)]


def ends_farther(trace) -> bool:
    """Whether the true position ends the iteration farther from the target than it started."""
    x = trace.columns["x"]
    return bool(x) and abs(trace.x_ref - x[-1]) > abs(trace.x_ref - x[0])


def error_record(task: dict, message: str, transient: bool = False) -> dict:
    """The journal record of a run that could not run (``task`` from :meth:`RunSpec.task`).

    ``transient``: the cause lies in the circumstances (a time limit, a worker
    that died), not in the run's inputs; ``--resume`` computes the run again.
    """
    record = {"type": "run", "battery": task["battery"], "run_id": task["run_id"],
              "run_hash": task["run_hash"], "params": task["data"], "status": "error",
              "message": message, "controllers": [], "elapsed_s": 0.0}
    if task.get("key"):
        record["key"] = task["key"]
    if transient:
        record["transient"] = True
    return record


_LOCAL: dict[str, str] = {}


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat.rsplit(")", 1)[-1].split()[0] not in ("Z", "X")


def _watch_owner(owner: int) -> None:
    while True:
        time.sleep(0.5)
        if not _alive(owner):
            if "unzip_dir" in _LOCAL:
                shutil.rmtree(_LOCAL["unzip_dir"], ignore_errors=True)
            os._exit(1)


def init_local_worker(fmu_path: str, owner: int) -> None:
    """Initializer of a local worker process: extract the FMU once, ignore Ctrl-C.

    The worker exits by itself when ``owner`` (the process running the battery)
    is gone, e.g. killed: the worker is a child of the forkserver, which would
    otherwise keep it.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_owner, args=(owner,), daemon=True).start()
    _LOCAL["fmu_path"] = fmu_path
    _LOCAL["unzip_dir"] = _extract(fmu_path)


def run_in_local_worker(task: dict) -> dict:
    """Run one task in a local worker process (the FMU extracted by its initializer)."""
    return execute_run(task, _LOCAL["fmu_path"], _LOCAL["unzip_dir"])


def local_worker_main(conn, fmu_path: str, owner: int) -> None:
    """A local worker process: extract the FMU, say ``ready``, then run the tasks it is sent.

    Each message received is a task (from :meth:`RunSpec.task`) or None (exit);
    each task is answered with its journal record.
    """
    init_local_worker(fmu_path, owner)
    conn.send(("ready", os.getpid()))
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        record = run_in_local_worker(task)
        try:
            conn.send(("done", record))
        except OSError:  # the battery's process is gone (killed, SIGTERM): no traceback
            return


def run_in_dask_worker(tasks: list[dict], fmu_bytes: bytes, digest: str) -> list[dict]:
    """A Dask task: a few runs; the FMU comes as bytes; each worker process extracts it once."""
    fmu_path, unzip_dir = cached_plant(digest, fmu_bytes=fmu_bytes)
    return [execute_run(task, fmu_path, unzip_dir) for task in tasks]
