"""``papwc identify``: fit the friction plant to a measured log, design its excitation, or
identify a plant FMU."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from papwc.identify import DESIGN_DURATION, DESIGN_F_P_MAX, DESIGN_T, DESIGN_TRAVEL

HELP = ("identify the friction plant (m, f_c, f_s, c, the deviations the data support and the "
        "stiction band) from a log of force and position, design the excitation, or identify a "
        "plant FMU")

EPILOG = """\
examples:
  papwc identify --design --out id/        # id/excitation.csv: the force to apply, per sample
  papwc identify machine.csv --out id/     # id/plant.toml, identified.csv, report.md, figures
  papwc identify machine.csv --out id/ --time-column t --force-column F --position-column pos
  papwc identify --fmu build/FrictionPlant.fmu --start-values m=120,f_c=80,f_s=110,c=500 \\
      --out id/                            # applies the excitation, writes id/log.csv, fits

a log is a CSV with a header naming each column once: time (s), force (N, held from its
row to the next), table position (m; the column x_meas, else x); one value per column in
every row, evenly sampled at a period of 1e-06 to 0.1 s (time in seconds), each value
finite and within the model layer's range (|force| <= 1e9 N, |position| <= 1e6 m,
|time| <= 1e9 s). DIR holds INCOMPLETE until everything is written; a new run into DIR
first removes what an earlier one wrote there, nothing else. The step under way is shown
on standard error (a status line on a terminal; otherwise a line as each step starts and
one every 10 s while it lasts).
exit code: 0 ok, 1 a file cannot be written, 2 a bad log, option or FMU, 130 interrupted.
"""

#: Largest excitation, s.
MAX_DURATION = 1000.0


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number > 0")
    return value


def _assignments(text: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        name, sep, value = part.partition("=")
        if not sep or not name.strip():
            raise argparse.ArgumentTypeError(f"{part!r} is not NAME=VALUE")
        try:
            number = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{part!r}: {value!r} is not a number") from None
        if not math.isfinite(number):
            raise argparse.ArgumentTypeError(f"{part!r}: the value must be finite")
        out[name.strip()] = number
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc identify`` to its subparser."""
    parser.add_argument("log", nargs="?", type=Path, default=None, metavar="LOG.csv",
                        help="the log to identify (CSV: time, force, position)")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="output folder (created)")
    mode = parser.add_argument_group("instead of a log")
    mode.add_argument("--design", action="store_true",
                      help="write the excitation to apply (DIR/excitation.csv) and stop")
    mode.add_argument("--fmu", type=Path, default=None, metavar="PLANT.fmu",
                      help="apply the excitation to this FMI 2.0 Co-Simulation FMU, log it "
                           "(DIR/log.csv) and identify it")
    mode.add_argument("--start-values", type=_assignments, default={}, metavar="NAME=V,...",
                      help="start values of the FMU's parameters (with --fmu)")
    mode.add_argument("--force-variable", default="u", metavar="NAME",
                      help="the FMU's force input (default u)")
    mode.add_argument("--position-variable", default="x_meas", metavar="NAME",
                      help="the FMU's position output (default x_meas)")
    design = parser.add_argument_group("the excitation (--design, --fmu)")
    design.add_argument("--T", type=_positive, default=DESIGN_T, metavar="S",
                        help=f"sample period, s (default {DESIGN_T:g})")
    design.add_argument("--f-p-max", type=_positive, default=DESIGN_F_P_MAX, metavar="N",
                        help=f"largest force to apply, N (default {DESIGN_F_P_MAX:g})")
    design.add_argument("--duration", type=_positive, default=DESIGN_DURATION, metavar="S",
                        help=f"length of the excitation, s (default {DESIGN_DURATION:g}, at "
                             f"most {MAX_DURATION:g})")
    design.add_argument("--expect", type=_assignments, default={}, metavar="NAME=V,...",
                        help="expected m, f_c, f_s, c (default Table 1: 150 kg, 100 N, 130 N, "
                             "700 N.s/m); the design holds for plants within +-50 %%")
    parser.add_argument("--travel", type=_positive, default=DESIGN_TRAVEL, metavar="M",
                        help=f"the table stays within +-M of its start (m, default "
                             f"{DESIGN_TRAVEL:g}): the excitation is made for it, a log beyond "
                             "it is refused")
    columns = parser.add_argument_group("the log's columns")
    columns.add_argument("--time-column", default="time", metavar="NAME")
    columns.add_argument("--force-column", default="u", metavar="NAME")
    columns.add_argument("--position-column", default=None, metavar="NAME",
                         help="the table position (default: x_meas, the plant's measured "
                              "output, else x)")
    columns.add_argument("--motor-column", default=None, metavar="NAME",
                         help="motor position (read and checked; the flexible drive is not "
                              "fitted)")
    parser.add_argument("--deviations", default="stribeck,lag,ripple", metavar="LIST",
                        help="deviations to try, comma-separated: stribeck, lag, ripple "
                             "(default: all three), or none")


