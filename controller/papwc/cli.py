"""The ``papwc`` command line: argparse subcommands, one module each in ``papwc.commands``."""

from __future__ import annotations

import argparse
import importlib
import sys

from papwc import __version__
from papwc.errors import PapwcError

#: Subcommand modules under papwc.commands, in the order ``papwc --help`` lists them.
COMMANDS: tuple[str, ...] = ("build", "run", "reproduce", "bench", "battery", "cosim", "hostenv")


def make_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every subcommand's own subparser."""
    parser = argparse.ArgumentParser(
        prog="papwc",
        description="Adaptive pulse control of machines with friction, on FMI 2.0 co-simulation.",
    )
    parser.add_argument("--version", action="version", version=f"papwc {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        module = importlib.import_module(f"papwc.commands.{name}")
        p = sub.add_parser(
            name,
            help=module.HELP,
            description=module.HELP,
            epilog=getattr(module, "EPILOG", None),
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``papwc`` console script; returns the exit code."""
    args = make_parser().parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except PapwcError as exc:
        print(f"papwc {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"papwc {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
