"""``papwc reproduce``: the paper's results regenerated end to end."""

from __future__ import annotations

import argparse
from pathlib import Path

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
    parser.add_argument("--fmu", default=None, metavar="PATH",
                        help="plant FMU (default: one built from the current sources: the "
                             "checkout's build/FrictionPlant.fmu if current, else built "
                             "into DIR/fmu/)")


def run(args: argparse.Namespace) -> int:
    """Run ``papwc reproduce``; return 0, or 1 if a run failed."""
    from papwc.analysis.reproduce import reproduce

    return reproduce(Path(args.out), args.scenario, args.fmu)
