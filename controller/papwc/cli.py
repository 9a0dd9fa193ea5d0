"""The ``papwc`` command line: argparse subcommands, one module each in ``papwc.commands``."""

from __future__ import annotations

import argparse
import importlib
import sys

from papwc import __version__
from papwc.exit_status import run_command

#: Subcommand modules under papwc.commands, in the order ``papwc --help`` lists them.
COMMANDS: tuple[str, ...] = ("build", "run", "reproduce", "bench", "battery", "spec", "cosim",
                             "hostenv", "identify")


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
        p.set_defaults(_run=module.run, _memory_hint=getattr(module, "MEMORY_HINT", None))
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``papwc`` console script; returns the exit code.

    Exit codes: 0 success; 1 a run failed, or an operating-system error (one
    line naming the path and the operation; what was written stays); 2 bad
    input (a file, a field, an option); 130 interrupted (Ctrl-C).
    """
    args = make_parser().parse_args(argv)
    return run_command(f"papwc {args.command}", lambda: args._run(args), args._memory_hint)


if __name__ == "__main__":
    sys.exit(main())
