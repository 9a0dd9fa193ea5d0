"""``papwc bench``: print measured figures, one table per section of :mod:`papwc.bench`."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

HELP = "measure and print cost figures (per-call cost of the FMUs, ...)"

EPILOG = """\
examples:
  papwc bench --quick              # builds the FMUs into a temporary folder, fewer iterations
  papwc bench                      # the full measurement (about 3 min)
  papwc bench --fmu-dir build      # use FMUs already written by `papwc build` (and
                                   # build/pythonfmu/FrictionPlant.fmu, built if missing)
  papwc bench --realism            # also scenarios/realism.toml with the native and the
                                   # pythonfmu plant (a few minutes)
  papwc bench --fmu-dir build --only "update time"   # one section: each controller kind's
                                   # update against T/2 (R7, about 2 min; --quick: 10 s)
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc bench`` to its subparser."""
    parser.add_argument(
        "--quick", action="store_true", help="fewer iterations: a fast, less precise run"
    )
    parser.add_argument(
        "--fmu-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder with the FMUs written by `papwc build` (default: build them afresh "
        "into a temporary folder)",
    )
    parser.add_argument(
        "--realism", action="store_true",
        help="also run scenarios/realism.toml on 2 workers and print its wall time",
    )
    parser.add_argument(
        "--only", default=None, metavar="TEXT",
        help="run only the sections whose title holds TEXT (case ignored)",
    )


def run(args: argparse.Namespace) -> int:
    """Build the FMUs unless given, run every bench section, print the figures; return 0."""
    from papwc.bench import BenchContext, load_sections, run_sections
    from papwc.bench.native_step import PYTHONFMU_PLANT
    from papwc.fmubuild.fmus import build_all, build_fmu

    sections = load_sections()
    if args.only is not None:
        chosen = [s for s in sections if args.only.lower() in s.title.lower()]
        if not chosen:
            from papwc.errors import PapwcError

            raise PapwcError(f"--only {args.only!r}: no section's title holds it; sections: "
                             + "; ".join(s.title for s in sections))
        sections = chosen
    # a section named by --only runs even if it is opt-in
    options = frozenset(s.option for s in sections if s.option) if args.only is not None \
        else frozenset(["realism"] if args.realism else [])
    if args.fmu_dir is not None:
        # the pythonfmu plant beside the native one, built before any FMU is loaded
        pythonfmu_plant = args.fmu_dir / PYTHONFMU_PLANT
        if not pythonfmu_plant.is_file():
            build_fmu("FrictionPlant", pythonfmu_plant.parent, backend="pythonfmu")
        run_sections(BenchContext(fmu_dir=args.fmu_dir, quick=args.quick, options=options),
                     sections)
        return 0
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        build_all(Path(tmp))
        build_fmu("FrictionPlant", Path(tmp) / Path(PYTHONFMU_PLANT).parent, backend="pythonfmu")
        run_sections(BenchContext(fmu_dir=Path(tmp), quick=args.quick, options=options),
                     sections)
    return 0
