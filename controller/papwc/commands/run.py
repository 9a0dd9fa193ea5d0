"""``papwc run``: run a scenario's controllers and write results."""

from __future__ import annotations

import argparse
from pathlib import Path

from papwc.commands import add_fmu_option

#: What the out-of-memory message suggests lowering.
MEMORY_HINT = "--max-steps"

HELP = "run a scenario file (TOML) and write summary.csv, traces and plots"
EPILOG = """examples:
  papwc run scenarios/paper.toml --out results/paper
  papwc run scenarios/long_move.toml --plant physics
  papwc run scenarios/realism.toml --plant-model id/plant.toml   # told what papwc identify found

each controller's traces and summary rows are written as it finishes; until
everything is written (and after Ctrl-C or an error) DIR holds a file
INCOMPLETE saying what is missing. Ctrl-C (or SIGTERM) keeps the traces of the
controller under way too, the last one cut short (INCOMPLETE says where). A new
run into DIR first removes what an earlier run wrote there (summary.csv,
trace_*_it*.csv, the plots), nothing else.
exit code: 0 ok, 1 a controller's run failed or a file cannot be written,
2 the scenario file or an option is wrong, 130 interrupted (Ctrl-C).
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
    add_max_steps(parser)
    add_controllers_option(parser)
    parser.add_argument("--plant-model", default=None, metavar="PLANT.toml",
                        help="give every controller the plant papwc identify wrote in "
                             "PLANT.toml (its [plant] and [identified] tables) in place of "
                             "what the scenario tells it: m_est, f_c_est, c_est and the "
                             "stiction band (f_b_floor, f_b_step), where its kind reads them; "
                             "the plant run is the scenario's")


def add_controllers_option(parser: argparse.ArgumentParser) -> None:
    """The option ``--controllers`` (shared with ``papwc battery``)."""
    parser.add_argument("--controllers", choices=("auto", "native", "python"), default="auto",
                        help="run the kinds pwc, papwc and pid with the C controller of "
                             "PulseController.fmu (native: built into OUT/fmu if needed; "
                             "auto, the default: where build/PulseController.fmu is current, "
                             "after papwc build) or every kind with the Python controllers "
                             "(python); the same numbers either way. exact, dual_loop and "
                             "hybrid are Python")


def add_max_steps(parser: argparse.ArgumentParser) -> None:
    """The option ``--max-steps`` (shared with ``papwc battery``)."""
    from papwc.limits import MAX_STEPS

    parser.add_argument("--max-steps", type=positive_int, default=MAX_STEPS, metavar="N",
                        help="refuse a run of more than N communication steps (all "
                             f"controllers and iterations; default {MAX_STEPS})")


def positive_int(text: str) -> int:
    """An argparse type: a whole number >= 1."""
    from papwc.limits import whole_number

    return whole_number(1)(text)


def run(args: argparse.Namespace) -> int:
    """Run the scenario; return 0, or 1 if a controller's run failed."""
    import sys

    from papwc.limits import check_steps
    from papwc.results.folder import ResultsFolder, format_table, run_into_folder
    from papwc.scenario import load_scenario
    from papwc.scenario_run import ensure_plant_fmu, run_scenario

    if args.plant == "physics" and args.fmu is not None:
        from papwc.errors import PapwcError

        raise PapwcError(f"--fmu {args.fmu}: --plant physics runs the in-process physics and "
                         "loads no FMU; give --fmu with --plant fmu (the default) only")
    scenario = load_scenario(args.scenario)
    if args.plant_model is not None:
        told = given_plant_model(scenario, args.plant_model)
        print(f"papwc run: {told}", file=sys.stderr)
    m = scenario.maneuver
    check_steps(str(args.scenario), len(scenario.controllers), m.iterations, m.duration, m.T,
                args.max_steps)
    for label, message in scenario.warnings:
        print(f"papwc run: warning: {scenario.source}: {label}: {message}", file=sys.stderr)
    out = Path(args.out) if args.out else Path("results") / scenario.name
    warnings = {label: scenario.warnings_of(label) for label in scenario.labels}
    fmu = ensure_plant_fmu(args.fmu, out) if args.plant == "fmu" else None
    folder = ResultsFolder(out, scenario.labels, warnings, scenario=scenario)
    folder.start()
    from papwc.scenario_run import controller_library

    library = controller_library(args.controllers, out)
    results = run_into_folder(folder, lambda progress: run_scenario(
        scenario, args.plant, fmu, progress=progress, library=library,
        stopped=folder.add_cut))
    rows = run_into_folder(folder, lambda progress: folder.finish())
    print(format_table(rows))
    print(f"wrote {out / 'summary.csv'}, {len(rows)} rows, pulses.csv, traces and plots in "
          f"{out}")
    failed = [r for r in results if r.error]
    for r in failed:
        print(f"error: {r.label}: {r.error}")
    return 1 if failed else 0


def given_plant_model(scenario, path: str) -> str:
    """Give ``scenario``'s controllers the plant model of ``path`` (``--plant-model``, see
    :meth:`papwc.identify.plant_model.PlantModel.settings`); one line saying what they were
    given.

    Raises
    ------
    ScenarioError
        If ``path`` is not a plant model, or a controller's settings with it are not valid
        (naming the file, the controller and the setting).
    """
    from papwc.errors import ScenarioError
    from papwc.identify.plant_model import REPLACED, read_plant_model

    model = read_plant_model(path)
    try:
        given = model.give_to(scenario)
    except ScenarioError as exc:
        raise ScenarioError(f"--plant-model {path}: {exc} (of {scenario.source})") from None
    return f"the plant identified in {path} given to " + "; ".join(
        f"{label} (" + ", ".join(f"{name} = {new.get(name):.6g}" for name in REPLACED
                                 if name in new.field_names() and new.get(name) != told.get(name))
        + ")" for label, told, new in given)
