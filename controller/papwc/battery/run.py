"""The whole battery: plan, journal, engine, report (:func:`run_battery`)."""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from papwc.battery.engines import default_workers, run_dask, run_local
from papwc.battery.journal import JOURNAL_FORMAT, JOURNAL_NAME, Journal
from papwc.battery.plan import plan_runs
from papwc.battery.report import write_outputs
from papwc.battery.schema import Battery
from papwc.battery.worker import error_record
from papwc.errors import BatteryError

# --- the whole battery -----------------------------------------------------------------------


@dataclass
class BatteryOutcome:
    """What :func:`run_battery` did.

    Attributes
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
    """

    runs: int
    computed: int
    failed: list[tuple[str, str, str]]
    files: list[Path]
    seconds: float
    run_seconds: float = 0.0


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def run_battery(
    batteries: list[Battery],
    out: str | os.PathLike,
    fmu: str | os.PathLike,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = True,
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
        Show a progress bar on stderr (only if stderr is a terminal).

    Returns
    -------
    BatteryOutcome
    """
    start = time.perf_counter()
    out = Path(out)
    fmu = Path(fmu)
    if not fmu.is_file():
        raise BatteryError(f"plant FMU {str(fmu)!r} does not exist")
    from fmpy import read_model_description

    try:
        cosim = read_model_description(str(fmu)).coSimulation
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain Exceptions for broken files
        raise BatteryError(f"{fmu}: not a readable FMU: {exc}") from exc
    if cosim is None:
        raise BatteryError(f"{fmu}: not a Co-Simulation FMU")
    runs = plan_runs(batteries)
    digest = _sha256(fmu)
    fingerprint = hashlib.sha256(json.dumps(
        [digest] + [[s.battery, s.run_id, s.run_hash] for s in runs]).encode()).hexdigest()
    header = {"type": "header", "format": JOURNAL_FORMAT, "fingerprint": fingerprint,
              "fmu_sha256": digest, "batteries": [[b.name, b.source] for b in batteries],
              "runs": len(runs)}
    journal = Journal(out / JOURNAL_NAME, header, resume, overwrite)
    computed = 0
    try:
        todo = [s for s in runs if (s.battery, s.run_id) not in journal.records]
        from tqdm import tqdm

        bar = tqdm(total=len(runs), initial=len(runs) - len(todo), unit="run",
                   desc="battery", file=sys.stderr, dynamic_ncols=True,
                   disable=not (progress and sys.stderr.isatty()))

        def done(record: dict) -> None:
            nonlocal computed
            journal.append(record)
            computed += 1
            bar.update(1)

        with bar:
            sources = {b.name: b.source for b in batteries}
            for spec in todo:
                if spec.error:
                    done(error_record(spec.task(sources[spec.battery]), spec.error))
            tasks = [s.task(sources[s.battery]) for s in todo if not s.error]
            run_start = time.perf_counter()
            if tasks:
                if scheduler:
                    run_dask(tasks, fmu, digest, scheduler, done)
                else:
                    n = workers or default_workers()
                    run_local(tasks, fmu, max(1, min(n, len(tasks))), done)
            run_seconds = time.perf_counter() - run_start
        records = journal.records
    finally:
        journal.close()
    files = write_outputs(out, batteries, runs, records, digest)
    failed = [(s.battery, s.run_id, records[(s.battery, s.run_id)]["message"]) for s in runs
              if records[(s.battery, s.run_id)]["status"] != "ok"]
    return BatteryOutcome(len(runs), computed, failed, files, time.perf_counter() - start,
                          run_seconds)
