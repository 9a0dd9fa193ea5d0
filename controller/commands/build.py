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

from papwc.build.controller_fmu import build_pulse_controller
from papwc.build.fmus import build_friction_plant, build_trivial
from papwc.build.ssp import build_closed_loop_ssp

HELP = (
    "build the FMUs (FrictionPlant.fmu, PulseController.fmu, PapwcTrivial.fmu) and "
    "ClosedLoop.ssp into a folder"
)

EPILOG = """\
examples:
  papwc build                      # writes build/FrictionPlant.fmu, build/PulseController.fmu,
                                   # build/PapwcTrivial.fmu and build/ClosedLoop.ssp
  papwc build --out /tmp/fmus      # writes into /tmp/fmus
  papwc build --scenario scenarios/long_move.toml --controller 2
                                   # ClosedLoop.ssp for another scenario's 2nd controller
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


#: Scenario whose PAPWC case ClosedLoop.ssp binds unless --scenario is given.
DEFAULT_SSP_SCENARIO = Path("scenarios") / "paper.toml"

#: What ``papwc build`` writes, in order.
STEPS: list[BuildStep] = [
    BuildStep("FrictionPlant.fmu", build_friction_plant),
    BuildStep("PulseController.fmu", build_pulse_controller),
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
    parser.add_argument(
        "--scenario",
        type=Path,
        default=None,
        metavar="FILE",
        help="scenario whose plant, maneuver and controller ClosedLoop.ssp binds "
        "(default: scenarios/paper.toml)",
    )
    parser.add_argument(
        "--controller",
        type=int,
        default=None,
        metavar="N",
        help="[[controller]] table #N (1-based) for ClosedLoop.ssp; default: the first papwc table",
    )


def run(args: argparse.Namespace) -> int:
    """Run every build step into ``args.out``; print each path written; return 0."""
    for build_step in STEPS:
        print(build_step.build(args.out))
    scenario = args.scenario
    if scenario is None:
        scenario = DEFAULT_SSP_SCENARIO
        if not scenario.is_file():
            print(f"ClosedLoop.ssp not written: {scenario} not found here (give --scenario FILE)")
            return 0
    index = None if args.controller is None else args.controller - 1
    print(
        build_closed_loop_ssp(
            args.out,
            scenario,
            args.out / "FrictionPlant.fmu",
            args.out / "PulseController.fmu",
            index,
        )
    )
    return 0
