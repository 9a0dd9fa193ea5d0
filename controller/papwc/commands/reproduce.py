"""``papwc reproduce``: the paper's results regenerated end to end."""

from __future__ import annotations

import argparse
from pathlib import Path

from papwc.commands import add_fmu_option

#: What the out-of-memory message suggests lowering.
MEMORY_HINT = "--scenario with fewer iterations, --workers"

HELP = "run the paper's scenario on FrictionPlant.fmu, write figures 1, 3-9 and tables"
EPILOG = """examples:
  papwc reproduce --out results/reproduce
  papwc reproduce --out results/reproduce --readings    # also search the readings

Beside report.md, claims.csv holds each simulation claim of the paper's Section 4:
its metric, the value under the scenario's settings and, where those do not
reproduce it, under the reading (other values of the settings the paper leaves
open) that does. --readings searches those readings anew (minutes on 2 cores)
and writes readings.csv.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc reproduce`` to its subparser."""
    parser.add_argument("--out", type=Path, default=Path("results/reproduce"), metavar="DIR",
                        help="output folder (default: results/reproduce)")
    parser.add_argument("--scenario", default=None, metavar="FILE",
                        help="scenario file (default: the shipped scenarios/paper.toml)")
    add_fmu_option(parser)
    parser.add_argument("--readings", action="store_true",
                        help="search the readings the paper leaves open for each claim that "
                             "the scenario's settings do not reproduce (writes readings.csv)")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="processes for --readings (default: the cores available)")


def run(args: argparse.Namespace) -> int:
    """Run ``papwc reproduce``; return 0, or 1 if a run failed."""
    from papwc.errors import PapwcError

    if args.workers is not None and args.workers < 1:
        raise PapwcError(f"--workers {args.workers}: must be >= 1")
    from papwc.analysis.reproduction import reproduce

    return reproduce(Path(args.out), args.scenario, args.fmu, readings=args.readings,
                     workers=args.workers)
