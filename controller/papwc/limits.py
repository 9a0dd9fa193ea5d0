"""Bounds on the work a command takes on, checked before any run starts.

Physical magnitudes are bounded by the ``min``/``max`` of the model layer's
tables (:mod:`papwc.model`); what is bounded here is the amount of work and
memory an input asks for. Each limit has a default that a command-line flag
raises on purpose (``--max-steps``, ``--max-runs``); the message of a refusal
gives the estimate that exceeds it.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from collections.abc import Callable
from pathlib import Path

from papwc.errors import ScenarioError

__all__ = [
    "BYTES_PER_STEP",
    "DEFAULT_RUN_TIMEOUT",
    "MAX_INPUT_BYTES",
    "MAX_RUNS",
    "MAX_STEPS",
    "NAME_PATTERN",
    "check_name",
    "check_steps",
    "read_input_text",
    "whole_number",
    "safe_name",
    "scenario_steps",
]

#: Default limit of the communication steps of one run: every controller, every
#: iteration (``--max-steps`` raises it).
MAX_STEPS = 1_000_000
#: Default limit of the runs of a battery and of the grid points of its sweep
#: (``--max-runs`` raises it).
MAX_RUNS = 100_000
#: Largest scenario or battery file read, bytes.
MAX_INPUT_BYTES = 16 * 1024 * 1024
#: Default time limit of one battery run, s (``[battery] run_timeout``).
DEFAULT_RUN_TIMEOUT = 600.0
#: Memory a trace holds per recorded step while a run keeps it (estimate for
#: messages), bytes.
BYTES_PER_STEP = 400

#: Names and labels that go into file names: a letter, digit or ``_`` first, then
#: letters, digits and ``_ . + -``; at most 80 characters.
NAME_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,79}")


def check_name(value: str) -> str | None:
    """What is wrong with ``value`` as a name that goes into file names, or None."""
    if NAME_PATTERN.fullmatch(value):
        return None
    return ("must be 1 to 80 characters: letters, digits and _ . + - (not first: . + -), "
            "as it names files")


def safe_name(text: str, fallback: str = "scenario") -> str:
    """``text`` made into a name :func:`check_name` accepts (other characters -> ``_``)."""
    name = re.sub(r"[^A-Za-z0-9_.+-]", "_", text)[:80].lstrip(".+-")
    return name or fallback


def scenario_steps(n_controllers: int, iterations: int, steps_per_iteration: int) -> int:
    """Communication steps of one run: controllers x iterations x steps per iteration."""
    return n_controllers * iterations * steps_per_iteration


def check_steps(where: str, n_controllers: int, iterations: int, duration: float, T: float,
                max_steps: int) -> None:
    """Raise ScenarioError if a run would take more than ``max_steps`` communication steps.

    ``where`` names the file (and run) in the message.
    """
    per_iteration = duration / T
    total = n_controllers * iterations * per_iteration
    if math.isfinite(total) and total <= max_steps:
        return
    memory = BYTES_PER_STEP * total
    raise ScenarioError(
        f"{where}: {n_controllers} controller(s) x {iterations} iteration(s) x "
        f"{per_iteration:.4g} steps (duration = {duration!r} s / T = {T!r} s) = {total:.4g} "
        f"communication steps, over the limit of {max_steps:.4g} steps per run (traces "
        f"of about {_bytes(memory)}); pass --max-steps {_round_up(total)} to allow it")


def _round_up(x: float) -> str:
    if not math.isfinite(x) or x >= 1e18:
        return "N"
    return str(int(math.ceil(x)))


def _bytes(n: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 1e3:.3g} kB"


def input_path_problem(path: Path) -> str | None:
    """Why ``path`` cannot be read as a text input file (or None): missing, not a file."""
    if not path.exists():
        return "no such file"
    if path.is_dir():
        return "is a folder, not a file"
    if not path.is_file():
        return "is not a regular file (a FIFO, device or socket)"
    return None


def read_input_text(path: str | os.PathLike, what: str, form: str, error: type[Exception],
                    too_large: str = "", encoding: str = "utf-8-sig") -> str:
    """The text of the input file at ``path`` (a scenario, a battery, a log).

    Parameters
    ----------
    path : path
        The file.
    what : str
        What it is, in messages (``"scenario"``: "no such scenario file").
    form : str
        Its format, in messages (``"TOML"``, ``"CSV"``).
    error : type
        The exception raised, with one message naming the file and the problem.
    too_large : str
        What a file larger than :data:`MAX_INPUT_BYTES` is told besides its size
        (default: that it is not a ``what`` file).
    encoding : str
        ``"utf-8-sig"`` (default: UTF-8, a byte-order mark that an editor put first
        dropped), or ``"utf-8"`` to keep one.

    Raises
    ------
    error
        Missing, a folder, a FIFO or device, unreadable, larger than
        :data:`MAX_INPUT_BYTES`, binary (a NUL byte) or not UTF-8.
    """
    problem = input_path_problem(Path(path))
    if problem == "no such file":
        raise error(f"{path}: no such {what} file")
    if problem is not None:
        raise error(f"{path}: {problem}; give a {what} file ({form})")
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_INPUT_BYTES + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read the {what} file: {exc.strerror or exc}") from None
    if len(raw) > MAX_INPUT_BYTES:
        raise error(f"{path}: larger than {MAX_INPUT_BYTES // (1024 * 1024)} MB; "
                    + (too_large or f"not a {what} file"))
    if b"\0" in raw:
        raise error(f"{path}: a binary file (it holds NUL bytes), not a {what} file "
                    f"({form} text)")
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise error(f"{path}: not UTF-8 text: byte 0x{raw[exc.start]:02x} at line {line} "
                    f"(offset {exc.start}); save the {what} file as UTF-8") from None


def whole_number(low: int, high: int | None = None) -> Callable[[str], int]:
    """An argparse type: a whole number in ``low..high`` (no upper bound if high is None).

    Its refusals are one phrase each: ``'x' is not a whole number``, ``0 must be >= 1``,
    ``0 is outside 1..50``.
    """

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if high is None and value < low:
            raise argparse.ArgumentTypeError(f"{text} must be >= {low}")
        if high is not None and not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{value} is outside {low}..{high}")
        return value

    return parse
