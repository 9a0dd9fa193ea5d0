"""``papwc reproduce``: the paper's results regenerated end to end."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "build the plant FMU if needed, run scenarios/paper.toml, write figures 1, 3-9 and tables"
EPILOG = """examples:
  papwc reproduce --out results/reproduce
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="results/reproduce", help="output folder")
    parser.add_argument("--scenario", default=None,
                        help="scenario file (default: scenarios/paper.toml)")
    parser.add_argument("--fmu", default=None,
                        help="plant FMU (default: build/FrictionPlant.fmu, built if missing)")


def run(args: argparse.Namespace) -> int:
    from papwc.reproduce import reproduce

    return reproduce(Path(args.out), args.scenario, args.fmu)
