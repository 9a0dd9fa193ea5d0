"""The subcommands of ``papwc``, one module each (``HELP``, ``EPILOG``, ``add_arguments``, ``run``).

Modules import what they run inside ``run`` so that ``papwc --help`` stays fast.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from papwc.errors import PapwcError


def add_fmu_option(parser: argparse.ArgumentParser) -> None:
    """The ``--fmu PATH`` option of the commands that run the plant FMU."""
    parser.add_argument("--fmu", default=None, metavar="PATH",
                        help="plant FMU (default: one built from the current sources: the "
                             "checkout's build/FrictionPlant.fmu if current, else built "
                             "into DIR/fmu/)")


def default_out(out: Path | None, *parts: str) -> Path:
    """``out``, or the checkout's ``parts`` folder when papwc runs from a checkout.

    Raises
    ------
    PapwcError
        If ``out`` is not given and papwc is installed from a wheel.
    """
    if out is not None:
        return out
    from papwc.resources import checkout_root

    root = checkout_root()
    if root is None:
        raise PapwcError("--out DIR is required: papwc is not running from a checkout")
    return root.joinpath(*parts)
