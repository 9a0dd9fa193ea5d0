"""Run a scenario's controllers against the plant and write what ``papwc run`` writes.

Results are on disk as soon as they exist: :class:`ResultsFolder` writes each
controller's traces, then its rows of ``summary.csv`` (and of ``pulses.csv``:
every pulse with its no-runaway bound), as the controller finishes (every file
atomically), and the plots at the end. While a run is under way, and after one
that was interrupted or failed, the folder holds a file ``INCOMPLETE`` that
says what is missing; it is removed once everything is written. A new run into
a used folder first removes the files an earlier run wrote there
(``summary.csv``, ``pulses.csv``, ``trace_*_it*.csv``, the plots,
``INCOMPLETE``), nothing else.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path

from papwc.errors import FmuError
from papwc.master import FmuSlave, PhysicsSlave, RunResult, Slave, run_controller, summarize
from papwc.master.pulses import ROW_COLUMNS, PulseBound
from papwc.output import (
    lock_folder,
    make_folder,
    refuse_link,
    remove_file,
    write_rows,
    write_text,
)
from papwc.scenario import Scenario

SUMMARY_COLUMNS = [
    "controller", "kind", "t_p_max", "iteration", "final_error_m", "pulses", "settle_time_s",
    "limit_cycle", "cycle_p2p_m", "b_hat", "f_c_hat", "outcome", "outcome_reason", "status",
    "message",
]  # fmt: skip
#: Columns of ``pulses.csv``: the controller, the iteration and
#: :data:`papwc.master.pulses.ROW_COLUMNS`.
PULSE_COLUMNS = ["controller", "iteration", *ROW_COLUMNS]

def ensure_plant_fmu(fmu: str | os.PathLike | None, out: str | os.PathLike) -> Path:
    """The plant FMU to use: ``fmu`` if given, else one built from the current sources.

    Without ``fmu``: the checkout's build/FrictionPlant.fmu when it is current,
    else ``out/fmu/FrictionPlant.fmu`` (built there if missing or stale).
    """
    if fmu is not None:
        path = Path(fmu)
        if not path.is_file():
            what = "is not a file" if path.exists() else "does not exist"
            raise FmuError(f"plant FMU {str(path)!r} {what}")
        from papwc.master.fmu import check_fmu

        check_fmu(path, where=f"plant FMU {str(path)!r}")
        return path
    from papwc.fmubuild.fmus import current_fmu

    refuse_link(Path(out) / "fmu")  # a folder the command fills is not followed
    return current_fmu("FrictionPlant", Path(out) / "fmu")


class RunTimeout(Exception):
    """A run went past its time limit (raised between two communication steps)."""


#: Communication steps between two looks at the clock of a run with a time limit.
_CLOCK_EVERY = 256
#: Set by Ctrl-C or SIGTERM (to the signal's number) while :func:`deferred_interrupt` is
#: active.
_INTERRUPT: dict[str, int] = {"requested": 0}


class Terminated(KeyboardInterrupt):
    """SIGTERM stopped the command (handled as Ctrl-C is: what was computed is kept)."""

    def __init__(self) -> None:
        super().__init__("terminated (SIGTERM)")


def interruption(signum: int | None = None) -> KeyboardInterrupt:
    """The exception of a deferred Ctrl-C (KeyboardInterrupt) or SIGTERM (:class:`Terminated`)."""
    signum = _INTERRUPT["requested"] if signum is None else signum
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def interrupt_requested() -> bool:
    """Whether a Ctrl-C or SIGTERM waits to be raised (see :func:`deferred_interrupt`)."""
    return bool(_INTERRUPT["requested"])


@contextlib.contextmanager
def deferred_interrupt() -> Iterator[None]:
    """Ctrl-C or SIGTERM raise between two communication steps, not inside an FMU.

    An FMU made with pythonfmu runs its Python code in this interpreter: a
    KeyboardInterrupt raised there becomes fmi2Fatal (the instance is lost and
    the run goes on with the next controller). Within this block the first
    Ctrl-C or SIGTERM only sets a flag, which the plant's step checks (see
    :func:`run_scenario`; ``papwc cosim`` checks it after every row); a second
    one raises at once. SIGTERM raises :class:`Terminated`, a KeyboardInterrupt.
    Outside the main thread, or where Ctrl-C is ignored (battery workers),
    nothing changes; SIGTERM is deferred only where it has its default action.
    """
    if threading.current_thread() is not threading.main_thread() or (
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return

    def handler(signum, frame) -> None:
        if _INTERRUPT["requested"]:
            raise interruption(signum)
        _INTERRUPT["requested"] = signum

    _INTERRUPT["requested"] = 0
    term = signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    signal.signal(signal.SIGINT, handler)
    if term:
        signal.signal(signal.SIGTERM, handler)
    try:
        yield
        if _INTERRUPT["requested"]:
            raise interruption()
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        if term:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _INTERRUPT["requested"] = 0


def _guard_steps(slave, deadline: float | None, limit: float | None):
    """Make ``slave.do_step`` raise after a deferred Ctrl-C, and past ``deadline``.

    Raises KeyboardInterrupt (Ctrl-C, checked every step) or :class:`RunTimeout`
    (``time.monotonic() > deadline``, checked every ``_CLOCK_EVERY`` steps),
    always between two steps.
    """
    do_step = slave.do_step
    count = [0]
    interrupt = _INTERRUPT

    def checked_step(t: float, h: float) -> None:
        do_step(t, h)
        if interrupt["requested"]:
            raise interruption()
        if deadline is not None:
            count[0] += 1
            if count[0] % _CLOCK_EVERY == 0 and time.monotonic() > deadline:
                raise RunTimeout(f"timed out: the run took longer than {limit:g} s "
                                 f"(stopped at t = {t + h!r} s)")

    slave.do_step = checked_step
    return slave


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
                 unzip_dir: str | os.PathLike | None = None,
                 timeout: float | None = None) -> list[RunResult]:
    """Run every controller of the scenario (each with a fresh plant instance).

    ``fmu`` is the plant FMU's path when ``plant`` is ``"fmu"`` (and
    ``unzip_dir`` an extracted copy of it, if there is one); ``progress`` is
    called with each controller's result as it finishes. With ``timeout`` (s),
    :class:`RunTimeout` is raised once the whole run has taken longer. Ctrl-C
    raises KeyboardInterrupt between two steps (:func:`deferred_interrupt`).
    """
    results = []
    deadline = None if timeout is None else time.monotonic() + timeout
    with deferred_interrupt():
        for settings, label in zip(scenario.controllers, scenario.labels, strict=True):
            slave = make_plant(scenario, plant, fmu, unzip_dir)
            _guard_steps(slave, deadline, timeout)
            try:
                results.append(run_controller(slave, settings, scenario.maneuver, label))
            finally:
                slave.close()
            if progress is not None:
                progress(results[-1])
    return results


def summary_rows(results: list[RunResult], warnings: Mapping[str, str] | None = None
                 ) -> list[dict]:
    """One row per controller and iteration (columns SUMMARY_COLUMNS).

    ``warnings`` (label -> text) go into the ``message`` of a controller's rows
    with status ok.
    """
    warnings = warnings or {}
    rows = []
    for r in results:
        for tr in r.traces:
            m = summarize(tr, r.settings.tolerance)
            rows.append({
                "controller": r.label, "kind": r.settings.kind, "t_p_max": r.settings.t_p_max,
                "iteration": tr.iteration, **m,
                "status": "error" if tr.error else "ok",
                "message": tr.error or warnings.get(r.label, ""),
            })
        if r.error and (not r.traces or not r.traces[-1].error):
            rows.append({"controller": r.label, "kind": r.settings.kind,
                         "t_p_max": r.settings.t_p_max, "iteration": len(r.traces) + 1,
                         "status": "error", "message": r.error})
    return rows


#: Name of the file that marks an output folder whose results are not all written.
INCOMPLETE = "INCOMPLETE"
#: Plots of ``papwc run``.
RUN_PLOTS = ("error.png", "force.png", "estimates.png")
#: Trace files of ``papwc run``.
_TRACE_FILE = re.compile(r"trace_.+_it[0-9]+\.csv(\.tmp)?")


def pulse_rows(result: RunResult, scenario: Scenario) -> list[dict]:
    """Rows of ``pulses.csv`` for one controller: every pulse of every iteration, its bound.

    The bound is that of :mod:`papwc.master.pulses` on the scenario's plant.
    """
    bound = PulseBound(scenario.plant, scenario.maneuver.T)
    return [{"controller": result.label, "iteration": trace.iteration, **row}
            for trace in result.traces for row in bound.rows(trace)]


def trace_name(label: str, iteration: int) -> str:
    """File name of a controller's trace of one iteration."""
    return f"trace_{label}_it{iteration}.csv"


