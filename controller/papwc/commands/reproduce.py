"""``papwc reproduce``: the paper's results regenerated end to end."""

from __future__ import annotations

import argparse
from pathlib import Path

from papwc.commands import add_fmu_option

HELP = "run the paper's scenario on FrictionPlant.fmu, write figures 1, 3-9 and tables"
EPILOG = """examples:
  papwc reproduce --out results/reproduce
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc reproduce`` to its subparser."""
    parser.add_argument("--out", type=Path, default=Path("results/reproduce"), metavar="DIR",
                        help="output folder (default: results/reproduce)")
    parser.add_argument("--scenario", default=None, metavar="FILE",
                        help="scenario file (default: the shipped scenarios/paper.toml)")
    add_fmu_option(parser)


def run(args: argparse.Namespace) -> int:
    """Run ``papwc reproduce``; return 0, or 1 if a run failed."""
    from papwc.analysis.reproduce import reproduce

    return reproduce(Path(args.out), args.scenario, args.fmu)
