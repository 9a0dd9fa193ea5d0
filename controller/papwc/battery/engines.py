"""Engines: a local pool of processes, or a Dask distributed cluster."""

from __future__ import annotations

import math
import os
import socket
import struct
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

from papwc.battery.worker import error_record, run_in_dask_worker
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


#: Seconds a worker may run past its run's time limit before it is killed (the run
#: itself stops at the limit, between two communication steps).
KILL_GRACE = 10.0
#: Seconds a new worker may take to start and extract the FMU.
START_TIMEOUT = 120.0


class _Worker:
    """One local worker process and its pipe."""

    def __init__(self, ctx, fmu_path: Path) -> None:
        from papwc.battery.worker import local_worker_main

        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=local_worker_main,
                                   args=(child, str(fmu_path), os.getpid()), daemon=True)
        self.process.start()
        child.close()
        self.ready = False
        self.started = time.monotonic()
        self.task: dict | None = None
        self.deadline = math.inf

    def send(self, task: dict, limit: float) -> None:
        self.task = task
        self.deadline = time.monotonic() + limit
        self.conn.send(task)

    def poll(self) -> tuple[str, object] | None:
        """A message if one has arrived, None if none, ``("died", None)`` if the pipe closed."""
        try:
            if not self.conn.poll():
                return None
            return self.conn.recv()
        except (EOFError, OSError):
            return ("died", None)

    def kill(self) -> None:
        if self.process.is_alive():
            self.process.kill()
        self.process.join(timeout=5)
        self.conn.close()

    def stop(self) -> None:
        """Ask the worker to exit (it removes its extracted FMU), kill it if it does not."""
        try:
            self.conn.send(None)
        except (OSError, ValueError):
            pass
        self.process.join(timeout=5)
        self.kill()


def run_local(tasks: list[dict], fmu_path: Path, workers: int,
              on_done: Callable[[dict], None], timeout: float | None = None) -> None:
    """Run tasks on ``workers`` local processes; call ``on_done(record)`` as each ends.

    Each worker runs one task at a time. A task carries its time limit
    (``task["timeout"]``, s; else ``timeout``): the run stops itself at the
    limit (recorded ``timed out``); a worker still busy ``KILL_GRACE`` seconds
    later is killed, its run recorded as timed out, and the worker replaced. A
    worker that dies (e.g. the FMU crashed the process) has its run recorded as
    an error and is replaced; the other runs are not affected.

    On Ctrl-C (KeyboardInterrupt) the records that have arrived are handed to
    ``on_done``, every worker is killed at once, and the interrupt propagates.
    """
    from multiprocessing.connection import wait as wait_any

    ctx = mp_context()
    pending = deque(tasks)
    pool: list[_Worker] = []

    def limit_of(task: dict) -> float:
        limit = task.get("timeout", timeout)
        return math.inf if limit is None else float(limit)

    def finish(worker: _Worker, record: dict) -> None:
        worker.task, worker.deadline = None, math.inf
        on_done(record)

    def replace(worker: _Worker) -> None:
        worker.kill()
        pool.remove(worker)
        if pending:
            pool.append(_Worker(ctx, fmu_path))

    try:
        pool.extend(_Worker(ctx, fmu_path) for _ in range(min(workers, len(pending))))
        while pool and (pending or any(w.task is not None for w in pool)):
            for worker in pool:
                if worker.ready and worker.task is None and pending:
                    task = pending.popleft()
                    worker.send(task, limit_of(task) + KILL_GRACE)
            now = time.monotonic()
            deadlines = [w.deadline for w in pool if w.task is not None]
            deadlines += [w.started + START_TIMEOUT for w in pool if not w.ready]
            wait_s = max(0.0, min(deadlines, default=math.inf) - now)
            wait_any([w.conn for w in pool] + [w.process.sentinel for w in pool],
                     timeout=None if math.isinf(wait_s) else min(wait_s, 3600.0))
            for worker in list(pool):
                message = worker.poll()
                if message is None and not worker.process.is_alive():
                    message = worker.poll() or ("died", None)
                if message is None:
                    continue
                kind, value = message
                if kind == "ready":
                    worker.ready = True
                elif kind == "done":
                    finish(worker, value)
                else:  # the process died
                    worker.process.join(timeout=5)
                    code = worker.process.exitcode
                    if worker.task is not None:
                        finish(worker, error_record(
                            worker.task, f"the worker process running it died (exit code "
                            f"{code}; e.g. the FMU crashed the process)", transient=True))
                    elif not worker.ready:
                        raise BatteryError(f"a worker process could not start (exit code "
                                           f"{code}); the FMU {fmu_path} may not load")
                    replace(worker)
            now = time.monotonic()
            for worker in list(pool):
                if worker.task is not None and now > worker.deadline:
                    task = worker.task
                    finish(worker, error_record(
                        task, f"timed out: the run took longer than {limit_of(task):g} s "
                        f"(run_timeout) and did not stop; its worker was killed and replaced",
                        transient=True))
                    replace(worker)
                elif not worker.ready and now > worker.started + START_TIMEOUT:
                    raise BatteryError(f"a worker process did not start within "
                                       f"{START_TIMEOUT:g} s")
    except KeyboardInterrupt:
        for worker in pool:
            message = worker.poll()
            if message is not None and message[0] == "done":
                finish(worker, message[1])
        for worker in pool:
            worker.kill()
        pool.clear()
        raise
    finally:
        for worker in pool:
            worker.stop()


