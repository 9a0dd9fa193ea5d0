"""Subcommands of ``papwc``: one module each, with ``HELP``, ``EPILOG``,
``add_arguments(parser)`` and ``run(args) -> int``."""
