"""``papwc hostenv``: the environment a non-Python FMI host needs for the FMUs."""

from __future__ import annotations

import argparse

HELP = ("print the line a non-Python FMI host (ecos, fmusim, OMSimulator, ...) needs to load "
        "the FMUs with this Python (Linux: LD_PRELOAD=libpython)")

EPILOG = """\
examples:
  papwc hostenv            # export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libpython3.11.so.1.0
  eval "$(papwc hostenv)" && ecos simulate --path build/ClosedLoop.ssp --stepSize 0.01 \\
      --stopTime 2 --parameterSet scenario
  papwc hostenv --value             # the library path alone
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc hostenv`` to its subparser."""
    parser.add_argument("--value", action="store_true",
                        help="print only the value (the library path on Linux)")


def run(args: argparse.Namespace) -> int:
    """Print the line (or the value); 0."""
    from papwc.host_environment import host_environment

    line = host_environment()
    if args.value:
        import shlex

        line = line.split("=", 1)[1].split(";", 1)[0].strip('"')
        if line.startswith("'"):
            line = shlex.split(line)[0]
    print(line)
    return 0
