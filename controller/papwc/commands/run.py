"""``papwc run``: run a scenario's controllers and write results."""

from __future__ import annotations

import argparse
from pathlib import Path

from papwc.commands import add_fmu_option

HELP = "run a scenario file (TOML) and write summary.csv, traces and plots"
EPILOG = """examples:
  papwc run scenarios/paper.toml --out results/paper
  papwc run scenarios/long_move.toml --plant physics
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc run`` to its subparser."""
    parser.add_argument("scenario", help="scenario file (TOML)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="output folder (default: results/NAME)")
    parser.add_argument("--plant", choices=("fmu", "physics"), default="fmu",
                        help="step FrictionPlant.fmu through the master (default) or the "
                             "physics in-process")
    add_fmu_option(parser)


def run(args: argparse.Namespace) -> int:
    """Run the scenario; return 0, or 1 if a controller's run failed."""
    from papwc.runner import ensure_plant_fmu, format_table, run_scenario, write_results
    from papwc.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    out = Path(args.out) if args.out else Path("results") / scenario.name
    fmu = ensure_plant_fmu(args.fmu, out) if args.plant == "fmu" else None
    results = run_scenario(scenario, args.plant, fmu)
    rows = write_results(results, out)
    print(format_table(rows))
    print(f"wrote {out / 'summary.csv'}, {len(rows)} rows, traces and plots in {out}")
    failed = [r for r in results if r.error]
    for r in failed:
        print(f"error: {r.label}: {r.error}")
    return 1 if failed else 0
