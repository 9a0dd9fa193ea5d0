"""The measured log: a CSV file of time, force and table position, read and checked.

A log has one row per sample: the time ``t_k`` (s), the force ``u_k`` (N) held from
``t_k`` to ``t_{k+1}`` (zero-order hold) and the table position ``x_k`` (m) read at
``t_k``; optionally the motor position (m). Units are SI; the column names are options
(:class:`Columns`; the position is the plant's ``x_meas``, else ``x``). The header names
each column once, and every row has one field per column. The samples are evenly spaced:
every time step must equal the median step within :data:`TIME_TOLERANCE` (relative); the
sample period ``h`` is then ``(t_last - t_first)/(rows - 1)``, and must be one of a
machine's log (:data:`papwc.model.maneuver.LOG_SAMPLE_PERIOD`).

Every value is a finite number within the model layer's range of its kind
(:func:`column_ranges`): a force within the largest any controller applies (``f_p_max``),
a position within the plant's (``x0``), a time within the longest maneuver (``duration``).

Every problem is one line naming the file, the row (data rows count from 1; the line of
the file is row + 1), the column, the value and what is allowed (:class:`LogError`).
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from papwc.identify import IdentifyError
from papwc.limits import read_input_text

__all__ = [
    "MAX_LOG_ROWS",
    "MIN_LOG_ROWS",
    "TIME_TOLERANCE",
    "Columns",
    "Log",
    "LogError",
    "check_travel",
    "column_ranges",
    "parse_log",
    "read_log",
]

#: Most data rows of a log: a 1000 s log at 100 Hz (100,000 steps, so 100,001 samples),
#: the longest ``papwc identify --fmu`` writes (``--duration 1000``).
MAX_LOG_ROWS = 100_001
#: Fewest rows that can hold a move: a rest (3 samples), the breakaway, 3 samples of
#: sliding, the stop and a rest (2 samples).
MIN_LOG_ROWS = 10
#: Largest relative difference of a time step from the sample period.
TIME_TOLERANCE = 1e-6


class LogError(IdentifyError):
    """A log cannot be identified: the message names the file, row, column and the problem."""


#: The position column read when none is named: the plant's measured output, else ``x``.
POSITION_COLUMNS = ("x_meas", "x")


@dataclass(frozen=True)
class Columns:
    """Names of the log's columns (the motor position is optional: None; the position
    None: the first of :data:`POSITION_COLUMNS` the header has)."""

    time: str = "time"
    force: str = "u"
    position: str | None = None
    motor: str | None = None

    def resolved(self, header: list[str]) -> Columns:
        """These columns with the position named (the default one ``header`` has)."""
        if self.position is not None:
            return self
        found = next((name for name in POSITION_COLUMNS if name in header), POSITION_COLUMNS[0])
        return replace(self, position=found)

    def needed(self) -> list[tuple[str, str]]:
        """(what, column name) of every column to read."""
        out = [("time", self.time), ("force", self.force),
               ("position", self.position or POSITION_COLUMNS[0])]
        if self.motor is not None:
            out.append(("motor position", self.motor))
        return out


@dataclass
class Log:
    """A checked log.

    Attributes
    ----------
    t : ndarray
        Times, s (evenly spaced, increasing).
    u : ndarray
        Force held over each sample, N (the last one acts on nothing).
    x : ndarray
        Table position at each sample, m.
    x_d : ndarray or None
        Motor position, m.
    h : float
        Sample period, s.
    source : str
        The file (or what made the log), for messages.
    columns : Columns
        The names of the columns read.
    """

    t: np.ndarray
    u: np.ndarray
    x: np.ndarray
    x_d: np.ndarray | None
    h: float
    source: str
    columns: Columns

    def where(self, k: int, column: str) -> str:
        """``"<source>, row <k+1> (line <k+2>), column '<column>'"`` for sample index ``k``."""
        return f"{self.source}, row {k + 1} (line {k + 2}), column {column!r}"


def read_log(path: str | os.PathLike, columns: Columns = Columns()) -> Log:
    """Read and check the log CSV at ``path``.

    Parameters
    ----------
    path : path
        The log: CSV with a header; time (s), force (N, held from its row to the next),
        table position (m), optionally the motor position; UTF-8, at most 16 MB.
    columns : Columns
        The names of the columns to read (default ``time``, ``u``, ``x``).

    Returns
    -------
    Log
        The checked samples.

    Raises
    ------
    LogError
        Naming the file, the row and the column: missing, unreadable, not UTF-8 text, a
        column missing, a value not a number or not finite, time not increasing or not
        even, too few or too many rows.
    """
    path = Path(path)
    text = read_input_text(path, "log", "CSV", LogError,
                           too_large=f"a log has at most {MAX_LOG_ROWS} rows")
    return parse_log(text, str(path), columns)


def column_ranges() -> dict[str, tuple[float, float, str]]:
    """What a value of each kind of column may be: kind -> (lowest, highest, what), read
    from the model layer (the force: a controller's force limit ``f_p_max``; a position:
    the plant's ``x0``; a time: the longest maneuver ``duration``)."""
    from papwc.model.controller_settings import CONTROLLER_SETTINGS
    from papwc.model.maneuver import MANEUVER_VARIABLES
    from papwc.model.plant import PLANT_PARAMETERS
    from papwc.model.variables import by_name

    force = by_name(CONTROLLER_SETTINGS)["f_p_max"].max
    x0 = by_name(PLANT_PARAMETERS)["x0"]
    duration = by_name(MANEUVER_VARIABLES)["duration"].max
    position = (x0.min, x0.max, f"a position of the plant (its x0), {x0.min:g}..{x0.max:g} m")
    return {"time": (-duration, duration, f"a time within {-duration:g}..{duration:g} s "
                                          "(the longest maneuver); start the time near 0"),
            "force": (-force, force, f"a force within {-force:g}..{force:g} N (the largest "
                                     "force limit f_p_max of a controller)"),
            "position": position, "motor position": position}


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise LogError(f"{where}: {text!r} is not a number") from None
    if math.isnan(value):
        raise LogError(f"{where}: {text!r} is NaN; every value must be a finite number")
    if not math.isfinite(value):
        raise LogError(f"{where}: {text!r} is not finite; every value must be a finite number")
    return value


def parse_log(text: str, source: str, columns: Columns = Columns()) -> Log:
    """Check the CSV text of a log; see :func:`read_log`.

    Parameters
    ----------
    text : str
        The CSV text.
    source : str
        What names the log in messages (its file).
    columns : Columns
        The names of the columns to read.

    Returns
    -------
    Log
        The checked samples.

    Raises
    ------
    LogError
        Naming ``source``, the row (line = row + 1) and the column of what is wrong.

    Examples
    --------
    >>> rows = [f"{0.01 * k:.2f},{100.0 if k % 4 == 1 else 0.0},{1e-6 * k}" for k in range(12)]
    >>> log = parse_log("time,u,x\\n" + "\\n".join(rows), "log.csv")
    >>> len(log.t), log.h
    (12, 0.01)
    >>> parse_log("time,u,x\\n0,1,0\\n0.01,oops,0", "bad.csv")
    Traceback (most recent call last):
    ...
    papwc.identify.log_file.LogError: bad.csv, row 2 (line 3), column 'u': 'oops' is not a number
    """
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader)
    except StopIteration:
        raise LogError(f"{source}: empty; a log has a header line and one row per "
                       "sample") from None
    except csv.Error as exc:
        raise LogError(f"{source}, line 1: not CSV: {exc}") from None
    header = [name.strip() for name in header]
    seen: dict[str, int] = {}
    for i, name in enumerate(header):
        if name and name in seen:
            raise LogError(f"{source}, line 1: column {name!r} is named twice (fields "
                           f"{seen[name] + 1} and {i + 1}); each column needs its own name")
        seen[name] = i
    if columns.position is None and not set(POSITION_COLUMNS) & set(header):
        raise LogError(f"{source}, line 1: no column 'x_meas' or 'x' (position); the columns "
                       "are " + ", ".join(repr(n) for n in header)
                       + "; name the column with the option for the position")
    columns = columns.resolved(header)
    index = {}
    for what, name in columns.needed():
        if name not in header:
            raise LogError(f"{source}, line 1: no column {name!r} ({what}); the columns are "
                           + ", ".join(repr(n) for n in header)
                           + "; name the column with the option for the " + what)
        index[name] = header.index(name)
    needed = columns.needed()
    names = [name for _, name in needed]
    ranges = column_ranges()
    bounds = [ranges[what] for what, _ in needed]
    values: list[list[float]] = []
    try:
        for row in reader:
            if not row or all(not cell.strip() for cell in row):
                continue  # a blank line
            k = len(values)
            if k >= MAX_LOG_ROWS:
                raise LogError(f"{source}: more than {MAX_LOG_ROWS} rows; a log has at most "
                               f"{MAX_LOG_ROWS} rows (shorten it or sample it slower)")
            line = reader.line_num
            cells = []
            for name, (low, high, what) in zip(names, bounds, strict=True):
                where = f"{source}, row {k + 1} (line {line}), column {name!r}"
                if index[name] >= len(row):
                    raise LogError(f"{where}: missing (the row has {len(row)} of "
                                   f"{len(header)} fields)")
                value = _number(row[index[name]].strip(), where)
                if not low <= value <= high:
                    raise LogError(f"{where}: {value!r} is outside the model layer's range: "
                                   f"{what}")
                cells.append(value)
            if len(row) != len(header):
                raise LogError(f"{source}, row {k + 1} (line {line}): {len(row)} fields, the "
                               f"header has {len(header)}; every row has one value per column")
            values.append(cells)
    except csv.Error as exc:
        raise LogError(f"{source}, line {reader.line_num}: not CSV: {exc}") from None
    n = len(values)
    if n < MIN_LOG_ROWS:
        raise LogError(f"{source}, rows 1-{n}, column {columns.position!r}: {n} rows are too "
                       f"short to contain a move; a log needs at least {MIN_LOG_ROWS} (a rest, "
                       "the breakaway, sliding, the stop, a rest)")
    data = np.array(values, dtype=float)
    t = data[:, 0]
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0.0))
    if bad.size:
        k = int(bad[0]) + 1
        raise LogError(f"{source}, row {k + 1} (line {k + 2}), column {columns.time!r}: time "
                       f"{float(t[k])!r} s is not after {float(t[k - 1])!r} s of row {k}; time "
                       "must increase")
    h = float(np.median(dt))
    slack = TIME_TOLERANCE * h + 4.0 * np.spacing(np.maximum(np.abs(t[1:]), np.abs(t[:-1])))
    uneven = np.flatnonzero(np.abs(dt - h) > slack)
    if uneven.size:
        k = int(uneven[0]) + 1
        raise LogError(f"{source}, row {k + 1} (line {k + 2}), column {columns.time!r}: the "
                       f"step from row {k} is {float(dt[k - 1])!r} s, not the sample period "
                       f"{h!r} s (uneven time); the log must be sampled evenly (within "
                       f"{TIME_TOLERANCE:g} of the period)")
    h = float((t[-1] - t[0]) / (n - 1))
    _check_sample_period(h, f"{source}, column {columns.time!r}")
    x_d = data[:, 3].copy() if columns.motor is not None else None
    return Log(t.copy(), data[:, 1].copy(), data[:, 2].copy(), x_d, float(h), source, columns)


