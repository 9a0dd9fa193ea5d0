"""The command line of an analysis that takes one count (``python -m papwc_studies.X``), and
the line its repeated pulses are reported in."""

from __future__ import annotations

import argparse
import statistics
from collections.abc import Sequence

from papwc.limits import whole_number

__all__ = ["MOVED", "REPEATS_MAX", "moves_line", "parse_count"]

#: Largest number of repetitions of a pulse a study takes.
REPEATS_MAX = 100_000
#: Displacements at or below this are "did not move", m.
MOVED = 5e-8


def parse_count(argv: Sequence[str] | None, prog: str, description: str, option: str,
                default: int, high: int, what: str) -> int:
    """The count given as ``option N`` (1 to high, else ``default``) in ``argv``.

    Anything else, or a count that is not a whole number in 1..high, is refused in one line
    (exit 2).
    """
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument(option, type=whole_number(1, high), default=default, dest="count",
                        help=f"{what} (1 to {high}, default {default})")
    return parser.parse_args(argv).count


def moves_line(moved: Sequence[float], repeats: int) -> str:
    """``moved n of repeats; smallest / median / largest um (...)`` of the moves that moved
    (um, not empty)."""
    return (f"moved {len(moved)} of {repeats}; {min(moved):.2f} / "
            f"{statistics.median(moved):.2f} / {max(moved):.2f} um (smallest / median / largest)")