class ResultsFolder:
    """What ``papwc run`` writes into its output folder, written as results come.

    Parameters
    ----------
    out : path
        The output folder (created).
    labels : iterable of str
        The controllers the run will add, in order.
    warnings : mapping, optional
        Label -> warning text, recorded in the ``message`` of ok rows.
    what : str
        What writes (``"papwc run"``), for the ``INCOMPLETE`` file.
    scenario : Scenario, optional
        The scenario run (one plant for every controller): given, ``pulses.csv``
        lists every pulse with its bound (no runaway) on that plant.
    own : bool
        The folder is one the command fills inside its output folder (``runs/``
        of ``papwc reproduce``): a symbolic link there is refused, not followed.

    The folder is locked (:func:`papwc.output.lock_folder`) from :meth:`start`
    to :meth:`finish` or :meth:`abort`: a second command writing into it is
    refused.
    """

    def __init__(self, out: str | os.PathLike, labels: Iterable[str],
                 warnings: Mapping[str, str] | None = None, what: str = "papwc run",
                 scenario: Scenario | None = None, own: bool = False) -> None:
        self.own = own
        self._lock = None
        self.out = Path(out)
        self.labels = list(labels)
        self.warnings = dict(warnings or {})
        self.what = what
        self.scenario = scenario
        self.results: list[RunResult] = []
        self.rows: list[dict] = []
        self.pulse_rows: list[dict] = []
        self.written: list[str] = []
        #: The controller being written and what of it is on disk (until it all is).
        self._partial: tuple[str, list[str]] | None = None

    def start(self) -> None:
        """Create and lock the folder, remove what an earlier run wrote there, mark it
        incomplete; a symbolic link in place of one of those files is refused."""
        make_folder(self.out, own=self.own)
        self._lock = lock_folder(self.out, self.what)
        try:
            self._clean()
        except BaseException:
            self.release()
            raise
        self._mark(f"{self.what} started at {time.strftime('%Y-%m-%d %H:%M:%S')} and has not "
                   "finished (or was stopped)")

    def release(self) -> None:
        """Release the folder's lock (idempotent)."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def _clean(self) -> None:
        try:
            entries = list(self.out.iterdir())
        except OSError as exc:
            from papwc.errors import OutputError
            from papwc.output import os_error_text

            raise OutputError(f"cannot list folder {str(self.out)!r}: "
                              f"{os_error_text(exc)}") from exc
        own = {"summary.csv", "summary.csv.tmp", "pulses.csv", "pulses.csv.tmp", INCOMPLETE,
               INCOMPLETE + ".tmp", *RUN_PLOTS,
               *(Path(p).stem + ".tmp.png" for p in RUN_PLOTS)}
        for entry in entries:
            if entry.name in own or _TRACE_FILE.fullmatch(entry.name):
                refuse_link(entry)
                if not entry.is_dir():
                    remove_file(entry)

    @property
    def _rows_written(self) -> str:
        """What a finished controller has in the CSV files besides its traces."""
        return "summary and pulses rows" if self.scenario is not None else "summary rows"

    def _missing(self) -> list[str]:
        done = {r.label for r in self.results}
        part = self._partial[0] if self._partial is not None and self._partial[1] else None
        return ([f"controller {label} (" + ("the rest of its files" if label == part else
                                            f"traces and {self._rows_written}") + ")"
                 for label in self.labels if label not in done]
                + [f"plot {name}" for name in RUN_PLOTS])

    def _mark(self, reason: str) -> None:
        done = [f"controller {r.label}: {len(r.traces)} trace(s) and {self._rows_written}"
                for r in self.results]
        if self._partial is not None and self._partial[1]:
            label, parts = self._partial
            done.append(f"controller {label} in part: {', '.join(parts)}")
        text = [f"This folder is incomplete: {reason}.", ""]
        text += ["Written:"] + [f"- {d}" for d in done] if done else ["Written: nothing yet."]
        text += ["", "Missing:"] + [f"- {m}" for m in self._missing()] + [""]
        write_text(self.out / INCOMPLETE, "\n".join(text))

    def add(self, result: RunResult) -> None:
        """Write one finished controller: its traces, then summary.csv (and pulses.csv) rows."""
        parts: list[str] = []
        self._partial = (result.label, parts)
        for tr in result.traces:
            name = trace_name(result.label, tr.iteration)
            tr.to_csv(self.out / name)
            self.written.append(name)
            parts.append(name)
        self.rows += summary_rows([result], self.warnings)
        write_rows(self.out / "summary.csv", self.rows, SUMMARY_COLUMNS)
        parts.append("its rows of summary.csv")
        if "summary.csv" not in self.written:
            self.written.append("summary.csv")
        if self.scenario is not None:
            self.pulse_rows += pulse_rows(result, self.scenario)
            write_rows(self.out / "pulses.csv", self.pulse_rows, PULSE_COLUMNS)
            if "pulses.csv" not in self.written:
                self.written.append("pulses.csv")
        # counted as written (INCOMPLETE, the line after a stop) once all of it is
        self._partial = None
        self.results.append(result)
        self._mark(f"{self.what} is under way or was stopped")

    def finish(self, plots: bool = True) -> list[dict]:
        """Write the plots and remove ``INCOMPLETE``; return the summary rows."""
        if plots:
            from papwc.analysis import plots as run_plots

            run_plots.run_plots(self.results, self.out)
            self.written += list(RUN_PLOTS)
        remove_file(self.out / INCOMPLETE)
        self.release()
        return self.rows

    def abort(self, reason: str) -> str:
        """Mark the folder incomplete with ``reason``; return a line saying what was kept.

        Never raises (the folder may be the reason).
        """
        try:
            self._mark(reason)
            marked = f"; see {self.out / INCOMPLETE}"
        except OSError:
            marked = ""
        finally:
            self.release()
        kept = [r.label for r in self.results]
        missing = [label for label in self.labels if label not in kept]
        partial = (f" ({self._partial[0]} in part)" if self._partial is not None
                   and self._partial[1] else "")
        return (f"kept in {self.out}: "
                + (f"the results of {', '.join(kept)}" if kept else "no finished controller")
                + partial
                + (f"; missing: {', '.join(missing)}" if missing else "")
                + f"; the plots were not written{marked}")


def run_into_folder(folder: ResultsFolder, run: Callable[[Callable[[RunResult], None]], list],
                    ) -> list[RunResult]:
    """Call ``run(progress)`` with ``folder.add`` as progress; mark the folder if it stops.

    On Ctrl-C or an exception the folder is marked incomplete (what was kept,
    what is missing), the line saying so is printed on stderr, and the
    exception propagates.
    """
    import sys

    try:
        return run(folder.add)
    except Terminated:
        print(f"{folder.what}: terminated; " + folder.abort("terminated (SIGTERM)"),
              file=sys.stderr)
        raise
    except KeyboardInterrupt:
        print(f"{folder.what}: interrupted; " + folder.abort("interrupted (Ctrl-C)"),
              file=sys.stderr)
        raise
    except BaseException as exc:
        print(f"{folder.what}: stopped; " + folder.abort(f"stopped by an error: {exc}"),
              file=sys.stderr)
        raise


def write_results(results: list[RunResult], out: Path,
                  warnings: Mapping[str, str] | None = None) -> list[dict]:
    """Write summary.csv, trace_<controller>_it<N>.csv and the plots into ``out`` at once."""
    folder = ResultsFolder(out, [r.label for r in results], warnings)
    folder.start()
    for r in results:
        folder.add(r)
    return folder.finish()


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