def _check(args: argparse.Namespace) -> tuple[str, tuple[str, ...]]:
    """The mode (log, design, fmu) and the deviations to try; IdentifyError if inconsistent."""
    from papwc.identify import IdentifyError
    from papwc.identify.fit import DEVIATIONS
    from papwc.identify.log_file import MAX_LOG_ROWS
    from papwc.model.maneuver import LOG_SAMPLE_PERIOD
    from papwc.model.plant import plant_problems

    modes = [name for name, on in (("LOG.csv", args.log is not None), ("--design", args.design),
                                   ("--fmu", args.fmu is not None)) if on]
    if len(modes) != 1:
        raise IdentifyError("give exactly one of LOG.csv, --design and --fmu"
                            + (f" (given: {', '.join(modes)})" if modes else ""))
    if args.start_values and args.fmu is None:
        raise IdentifyError("--start-values is for --fmu")
    known = [d.name for d in DEVIATIONS]
    names = tuple(n.strip() for n in args.deviations.split(",") if n.strip())
    if names == ("none",):
        names = ()
    for name in names:
        if name not in known:
            raise IdentifyError(f"--deviations: unknown deviation {name!r}; allowed: "
                                + ", ".join(known) + " or none")
    if modes[0] != "LOG.csv":
        period = LOG_SAMPLE_PERIOD
        if not period.min <= args.T <= period.max:
            raise IdentifyError(f"--T {args.T!r} s: the sample period of a machine's log is "
                                f"{period.min:g} to {period.max:g} s (the log is read back)")
        if args.duration > MAX_DURATION:
            raise IdentifyError(f"--duration {args.duration!r} s: at most {MAX_DURATION:g} s")
        rows = round(args.duration / args.T) + 1  # the samples: both ends of every step
        if rows > MAX_LOG_ROWS:
            raise IdentifyError(f"--duration {args.duration!r} s / --T {args.T!r} s makes a "
                                f"log of {rows} samples: at most {MAX_LOG_ROWS}")
        for name in args.expect:
            if name not in ("m", "f_c", "f_s", "c"):
                raise IdentifyError(f"--expect: {name!r} is not one of m, f_c, f_s, c")
        problems = plant_problems({"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0,
                                   **args.expect})
        if problems:
            raise IdentifyError(f"--expect: {problems[0][1]}")
    return modes[0], names


