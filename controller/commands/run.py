"""``papwc run``: run a scenario's controllers and write results."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "run a scenario file (TOML) and write summary.csv, traces and plots"
EPILOG = """examples:
  papwc run scenarios/paper.toml --out results/paper
  papwc run scenarios/long_move.toml --plant physics
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario file (TOML)")
    parser.add_argument("--out", default=None, help="output folder (default: results/NAME)")
    parser.add_argument("--plant", choices=("fmu", "physics"), default="fmu",
                        help="step FrictionPlant.fmu through fmpy (default) or the physics "
                             "module in-process")
    parser.add_argument("--fmu", default=None,
                        help="plant FMU (default: build/FrictionPlant.fmu, built if missing)")


def run(args: argparse.Namespace) -> int:
    from papwc.runner import format_table, run_scenario, write_results
    from papwc.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    out = Path(args.out) if args.out else Path("results") / scenario.name
    results = run_scenario(scenario, args.plant, args.fmu)
    rows = write_results(results, out)
    print(format_table(rows))
    print(f"wrote {out / 'summary.csv'}, {len(rows)} rows, traces and plots in {out}")
    failed = [r for r in results if r.error]
    for r in failed:
        print(f"error: {r.label}: {r.error}")
    return 1 if failed else 0