#: Seconds a Dask scheduler has to accept the connection and greet (``--scheduler``).
CONNECT_TIMEOUT_S = 20.0
#: Largest greeting a Dask scheduler sends, bytes (its handshake takes about 60).
HANDSHAKE_MAX_BYTES = 1 << 16


def _recv_exactly(sock: socket.socket, n: int, deadline: float) -> bytes:
    """``n`` bytes from ``sock`` by ``deadline`` (``time.monotonic()``); TimeoutError if
    not, EOFError if the peer closes first."""
    data = b""
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0.0:
            raise TimeoutError
        sock.settimeout(left)
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise EOFError
        data += chunk
    return data


def check_scheduler(address: str, timeout: float | None = None) -> None:
    """Refuse (BatteryError) an address where no Dask scheduler answers within ``timeout``.

    A Dask scheduler greets every new TCP connection first with its handshake (an 8-byte
    little-endian length, then msgpack frames holding its Python version); this reads that
    greeting, at most :data:`HANDSHAKE_MAX_BYTES`, before Dask's client is let near the
    peer: a web server sends nothing (Dask's client then waited for ever), a peer that
    sends other bytes made Dask's reader allocate what their first 8 bytes say (exabytes).
    Only ``tcp://`` (and bare ``HOST:PORT``) addresses are probed; a refused connection is
    retried until ``timeout`` (s, default :data:`CONNECT_TIMEOUT_S`), as Dask does.
    """
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    try:
        import msgpack  # noqa: F401 - what a Dask greeting is read with
        from distributed.protocol.utils import unpack_frames  # noqa: F401
    except ImportError as exc:
        raise BatteryError("--scheduler needs dask[distributed]: pip install "
                           "'papwc[dask]'") from exc
    scheme, _, rest = address.rpartition("://")
    if scheme not in ("", "tcp"):
        return
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    where = f"--scheduler {address}"
    deadline = time.monotonic() + timeout
    while True:
        try:
            sock = socket.create_connection(
                (host, int(port)), timeout=max(0.1, deadline - time.monotonic()))
            break
        except OSError as exc:
            if time.monotonic() + 0.2 >= deadline:
                raise BatteryError(f"{where}: cannot connect to a Dask scheduler there within "
                                   f"{timeout:g} s: {exc.strerror or exc}") from None
            time.sleep(0.2)
    with sock:
        try:
            head = _recv_exactly(sock, 8, deadline)
            (n,) = struct.unpack("<Q", head)
            if not 0 < n <= HANDSHAKE_MAX_BYTES:
                raise ValueError(f"its first bytes are {head!r}")
            greeting = _greeting(_recv_exactly(sock, n, deadline))
        except TimeoutError:
            raise BatteryError(f"{where}: the peer accepted the connection but sent no Dask "
                               f"handshake within {timeout:g} s: not a Dask scheduler (give "
                               "the address `dask scheduler` prints)") from None
        except EOFError:
            raise BatteryError(f"{where}: the peer closed the connection without a Dask "
                               "handshake: not a Dask scheduler") from None
        except OSError as exc:
            raise BatteryError(f"{where}: the connection failed before a Dask handshake: "
                               f"{exc.strerror or exc}") from None
        except ValueError as exc:
            raise BatteryError(f"{where}: the peer does not speak Dask ({exc}); give the "
                               "address `dask scheduler` prints") from None
    if "python" not in greeting:
        raise BatteryError(f"{where}: the peer's greeting is not a Dask scheduler's "
                           f"(it holds {sorted(greeting)[:5]})")


def _greeting(data: bytes) -> dict:
    """The handshake a Dask peer sent (its frames as bytes); ValueError if it is none."""
    try:
        import msgpack
        from distributed.protocol.utils import unpack_frames

        frames, more = unpack_frames(data, partial=True)
        message = msgpack.loads(bytes(frames[0]), raw=False) if frames and not more else None
    except Exception as exc:  # noqa: BLE001 - what a foreign peer's bytes raise is open
        raise ValueError(f"its greeting does not unpack: {type(exc).__name__}") from None
    if not isinstance(message, dict):
        raise ValueError("its greeting is not a Dask handshake")
    return message


def run_dask(tasks: list[dict], fmu_path: Path, digest: str, scheduler: str,
              on_done: Callable[[dict], None]) -> None:
    """Run tasks on a Dask distributed cluster; the FMU travels as bytes, scattered once."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError as exc:
        raise BatteryError("--scheduler needs dask[distributed]: pip install "
                           "'papwc[dask]'") from exc
    try:
        client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S:g}s")
    except (OSError, TimeoutError) as exc:
        raise BatteryError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - Dask reading a foreign peer
        # (a MemoryError here is Dask's reader taking a foreign length, not this run's work)
        raise BatteryError(f"--scheduler {scheduler}: the peer is not a Dask scheduler "
                           f"(Dask's client failed: {type(exc).__name__})") from None
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
