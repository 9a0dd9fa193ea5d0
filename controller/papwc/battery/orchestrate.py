"""The whole battery: plan, journal, engine, report (:func:`run_battery`)."""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from papwc.battery.engines import default_workers, run_dask, run_local
from papwc.battery.journal import JOURNAL_FORMAT, JOURNAL_NAME, Journal
from papwc.battery.plan import plan_runs
from papwc.battery.report import write_outputs
from papwc.battery.schema import Battery
from papwc.battery.worker import error_record
from papwc.errors import BatteryError
from papwc.limits import MAX_RUNS, MAX_STEPS
from papwc.progress import PLAIN_PROGRESS_S

# --- the whole battery -----------------------------------------------------------------------


@dataclass
class BatteryOutcome:
    """What :func:`run_battery` did.

    Parameters
    ----------
    runs : int
        Runs in the batteries.
    computed : int
        Runs computed in this call (the others came from the journal).
    failed : list of (battery, run id, message)
        Runs with status error.
    files : list of Path
        Files written.
    seconds : float
        Wall time of the call.
    run_seconds : float
        Wall time of the computing (starting the workers or connecting to the
        cluster, up to the last run finished).
    records : dict
        The journal record of every run, by (battery, run id).
    """

    runs: int
    computed: int
    failed: list[tuple[str, str, str]]
    files: list[Path]
    seconds: float
    run_seconds: float = 0.0
    records: dict = field(default_factory=dict)


class BatteryInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a battery; the runs that finished are in the journal.

    Parameters
    ----------
    done, total : int
        Runs in the journal, runs of the batteries.
    journal : Path
        The journal file.
    """

    def __init__(self, done: int, total: int, journal: Path) -> None:
        super().__init__(f"{done} of {total} runs are in {journal}")
        self.done, self.total, self.journal = done, total, journal


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


#: Modules whose code computes a run in a worker (their digest keys the journal).
_RESULT_CODE = ("model", "controllers", "master", "scenario_run.py", "scenario.py",
                "results/summary.py", "results/pulses.py", "results/quantum.py",
                "battery/worker.py", "battery/plan.py", "battery/identify_first.py",
                "identify")


def code_digest() -> str:
    """The digest of the code that computes a battery run.

    Returns
    -------
    str
        SHA-256 (hex) of the papwc sources that compute a run in a worker (not the FMU's).
    """
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for name in _RESULT_CODE:
        path = root / name
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for file in files:
            h.update(file.relative_to(root).as_posix().encode() + b"\0")
            h.update(file.read_bytes() + b"\0")
    return h.hexdigest()


def result_key(fmu_guid: str) -> str:
    """The key of what determines a run's results, which keys the journal.

    Parameters
    ----------
    fmu_guid : str
        The plant FMU's GUID (a digest of its sources).

    Returns
    -------
    str
        32 hex digits of the FMU's identity, papwc's version and :func:`code_digest`.
    """
    from papwc import __version__

    text = json.dumps([fmu_guid, __version__, code_digest()])
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def run_battery(
    batteries: list[Battery],
    out: str | os.PathLike,
    fmu: str | os.PathLike,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = True,
    max_runs: int = MAX_RUNS,
    max_steps: int = MAX_STEPS,
    controller_fmu: str | os.PathLike | None = None,
) -> BatteryOutcome:
    """Run batteries and write their results into ``out``.

    Parameters
    ----------
    batteries : list of Battery
        From :func:`load_battery`; names must differ.
    out : path
        Output folder (created); holds the journal and the results.
    fmu : path
        The plant FMU (FrictionPlant.fmu).
    workers : int, optional
        Local worker processes (default: the number of cores). Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://HOST:PORT``) to run on instead.
    resume : bool
        Continue the journal in ``out``: runs it holds are not computed again.
    overwrite : bool
        Start afresh even if ``out`` holds a journal.
    progress : bool
        Show a progress bar on stderr if it is a terminal, else a line every
        :data:`PLAIN_PROGRESS_S` seconds and one when the last run is done.
    max_runs, max_steps : int
        Limits of the runs of the batteries and of the steps of one run
        (checked before any run).
    controller_fmu : path, optional
        The native PulseController.fmu whose C controller the workers run for the kinds it
        implements (a worker that cannot load it, e.g. on another machine of a Dask
        cluster, runs the Python controllers); None: the Python controllers. The results
        are the same numbers either way; its GUID is part of the journal's key (a journal
        is resumed only with the controllers it was begun with).

    Returns
    -------
    BatteryOutcome
        The runs, those computed now, those that failed, the files written, the times.

    Raises
    ------
    BatteryInterrupted
        On Ctrl-C: the runs that finished are in the journal (``--resume``).
    BatteryError
        For an FMU that cannot be used, or batteries over the limits, before any run.

    Examples
    --------
    Two draws of the plant's mass, one controller, one iteration, on the native plant FMU
    built into a temporary folder (what ``papwc battery FILE --workers 1`` does):

    >>> import csv, tempfile
    >>> from pathlib import Path
    >>> from papwc.battery.schema import parse_battery
    >>> from papwc.fmubuild.fmus import build_fmu
    >>> battery = parse_battery({
    ...     "name": "tiny", "maneuver": {"iterations": 1},
    ...     "controller": [{"kind": "exact", "label": "exact", "tolerance": 1e-7}],
    ...     "monte_carlo": {"n": 2, "seed": 1, "plant.m": {"dist": "uniform", "rel": 0.2}},
    ... }, "tiny.toml")
    >>> tmp = tempfile.TemporaryDirectory()
    >>> out = Path(tmp.name)
    >>> fmu = build_fmu("FrictionPlant", out / "fmu")
    >>> outcome = run_battery([battery], out / "tiny", fmu, workers=1, progress=False)
    >>> outcome.runs, outcome.computed, outcome.failed
    (2, 2, [])
    >>> with open(out / "tiny" / "results.csv", newline="") as f:
    ...     rows = list(csv.DictReader(f))
    >>> [row["success"] for row in rows]
    ['True', 'True']
    >>> tmp.cleanup()
    """
    start = time.perf_counter()
    start_clock = time.monotonic()
    out = Path(out)
    fmu = Path(fmu)
    if not fmu.is_file():
        raise BatteryError(f"plant FMU {str(fmu)!r} does not exist")
    from papwc.errors import FmuError
    from papwc.master.fmu import check_fmu

    try:  # refused once, before any work, if it cannot be unpacked, read or loaded
        md = check_fmu(fmu, where=f"plant FMU {str(fmu)!r}")
    except FmuError as exc:
        raise BatteryError(str(exc)) from None
    runs = plan_runs(batteries, max_runs=max_runs, max_steps=max_steps)
    for battery in batteries:
        if battery.identify_first:
            from papwc.battery.identify_first import check_excitable
            from papwc.battery.plan import get_field

            periods = {float(get_field(s.data, "maneuver.T")) for s in runs
                       if s.battery == battery.name and not s.error}
            check_excitable(battery.source, {v.name: (v.causality, v.type)
                                             for v in md.modelVariables}, periods)
    offsets = {b.seed_offset for b in batteries}
    digest = _sha256(fmu)
    identity = md.guid
    if controller_fmu is not None:  # the C controller computes too: its build keys the runs
        from papwc.errors import BuildError
        from papwc.fmubuild.model_description import read_model_description

        try:
            identity += " " + (read_model_description(Path(controller_fmu)).get("guid") or "")
        except BuildError as exc:
            raise BatteryError(f"controller FMU: {exc}") from None
    key = result_key(identity)
    fingerprint = hashlib.sha256(json.dumps(
        [key] + [[s.battery, s.run_id, s.run_hash] for s in runs]).encode()).hexdigest()
    header = {"type": "header", "format": JOURNAL_FORMAT, "key": key,
              "fingerprint": fingerprint, "fmu_guid": md.guid, "fmu_sha256": digest,
              "batteries": [[b.name, b.source] for b in batteries], "runs": len(runs),
              "seed_offset": offsets.pop() if len(offsets) == 1 else sorted(offsets)}
    journal = Journal(out / JOURNAL_NAME, header, resume, overwrite,
                      {(s.battery, s.run_id): s.run_hash for s in runs})
    for warning in journal.warnings[:20]:
        print(f"warning: {warning}", file=sys.stderr)
    if len(journal.warnings) > 20:
        print(f"warning: ... and {len(journal.warnings) - 20} more journal lines skipped",
              file=sys.stderr)
    computed = 0
    try:
        todo = [s for s in runs if (s.battery, s.run_id) not in journal.records]
        from tqdm import tqdm

        bar = tqdm(total=len(runs), initial=len(runs) - len(todo), unit="run",
                   desc="battery", file=sys.stderr, dynamic_ncols=True,
                   disable=not (progress and sys.stderr.isatty()))

        # Not a terminal (a log, a pipe): a plain line every PLAIN_PROGRESS_S seconds instead.
        plain = progress and not sys.stderr.isatty()
        told = [time.monotonic()]

        def done(record: dict) -> None:
            nonlocal computed
            journal.append(record)
            computed += 1
            bar.update(1)
            now = time.monotonic()
            if plain and (now - told[0] >= PLAIN_PROGRESS_S or computed == len(todo)):
                told[0] = now
                print(f"battery: {len(journal.records)} of {len(runs)} runs done "
                      f"({now - start_clock:.0f} s)", file=sys.stderr, flush=True)

        with bar:
            by_name = {b.name: b for b in batteries}

            def task(spec) -> dict:
                battery = by_name[spec.battery]
                out = {**spec.task(battery.source), "key": key,
                       "timeout": battery.run_timeout}
                if battery.identify_first:
                    out["identify_first"] = True
                if controller_fmu is not None:
                    out["controller_fmu"] = str(Path(controller_fmu).resolve())
                return out

            for spec in todo:
                if spec.error:
                    done(error_record(task(spec), spec.error))
            tasks = [task(s) for s in todo if not s.error]
            run_start = time.perf_counter()
            if tasks:
                if scheduler:
                    run_dask(tasks, fmu, digest, scheduler, done)
                else:
                    n = workers or default_workers()
                    run_local(tasks, fmu, max(1, min(n, len(tasks))), done)
            run_seconds = time.perf_counter() - run_start
        records = journal.records
    except KeyboardInterrupt:
        journal.release()
        raise BatteryInterrupted(len(journal.records), len(runs), journal.path) from None
    except BaseException:
        journal.release()
        raise
    finally:
        journal.close(release=False)  # the folder stays locked while the results are written
    try:
        files = write_outputs(out, batteries, runs, records, digest)
    finally:
        journal.release()
    failed = [(s.battery, s.run_id, records[(s.battery, s.run_id)]["message"]) for s in runs
              if records[(s.battery, s.run_id)]["status"] != "ok"]
    return BatteryOutcome(len(runs), computed, failed, files, time.perf_counter() - start,
                          run_seconds, records)
