"""``papwc build``: build the project's FMUs into a folder.

What is built is the list :data:`STEPS`; each step is a
:class:`BuildStep` whose function takes the output folder and returns the path
it wrote. Add an FMU or package by appending a step.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from papwc.build.fmus import build_friction_plant, build_trivial

HELP = "build the FMUs (FrictionPlant.fmu, PapwcTrivial.fmu) into a folder"

EPILOG = """\
examples:
  papwc build                      # writes build/FrictionPlant.fmu, build/PapwcTrivial.fmu
  papwc build --out /tmp/fmus      # writes into /tmp/fmus
  fmpy simulate build/FrictionPlant.fmu --output-interval 0.01 --stop-time 1 \\
      --input-file scenarios/pulse_in.csv
"""


@dataclass(frozen=True)
class BuildStep:
    """One artefact of ``papwc build``.

    Attributes
    ----------
    name : str
        File name written, e.g. ``FrictionPlant.fmu``.
    build : callable
        ``build(out_dir) -> Path``; raises :class:`papwc.errors.BuildError`.
    """

    name: str
    build: Callable[[Path], Path]


#: What ``papwc build`` writes, in order.
STEPS: list[BuildStep] = [
    BuildStep("FrictionPlant.fmu", build_friction_plant),
    BuildStep("PapwcTrivial.fmu", build_trivial),
]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc build`` to its subparser."""
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("build"),
        metavar="DIR",
        help="folder to write into, created if needed (default: build/ in the current folder)",
    )


def run(args: argparse.Namespace) -> int:
    """Run every build step into ``args.out``; print each path written; return 0."""
    for build_step in STEPS:
        print(build_step.build(args.out))
    return 0