def run(args: argparse.Namespace) -> int:
    """Identify a log, design the excitation, or identify an FMU; return 0."""
    from papwc.identify import require_scipy

    require_scipy("papwc identify")
    from papwc.identify.excitation import apply_to_fmu, check_fmu, design_plan
    from papwc.identify.fit import check_log, identify
    from papwc.identify.fit_report import (
        IdentifyFolder,
        write_excitation,
        write_identification,
        write_log,
    )
    from papwc.identify.log_file import Columns, check_travel, read_log
    from papwc.progress import Progress

    mode, deviations = _check(args)
    columns = Columns(args.time_column, args.force_column, args.position_column,
                      args.motor_column)
    log = None
    if mode == "LOG.csv":
        log = read_log(args.log, columns)
        check_travel(log, args.travel)
        check_log(log)  # no motion, no breakaway, too short: refused before anything is written
    if mode == "--fmu":
        # The master reads the FMU's log and says a refusal itself, in one line.
        os.environ["PAPWC_FMU_STDERR"] = "0"
        check_fmu(args.fmu, args.start_values, args.force_variable, args.position_variable)
    u = plan = None
    if mode != "LOG.csv":
        plan = design_plan(args.T, args.f_p_max, args.travel, args.duration, args.expect)
        u = plan.u
    planned = {"--design": ["excitation.csv"],
               "--fmu": ["excitation.csv", "log.csv"], "LOG.csv": []}[mode]
    if mode != "--design":
        planned += ["identified.csv", "plant.toml", "position.png", "residual.png",
                    "friction.png", "report.md"]
    folder = IdentifyFolder(args.out, planned)
    folder.start()
    command = "papwc identify " + " ".join(sys.argv[2:]) if len(sys.argv) > 2 else (
        "papwc identify")
    with Progress("papwc identify") as progress:
        try:
            if u is not None:
                write_excitation(folder.out / "excitation.csv", u, args.T)
                folder.wrote("excitation.csv")
                top = float(abs(u).max())
                print(f"wrote {folder.out / 'excitation.csv'}: {u.size} samples of "
                      f"{args.T:g} s ({u.size * args.T:.4g} s), |u| <= {top:.6g} N: "
                      f"{plan.summary()}")
            if mode == "--fmu":
                folder.mark("papwc identify is applying the excitation to the FMU")
                progress.doing(f"applying the excitation to {args.fmu}: {u.size} steps of "
                               f"{args.T:g} s")
                log = apply_to_fmu(args.fmu, u, args.T, args.start_values, args.force_variable,
                                   args.position_variable)
                write_log(folder.out / "log.csv", log)
                folder.wrote("log.csv")
                log.source = str(folder.out / "log.csv")
                check_travel(log, args.travel)
            if log is not None:
                folder.mark("papwc identify is fitting the plant")
                ident = identify(log, deviations, progress=progress.say)
                progress.done()
                if args.motor_column is not None:
                    ident.notes.append(f"the motor position (column {args.motor_column!r}) was "
                                       "read and checked; the flexible drive is not fitted")
                write_identification(folder, ident, command)
                for e in ident.estimates:
                    print(f"{e.name:<13} {e.value:>14.6g}  [{e.low:.6g}, {e.high:.6g}] {e.unit}")
                print("deviations chosen: " + (", ".join(ident.chosen) or "none"))
                if ident.band is not None:
                    b = ident.band
                    print(f"stiction band: breakaways seen {b.lowest:.6g} to {b.highest:.6g} N "
                          f"({b.sticks}); the next draws within {b.low:.6g} to {b.high:.6g} N")
                else:
                    print("stiction band: none (too few breakaways from rest; see report.md)")
                print(f"replay rms {ident.replay_rms:.3g} m (bound {ident.replay_bound:.3g} m); "
                      f"identified in {ident.seconds:.3g} s")
                print(f"wrote plant.toml, identified.csv, report.md and figures in {folder.out}")
            folder.finish()
        except KeyboardInterrupt:
            progress.done()
            print("papwc identify: interrupted; " + folder.abort("interrupted (Ctrl-C)"),
                  file=sys.stderr)
            raise
        except BaseException as exc:
            progress.done()
            print("papwc identify: stopped; " + folder.abort(f"stopped by an error: {exc}"),
                  file=sys.stderr)
            raise
    return 0