def _check_sample_period(h: float, where: str) -> None:
    """Refuse a sample period ``h`` (s) that is not one of a machine's log (LogError)."""
    from papwc.model.maneuver import LOG_SAMPLE_PERIOD as period

    slack = 1.0 + TIME_TOLERANCE  # h is computed from the times: within their tolerance
    if period.min / slack <= h <= period.max * slack:
        return
    if h > period.max:
        hint = (f"is the time in milliseconds? (then the period is {h / 1000.0:.6g} s); "
                "write the time column in seconds")
    else:
        hint = "is the time in seconds? write the time column in seconds"
    raise LogError(f"{where}: the sample period is {h!r} s, outside the "
                   f"{period.min:g}..{period.max:g} s of a machine's log; {hint}")


def check_travel(log: Log, travel: float) -> None:
    """Refuse a log whose position leaves ``x_0 +- travel`` (m) (:class:`LogError`)."""
    excursion = np.abs(log.x - log.x[0])
    beyond = np.flatnonzero(excursion > travel)
    if beyond.size:
        k = int(beyond[0])
        raise LogError(f"{log.where(k, log.columns.position)}: position {float(log.x[k])!r} m is "
                       f"beyond the travel: {excursion[k]:.6g} m from the start "
                       f"{float(log.x[0])!r} m, more than --travel {travel!r} m")
