"""The subcommands of ``papwc``, one module each (``HELP``, ``EPILOG``, ``add_arguments``, ``run``).

Modules import what they run inside ``run`` so that ``papwc --help`` stays fast.
"""

from __future__ import annotations

import argparse


def add_fmu_option(parser: argparse.ArgumentParser) -> None:
    """The ``--fmu PATH`` option of the commands that run the plant FMU."""
    parser.add_argument("--fmu", default=None, metavar="PATH",
                        help="plant FMU (default: one built from the current sources: the "
                             "checkout's build/FrictionPlant.fmu if current, else built "
                             "into DIR/fmu/)")
