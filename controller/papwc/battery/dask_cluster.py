"""A Dask cluster of local processes (``dask scheduler``, ``dask worker``): tests, benchmarks."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from papwc.errors import BatteryError

# --- a Dask cluster of local processes (tests, benchmarks) -----------------------------------


def _stop(proc: subprocess.Popen) -> None:
    """Stop a process started in its own session, and its children."""
    if proc.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)


@contextlib.contextmanager
def local_dask_cluster(n_workers: int = 1, nthreads: int = 1,
                       timeout: float = 60.0) -> Iterator[str]:
    """Start ``dask scheduler`` and ``dask worker`` (the CLI) on 127.0.0.1; yield the address.

    The scheduler picks a free port and writes it to a scheduler file; the
    worker runs ``n_workers`` processes of ``nthreads`` threads, no dashboards.
    Both are stopped (their process groups) when the block ends.
    """
    dask_cli = Path(sys.executable).with_name("dask")
    cmd = [str(dask_cli)] if dask_cli.is_file() else [sys.executable, "-m", "dask"]
    with tempfile.TemporaryDirectory(prefix="papwcdask") as tmp:
        sched_file = Path(tmp) / "scheduler.json"
        procs: list[subprocess.Popen] = []
        logs = [open(Path(tmp) / name, "wb")
                for name in ("scheduler.log", "worker.log")]
        try:
            procs.append(subprocess.Popen(
                cmd + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                       "--scheduler-file", str(sched_file)],
                stdout=logs[0], stderr=subprocess.STDOUT, start_new_session=True, cwd=tmp))
            deadline = time.monotonic() + timeout
            address = None
            while address is None:
                if procs[0].poll() is not None or time.monotonic() > deadline:
                    raise BatteryError("dask scheduler did not start: "
                                       + (Path(tmp) / "scheduler.log").read_text()[-2000:])
                with contextlib.suppress(FileNotFoundError, ValueError):
                    address = json.loads(sched_file.read_text())["address"]
                time.sleep(0.05)
            procs.append(subprocess.Popen(
                cmd + ["worker", address, "--host", "127.0.0.1", "--no-dashboard",
                       "--nworkers", str(n_workers), "--nthreads", str(nthreads),
                       "--local-directory", tmp],
                stdout=logs[1], stderr=subprocess.STDOUT, start_new_session=True, cwd=tmp))
            from dask.distributed import Client

            with Client(address, timeout="20s") as client:
                try:
                    client.wait_for_workers(n_workers, timeout=timeout)
                except TimeoutError as exc:
                    raise BatteryError("dask worker did not connect: " + (
                        Path(tmp) / "worker.log").read_text()[-2000:]) from exc
            yield address
        finally:
            for proc in reversed(procs):
                _stop(proc)
            for f in logs:
                f.close()
