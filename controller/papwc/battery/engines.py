"""Engines: a local pool of processes, or a Dask distributed cluster."""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from papwc.battery.worker import (
    error_record,
    init_local_worker,
    run_in_dask_worker,
    run_in_local_worker,
)
from papwc.errors import BatteryError

# --- engines ----------------------------------------------------------------------------------


def default_workers() -> int:
    """Number of cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def mp_context():
    """The multiprocessing context of the workers: forkserver where there is one, else spawn."""
    import multiprocessing

    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def run_local(tasks: list[dict], fmu_path: Path, workers: int,
               on_done: Callable[[dict], None]) -> None:
    """Run tasks in a pool of ``workers`` processes; call ``on_done(record)`` as each ends.

    At most two tasks per worker are queued at a time. If a worker process dies
    (e.g. the FMU crashed it), the tasks that were queued are run again one per
    fresh single-process pool, so the one that kills its worker is recorded as an
    error and the others are not affected.
    """
    pending = list(reversed(tasks))
    suspects: list[dict] = []

    def pool(n: int) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=n, mp_context=mp_context(),
                                   initializer=init_local_worker,
                                   initargs=(str(fmu_path), os.getpid()))

    while pending:
        executor = pool(workers)
        in_flight: dict = {}
        broken = False
        try:
            while (pending or in_flight) and not broken:
                while pending and len(in_flight) < 2 * workers:
                    task = pending.pop()
                    in_flight[executor.submit(run_in_local_worker, task)] = task
                done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                for fut in done:
                    task = in_flight.pop(fut)
                    try:
                        on_done(fut.result())
                    except BrokenProcessPool:
                        suspects.append(task)
                        broken = True
            suspects.extend(in_flight.values())
        finally:
            executor.shutdown(wait=True, cancel_futures=True)
        for task in suspects:
            with pool(1) as single:
                try:
                    on_done(single.submit(run_in_local_worker, task).result())
                except BrokenProcessPool:
                    on_done(error_record(task, "the worker process running it died "
                                        "(e.g. the FMU crashed the process)"))
        suspects = []


def run_dask(tasks: list[dict], fmu_path: Path, digest: str, scheduler: str,
              on_done: Callable[[dict], None]) -> None:
    """Run tasks on a Dask distributed cluster; the FMU travels as bytes, scattered once."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError as exc:
        raise BatteryError("--scheduler needs dask[distributed]: pip install "
                           "'papwc[dask]'") from exc
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise BatteryError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from exc
    try:
        try:
            client.wait_for_workers(1, timeout=60)
        except TimeoutError as exc:
            raise BatteryError(f"the Dask scheduler at {scheduler} has no worker "
                               "(waited 60 s)") from exc
        fmu_future = client.scatter(fmu_path.read_bytes(), broadcast=True, hash=False)
        # Runs take tens of milliseconds; a few per task keep the scheduler's per-task
        # cost small while every worker still gets several tasks (and each finished
        # task's runs are persisted as soon as it ends).
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        size = max(1, min(8, len(tasks) // (8 * n_workers)))
        futures = {}
        for i in range(0, len(tasks), size):
            chunk = tasks[i : i + size]
            first = chunk[0]
            key = (f"papwc-battery-{first['battery']}-{first['run_id']}-{first['run_hash']}"
                   f"-{len(chunk)}")
            fut = client.submit(run_in_dask_worker, chunk, fmu_future, digest, key=key,
                                pure=False)
            futures[fut] = chunk
        try:
            for fut in as_completed(futures):
                chunk = futures[fut]
                if fut.status == "finished":
                    for record in fut.result():
                        on_done(record)
                else:
                    exc = fut.exception()
                    for task in chunk:
                        on_done(error_record(task, f"Dask task failed: {type(exc).__name__}: "
                                            f"{exc}"))
                fut.release()
        finally:
            client.cancel(list(futures))
    finally:
        client.close()
