"""``papwc cosim``: run an SSP of FMI 2.0 Co-Simulation FMUs with the project's master."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from papwc.commands import default_out

#: What the out-of-memory message suggests lowering.
MEMORY_HINT = "--stop, --variables"

HELP = ("run an SSP (FMI 2.0 Co-Simulation FMUs, parameter bindings, fixed step) with the "
        "master as libcosim runs it; write a CSV and a plot")

EPILOG = """\
The components step side by side (Jacobi) at the SSD's fixed step
(osp:FixedStepAlgorithm or oms:FixedStepMaster) or --step, from the
DefaultExperiment's start to its stop time, with every parameter binding
applied (Strings too). Row 0 of the CSV holds the values after initialization.
Rows are written as they come (memory does not grow with the run's length);
until the run has finished, and after Ctrl-C or SIGTERM, DIR holds a file
INCOMPLETE and the CSV every row recorded before the stop.

examples:
  papwc cosim build/ClosedLoop.ssp                  # writes results/cosim/ClosedLoop.csv, .png
  papwc cosim build/ClosedLoop.ssp --out /tmp/loop --variables plant.x controller.u
  papwc cosim other.ssp --step 0.001 --stop 5
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc cosim`` to its subparser."""
    parser.add_argument("ssp", type=Path, help="the SSP archive (.ssp)")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="output folder, created if needed (default: results/cosim/ of the "
                             "papwc checkout; required when papwc is installed from a wheel)")
    parser.add_argument("--variables", nargs="+", default=None, metavar="COMP.VAR",
                        help="variables to record (default: every output of every component)")
    parser.add_argument("--step", type=float, default=None, metavar="S",
                        help="communication step, s (default: the SSD's fixed step)")
    parser.add_argument("--stop", type=float, default=None, metavar="S",
                        help="stop time, s (default: the SSD's DefaultExperiment stopTime)")


def run(args: argparse.Namespace) -> int:
    """Run the SSP; print what was written; 0, or 1 if a step failed (rows before it kept)."""
    from papwc.results.cosim_stream import cosim
    out = default_out(args.out, "results", "cosim")
    # The master reads the FMUs' log and reports a refusal itself, in one line.
    os.environ["PAPWC_FMU_STDERR"] = "0"
    result = cosim(args.ssp, out, args.variables, args.step, args.stop)
    print(f"wrote {result.csv_path} ({result.steps} steps of {result.step_size!r} s, "
          f"{len(result.columns) - 1} variables) and {result.png_path}")
    if result.error:
        print(f"papwc cosim: error: {result.error}", file=sys.stderr)
        return 1
    return 0
