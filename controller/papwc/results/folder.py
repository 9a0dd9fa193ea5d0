"""The output folder of ``papwc run``, written as results come.

Results are on disk as soon as they exist: :class:`ResultsFolder` writes each
controller's traces, then its rows of ``summary.csv`` (and of ``pulses.csv``:
every pulse with its no-runaway bound), as the controller finishes (every file
atomically), and the plots at the end. While a run is under way, and after one
that was interrupted or failed, the folder holds a file ``INCOMPLETE`` that
says what is missing; it is removed once everything is written. A controller that
Ctrl-C or SIGTERM stops keeps the traces it computed (:meth:`ResultsFolder.add_cut`),
the last one cut short, as ``INCOMPLETE`` says (it has no summary rows). A new run into
a used folder first removes the files an earlier run wrote there
(``summary.csv``, ``pulses.csv``, ``trace_*_it*.csv``, the plots,
``INCOMPLETE``), nothing else.
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

from papwc.interrupts import Terminated
from papwc.master import RunResult
from papwc.output_files import (
    lock_folder,
    make_folder,
    refuse_link,
    remove_file,
    write_rows,
    write_text,
)
from papwc.results.pulses import ROW_COLUMNS, PulseBound
from papwc.results.summary import summarize
from papwc.scenario import Scenario

SUMMARY_COLUMNS = [
    "controller", "kind", "t_p_max", "iteration", "final_error_m", "pulses", "settle_time_s",
    "limit_cycle", "cycle_p2p_m", "b_hat", "f_c_hat", "outcome", "outcome_reason", "status",
    "message",
]  # fmt: skip
#: Columns of ``pulses.csv``: the controller, the iteration and
#: :data:`papwc.results.pulses.ROW_COLUMNS`.
PULSE_COLUMNS = ["controller", "iteration", *ROW_COLUMNS]

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

    The bound is that of :mod:`papwc.results.pulses` on the scenario's plant.
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

    The folder is locked (:func:`papwc.output_files.lock_folder`) from :meth:`start`
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
        #: The controller a stop cut short and its traces on disk (:meth:`add_cut`).
        self._cut: tuple[str, list[str]] | None = None

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
            from papwc.output_files import os_error_text

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
        part = next((p[0] for p in (self._partial, self._cut) if p is not None and p[1]), None)
        return ([f"controller {label} (" + ("the rest of its files" if label == part else
                                            f"traces and {self._rows_written}") + ")"
                 for label in self.labels if label not in done]
                + [f"plot {name}" for name in RUN_PLOTS])

    def _mark(self, reason: str) -> None:
        done = [f"controller {r.label}: {len(r.traces)} trace(s) and {self._rows_written}"
                for r in self.results]
        for partial in (self._partial, self._cut):
            if partial is not None and partial[1]:
                label, parts = partial
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

    def add_cut(self, result: RunResult) -> None:
        """Write the traces of a controller that Ctrl-C or SIGTERM stopped (the last cut
        short: ``result.error`` says where); ``INCOMPLETE`` names them. No summary rows: the
        controller did not finish. Never raises (the run is being stopped)."""
        parts: list[str] = []
        self._cut = (result.label, parts)
        try:
            for tr in result.traces:
                name = trace_name(result.label, tr.iteration)
                tr.to_csv(self.out / name)
                self.written.append(name)
                parts.append(f"{name} ({tr.error})" if tr.error else name)
        except (OSError, KeyboardInterrupt):  # a second Ctrl-C, a full disk: keep what is
            pass

    def finish(self, plots: bool = True) -> list[dict]:
        """Write the plots and remove ``INCOMPLETE``; return the summary rows."""
        if plots:
            from papwc.results import plots as run_plots

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
        cut = (f"; the traces of {self._cut[0]} until the stop are kept" if self._cut is not None
               and self._cut[1] else "")
        return (f"kept in {self.out}: "
                + (f"the results of {', '.join(kept)}" if kept else "no finished controller")
                + partial
                + (f"; missing: {', '.join(missing)}" if missing else "")
                + cut
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

