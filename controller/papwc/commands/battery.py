"""``papwc battery``: run sweeps and Monte Carlo batteries of a scenario in parallel.

The battery file syntax is described in :mod:`papwc.battery`.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import shlex
import sys
from collections.abc import Iterator
from pathlib import Path

from papwc.commands import add_fmu_option

HELP = "run a battery (sweep and/or Monte Carlo) of a scenario on local processes or Dask"

EPILOG = """\
examples:
  papwc battery scenarios/robustness.toml                 # all cores, results/robustness/
  papwc battery scenarios/robustness.toml --workers 2 --out results/rob
  papwc battery scenarios/robustness.toml --out results/rob --resume   # after Ctrl-C or a kill
  papwc battery a.toml b.toml --out results/ab --quiet    # two batteries, one results.csv
  papwc battery scenarios/realism_mc.toml --seed-offset 1000 --out results/mc_oos
  papwc spec results/realism_mc results/mc_oos      # tuned and out of sample side by side
  dask scheduler --host 127.0.0.1 --port 8786 --no-dashboard &
  dask worker tcp://127.0.0.1:8786 --nworkers 2 --nthreads 1 --no-dashboard &
  papwc battery scenarios/robustness.toml --scheduler tcp://127.0.0.1:8786

writes into the output folder: results.csv (one row per run, controller and
iteration), runs.csv (every resolved parameter per run), pulses.csv (every pulse
and its bound), spec.csv (the spec's figures and verdicts), summary.md, the plots
final_error_<battery>.png, and journal.jsonl (finished runs, for --resume).
exit code: 0 if every run succeeded in running, 1 if a run has status error
(or a file cannot be written), 2 if a battery file or an option is wrong, 130
if interrupted (Ctrl-C: the runs that finished are in the journal; the message
says how to resume). A run longer than [battery] run_timeout (default 600 s)
is stopped and recorded as "timed out"; --resume computes it again.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc battery`` to its subparser."""
    parser.add_argument("files", nargs="+", metavar="FILE", help="battery files (TOML)")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="output folder (default: results/NAME for one battery, "
                             "results/battery for several)")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="local worker processes (default: the number of cores)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run on this Dask distributed scheduler instead of local processes")
    add_fmu_option(parser)
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--resume", action="store_true",
                      help="continue the journal in DIR: finished runs are not computed again")
    mode.add_argument("--overwrite", action="store_true",
                      help="start afresh even if DIR holds the journal of a battery")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress bar and no report on stdout")
    from papwc.commands.run import add_controllers_option, add_max_steps, positive_int
    from papwc.limits import MAX_RUNS

    parser.add_argument("--max-runs", type=positive_int, default=MAX_RUNS, metavar="N",
                        help="refuse batteries of more than N runs or grid points together "
                             f"(default {MAX_RUNS})")
    add_max_steps(parser)
    from papwc.limits import whole_number
    from papwc.model.plant import PLANT_PARAMETERS

    seed_max = next(v.max for v in PLANT_PARAMETERS if v.name == "seed")
    parser.add_argument("--seed-offset", type=whole_number(0, int(seed_max)), default=0,
                        metavar="N",
                        help="add N to every seed: the Monte Carlo draws' seed, each run's "
                             "plant.seed and maneuver.noise_seed (judge a controller on "
                             "tables it was not tuned on; compare with `papwc spec`); "
                             "default 0, the file's own")
    add_controllers_option(parser)


#: Largest ``--workers`` per core this process may run on.
WORKERS_PER_CORE = 4
#: A Dask scheduler address: ``[tcp|tls|ws|wss|ucx]://HOST:PORT`` or ``HOST:PORT``.
SCHEDULER_ADDRESS = re.compile(r"((tcp|tls|ws|wss|ucx)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)"
                               r":[0-9]{1,5}")


def run(args: argparse.Namespace) -> int:
    """Run the batteries; return 0, or 1 if any run has status error."""
    from papwc.battery import BatteryError, load_battery, run_battery
    from papwc.battery.engines import default_workers
    from papwc.battery.orchestrate import BatteryInterrupted
    from papwc.scenario_run import ensure_plant_fmu

    if args.workers is not None:
        most = WORKERS_PER_CORE * default_workers()
        if not 1 <= args.workers <= most:
            raise BatteryError(f"--workers {args.workers}: must be from 1 to {most} "
                               f"({WORKERS_PER_CORE} per core)")
    if args.scheduler is not None and not SCHEDULER_ADDRESS.fullmatch(args.scheduler):
        raise BatteryError(f"--scheduler {args.scheduler!r}: not a Dask scheduler address; "
                           "write tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786)")
    batteries = [load_battery(f) for f in args.files]
    for battery in batteries:
        battery.seed_offset = args.seed_offset
    from papwc.battery.plan import check_size

    check_size(batteries, args.max_runs)
    if args.scheduler is not None:
        from papwc.battery.engines import check_scheduler

        check_scheduler(args.scheduler)  # before anything is written
    out = args.out
    if out is None:
        out = Path("results") / (batteries[0].name if len(batteries) == 1 else "battery")
    fmu = ensure_plant_fmu(args.fmu, out)
    from papwc.scenario_run import controller_fmu as controllers_fmu

    controller_fmu = controllers_fmu(args.controllers, out)
    try:
        with _sigterm_as_interrupt():
            outcome = run_battery(batteries, out, fmu, workers=args.workers,
                                  scheduler=args.scheduler, resume=args.resume,
                                  overwrite=args.overwrite, progress=not args.quiet,
                                  max_runs=args.max_runs, max_steps=args.max_steps,
                                  controller_fmu=controller_fmu)
    except BatteryInterrupted as stop:
        again = " ".join(shlex.quote(str(f)) for f in args.files)
        from papwc.limits import MAX_RUNS, MAX_STEPS

        # every option that changes what runs, so that the line runs verbatim
        extra = "".join(f" {flag} {shlex.quote(str(value))}" for flag, value in (
            ("--fmu", args.fmu), ("--scheduler", args.scheduler), ("--workers", args.workers),
            ("--max-runs", args.max_runs if args.max_runs != MAX_RUNS else None),
            ("--max-steps", args.max_steps if args.max_steps != MAX_STEPS else None),
            ("--seed-offset", args.seed_offset or None),
            ("--controllers", args.controllers if args.controllers != "auto" else None))
            if value is not None) + (" --quiet" if args.quiet else "")
        what = "terminated (SIGTERM)" if _TERMINATED["by"] else "interrupted"
        print(f"papwc battery: {what}: {stop.done} of {stop.total} runs are in the "
              f"journal {stop.journal}; to finish, run: papwc battery {again} --out "
              f"{shlex.quote(str(out))}{extra} --resume", file=sys.stderr)
        if _TERMINATED["by"]:
            from papwc.interrupts import Terminated

            raise Terminated from None
        raise
    warned = sum(1 for r in outcome.records.values()
                 if r["status"] == "ok" and r["message"].startswith("warning:"))
    if warned:
        first = next(r for r in outcome.records.values()
                     if r["status"] == "ok" and r["message"].startswith("warning:"))
        print(f"warning: {warned} run(s) have warnings (see results.csv), e.g. "
              f"{first['battery']} {first['run_id']}: {first['message'][9:]}", file=sys.stderr)
    if not args.quiet:
        reused = outcome.runs - outcome.computed
        print(f"{outcome.runs} runs ({outcome.computed} computed, {reused} from the journal) "
              f"in {outcome.seconds:.1f} s; {len(outcome.failed)} with status error")
        print("wrote " + ", ".join(str(p) for p in outcome.files))
    for battery, run_id, message in outcome.failed[:10]:
        print(f"error: {battery} {run_id}: {message}", file=sys.stderr)
    if len(outcome.failed) > 10:
        print(f"error: ... and {len(outcome.failed) - 10} more runs (see results.csv)",
              file=sys.stderr)
    return 1 if outcome.failed else 0


#: Whether SIGTERM stopped the battery (see :func:`_sigterm_as_interrupt`).
_TERMINATED = {"by": False}


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM stops a battery as Ctrl-C does: the journal kept, the resume line printed.

    (Only where SIGTERM has its default action, in the main thread.)
    """
    import signal
    import threading

    _TERMINATED["by"] = False
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) != signal.SIG_DFL):
        yield
        return

    def handler(signum, frame) -> None:
        _TERMINATED["by"] = True
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
