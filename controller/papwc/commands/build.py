"""``papwc build``: build the project's FMUs and ClosedLoop.ssp into a folder."""

from __future__ import annotations

import argparse
from pathlib import Path

from papwc.commands import default_out

HELP = (
    "build the FMUs (FrictionPlant.fmu, PulseController.fmu, PulseControllerPython.fmu, "
    "PapwcTrivial.fmu) and ClosedLoop.ssp into a folder"
)

EPILOG = """\
While it works, the step under way is shown on standard error (a status line on a
terminal; otherwise a line as each step starts and one every 10 s while it lasts). The
first build compiles zig's C runtimes for every platform: a few minutes, once.

examples:
  papwc build                      # in a checkout: writes build/FrictionPlant.fmu,
                                   # build/PulseController.fmu (C: pwc, papwc, pid),
                                   # build/PulseControllerPython.fmu (pythonfmu: every
                                   # kind), build/PapwcTrivial.fmu, build/ClosedLoop.ssp
  papwc build --out /tmp/fmus      # writes into /tmp/fmus
  papwc build --backend pythonfmu  # FrictionPlant.fmu made with pythonfmu (runs in the
                                   # host's Python 3.10+) instead of the native one
  papwc build --scenario scenarios/long_move.toml --controller 2
                                   # ClosedLoop.ssp for another scenario's 2nd controller
                                   # (PulseControllerPython.fmu in it for exact, dual_loop, hybrid)
  fmpy simulate build/FrictionPlant.fmu --output-interval 0.01 --stop-time 1 \\
      --input-file scenarios/pulse_in.csv --output-file pulse_out.csv
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc build`` to its subparser."""
    from papwc.fmubuild.fmus import BACKENDS, DEFAULT_BACKEND

    parser.add_argument(
        "--backend",
        choices=BACKENDS,
        default=DEFAULT_BACKEND,
        help="how FrictionPlant.fmu is made: 'native' (C, compiled by zig for win64, "
        "linux64 and darwin64; no Python in the host) or 'pythonfmu' (the model layer in "
        "the host's Python 3.10 or newer); default: %(default)s. PulseController.fmu is "
        "native, PulseControllerPython.fmu and PapwcTrivial.fmu are pythonfmu FMUs either way",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder to write into, created if needed (default: build/ of the papwc "
        "checkout; required when papwc is installed from a wheel)",
    )
    parser.add_argument(
        "--scenario",
        type=Path,
        default=None,
        metavar="FILE",
        help="scenario whose plant, maneuver and controller ClosedLoop.ssp binds "
        "(default: the shipped scenarios/paper.toml)",
    )
    parser.add_argument(
        "--controller",
        type=int,
        default=None,
        metavar="N",
        help="[[controller]] table #N (1-based) for ClosedLoop.ssp; default: the first papwc table",
    )


def run(args: argparse.Namespace) -> int:
    """Build every FMU and the SSP into ``args.out``; print each path written; return 0."""
    from papwc.fmubuild.fmus import FMUS, build_fmu
    from papwc.fmubuild.ssp_writer import build_closed_loop_ssp
    from papwc.progress import Progress
    from papwc.resources import scenario_file

    out = default_out(args.out, "build")
    _check_controller(args)  # 1-based, checked before anything is built
    with Progress("papwc build") as progress:
        for recipe in FMUS:
            path = build_fmu(recipe.name, out, args.backend)
            progress.done()
            print(path, flush=True)
        scenario = args.scenario if args.scenario is not None else scenario_file("paper.toml")
        index = None if args.controller is None else args.controller - 1
        progress.doing("writing ClosedLoop.ssp")
        path = build_closed_loop_ssp(out, scenario, out / "FrictionPlant.fmu",
                                     out / "PulseController.fmu", index)
        progress.done()
        print(path)
    return 0


def _check_controller(args: argparse.Namespace) -> None:
    """Refuse ``--controller N`` outside 1..(number of [[controller]] tables), 1-based."""
    if args.controller is None:
        return
    from papwc.errors import PapwcError
    from papwc.resources import scenario_file
    from papwc.scenario import load_scenario

    path = args.scenario if args.scenario is not None else scenario_file("paper.toml")
    n = len(load_scenario(path).controllers)
    if not 1 <= args.controller <= n:
        raise PapwcError(f"--controller {args.controller}: {path} has {n} [[controller]] "
                         f"table(s); give 1 to {n} (1-based)")
