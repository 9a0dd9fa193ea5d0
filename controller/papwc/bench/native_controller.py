"""``papwc bench`` sections: the C controller (native PulseController.fmu, controller.c).

- *closed-loop step*: the master's closed loop (PAPWC on the Table 1 plant, recording
  included) with both native FMUs, against the plant FMU's step alone as a host calls it
  (fmpy's ``FMU2Slave`` setReal + doStep + getReal, the basis of master_step's goal) and as
  the master calls it (set + doStep + read of the trace's columns), with the loop's forces,
  interleaved in one run; beside it the loop with the C controller in process, with the
  Python controller, and with PulseControllerPython.fmu;
- *worst update in a C host*: ``fmu_src/PulseController/example/update_time.c`` (the C
  controller and the C plant, compiled here with the system C compiler or zig) closes the
  loop of every run of scenarios/realism.toml for the kinds the C controller implements and
  times each ``pc_update`` on the thread's CPU clock, each run 3 times (the smallest of its
  3 longest updates: a preemption or a page fault of one repetition aside); the longest
  as a fraction of the sample period T;
- *realism battery* (``papwc bench --realism``): scenarios/realism.toml on 2 workers with
  the C controllers and with the Python controllers; the factor, and results.csv the same.
"""

from __future__ import annotations

import math
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from papwc.bench import BenchContext, Row, gc_paused, median_interleaved, register_section
from papwc.errors import PapwcError

#: The clock of the closed-loop section: CPU time of this thread, ns (every call it times
#: runs in this thread).
_timer = time.thread_time_ns

#: A closed-loop step with both native FMUs may cost at most this multiple of the plant
#: FMU's step alone.
NATIVE_LOOP_GOAL = 1.5
#: The C controller's longest update may take at most this fraction of the sample period.
UPDATE_FRACTION_GOAL = 0.01
#: Table 1 of the paper, and the paper's PAPWC (t_p_max = 0.03 s).
_PLANT = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}


def _settings():
    from papwc.controllers.settings import ControllerSettings

    return ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8)


@register_section("C controller: closed-loop step with both native FMUs against the plant "
                  "FMU's step alone (master, PAPWC + recording)")
def native_closed_loop(context: BenchContext) -> list[Row]:
    """Cost per sample of :func:`papwc.master.run_closed_loop` through FrictionPlant.fmu with
    each controller, and of the plant FMU alone stepped by the master with the same forces;
    interleaved rounds, medians of the per-round ratios."""
    from papwc.bench.plant_calls import fmpy_loop
    from papwc.controllers import make_controller
    from papwc.master import FmuSlave, Maneuver, run_closed_loop
    from papwc.master.native_controller import NativeControllerSlave, fmu_controller_library
    from papwc.master.slave import ControllerSlave
    from papwc.master.trace import PLANT_COLUMNS
    from papwc.model.controller_settings import fmu_parameters

    iterations, rounds = (2, 3) if context.quick else (10, 9)
    maneuver = Maneuver(x_ref=0.01, T=0.01, duration=2.0, iterations=iterations)
    settings = _settings()
    n = maneuver.n_steps * iterations
    library = fmu_controller_library(context.fmu("PulseController.fmu"))
    if library is None:
        raise PapwcError("bench: PulseController.fmu has no C controller for this platform")
    start_values = {**fmu_parameters(settings.to_mapping(with_none=True)), "T": maneuver.T}
    plant = FmuSlave(context.fmu("FrictionPlant.fmu"))
    alone = FmuSlave(context.fmu("FrictionPlant.fmu"), name="alone")
    fmus = {name: FmuSlave(context.fmu(f"{name}.fmu"), name="controller",
                           restart_input="maneuver")
            for name in ("PulseController", "PulseControllerPython")}
    forces: list[float] = []
    tmp = tempfile.TemporaryDirectory(prefix="papwcbench")
    fmpy, close_fmpy = fmpy_loop(context.fmu("FrictionPlant.fmu"), Path(tmp.name), "u", "x",
                                 _timer)
    try:
        for slave in (plant, alone):
            slave.set_start_values(_PLANT)
        for slave in fmus.values():
            slave.set_start_values(start_values)

        def loop(make: Callable[[], object], keep: bool = False) -> Callable[[], float]:
            def measure() -> float:
                controller = make()
                with gc_paused():
                    start = _timer()
                    result = run_closed_loop(plant, controller, maneuver, settings)
                    elapsed = _timer() - start
                if result.error:
                    raise PapwcError(f"bench closed loop failed: {result.error}")
                if keep:
                    forces[:] = [u for tr in result.traces for u in tr.column("u")[:-1]]
                return elapsed * 1e-9 / n

            return measure

        def plant_alone() -> float:
            """The plant FMU stepped by the master with the loop's forces: set u, doStep,
            read what the trace reads."""
            alone.watch([c for c in PLANT_COLUMNS if c in alone.variables()])
            set_u = alone.input_setter(["u"])
            h = maneuver.T
            do_step = alone.do_step
            with gc_paused():
                start = _timer()
                for i in range(iterations):
                    alone.initialize(0.0) if i == 0 else alone.restart(0.0)
                    for k, u in enumerate(forces[i * maneuver.n_steps:
                                                 (i + 1) * maneuver.n_steps]):
                        set_u(u)
                        do_step(k * h, h)
                elapsed = _timer() - start
            return elapsed * 1e-9 / len(forces)

        loops = {
            "native FMUs": loop(lambda: fmus["PulseController"], keep=True),
            "fmpy plant": lambda: fmpy(forces),
            "plant alone": plant_alone,
            "C in process": loop(lambda: NativeControllerSlave(library, settings, maneuver.T)),
            "Python in process": loop(lambda: ControllerSlave(make_controller(settings,
                                                                              maneuver.T))),
            "pythonfmu FMU": loop(lambda: fmus["PulseControllerPython"]),
        }
        loops["native FMUs"]()  # warm-up, and the forces the plant alone replays
        medians, per_round = median_interleaved(loops, rounds)
    finally:
        for slave in (plant, alone, *fmus.values()):
            slave.close()
        close_fmpy()
        tmp.cleanup()

    def ratio(name: str, base: str = "fmpy plant") -> float:
        return statistics.median(m[name] / m[base] for m in per_round)

    native = ratio("native FMUs")
    verdict = "met" if native <= NATIVE_LOOP_GOAL else "MISSED"
    context.notes.append(
        f"{rounds} interleaved rounds of {iterations} iterations x {maneuver.n_steps} steps "
        "(PAPWC, t_p_max = 0.03 s, on Table 1's plant; immediate timing); the plant's step "
        "alone: fmpy's FMU2Slave setReal + doStep + getReal (the goal's basis), and the "
        "master's set u + doStep + read of the trace's plant columns, with the loop's forces; "
        f"CPU time of this thread; ratios = medians of per-round ratios; goal {verdict}")
    return [
        Row("closed-loop step, both native FMUs", medians["native FMUs"] * 1e6, "us/step"),
        Row("plant FMU's step alone, fmpy setReal + doStep + getReal",
            medians["fmpy plant"] * 1e6, "us/step"),
        Row("ratio both native FMUs / plant alone (fmpy)", native, "x"),
        Row(f"goal: ratio at most ({verdict})", NATIVE_LOOP_GOAL, "x"),
        Row("ratio, C controller in process / plant alone (fmpy)", ratio("C in process"), "x"),
        Row("ratio, Python controller in process / plant alone (fmpy)",
            ratio("Python in process"), "x"),
        Row("ratio, PulseControllerPython.fmu / plant alone (fmpy)", ratio("pythonfmu FMU"),
            "x"),
        Row("plant FMU's step alone, the master's set + doStep + read",
            medians["plant alone"] * 1e6, "us/step"),
        Row("ratio both native FMUs / plant alone (master)",
            ratio("native FMUs", "plant alone"), "x"),
    ]


# --- the worst update in a C host ----------------------------------------------------------------

def build_update_timer(folder: Path) -> Path:
    """Compile ``example/update_time.c`` with the C controller and the C plant into
    ``folder`` (the generated headers written there); the program's path."""
    from papwc.fmubuild.native_build import C_FLAGS, host_compiler
    from papwc.fmubuild.native_tables import write_controller_header, write_plant_header
    from papwc.resources import fmu_src_dir

    src = fmu_src_dir()
    write_controller_header(folder)
    write_plant_header(folder)
    program = folder / ("update_time.exe" if sys.platform == "win32" else "update_time")
    flags = [f for f in C_FLAGS if f != "-fvisibility=hidden"]
    compiler = host_compiler()
    if compiler is None:
        raise PapwcError("bench: no C compiler (PAPWC_CC, cc, gcc, clang or pip ziglang)")
    command = [*compiler, *flags, "-I", str(folder), "-I", str(src / "PulseController"),
               "-I", str(src / "FrictionPlant"), "-o", str(program),
               str(src / "PulseController" / "example" / "update_time.c"),
               str(src / "PulseController" / "controller.c"),
               str(src / "FrictionPlant" / "plant.c"), "-lm"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    if done.returncode != 0:
        raise PapwcError(f"bench: cannot compile update_time.c: {done.stderr.strip()[-2000:]}")
    return program


def realism_input(seeds: tuple[int, ...] | None = None) -> tuple[str, int]:
    """The runs of scenarios/realism.toml for the kinds the C controller implements, as
    update_time.c reads them (with ``seeds``: those plant seeds only); (text, runs)."""
    from papwc.battery.plan import plan_runs
    from papwc.battery.schema import load_battery
    from papwc.fmubuild.native_tables import NATIVE_KINDS
    from papwc.master.native_controller import PcSettings, settings_struct
    from papwc.model.plant import PLANT_DEFAULTS
    from papwc.resources import scenario_file
    from papwc.scenario import parse_scenario

    lines, count = [], 0
    for run in plan_runs([load_battery(scenario_file("realism.toml"))]):
        scenario = parse_scenario(run.data, run.run_id)
        if seeds is not None and scenario.plant.get("seed", PLANT_DEFAULTS["seed"]) not in seeds:
            continue
        m = scenario.maneuver
        for s, label in zip(scenario.controllers, scenario.labels, strict=True):
            if s.kind not in NATIVE_KINDS:
                continue
            lines.append(f"run {run.run_id.replace(' ', '_')}/{label} {m.T!r} {m.n_steps} "
                         f"{m.iterations} {m.x_ref!r}")
            lines += [f"p {name} {float(value)!r}" for name, value in scenario.plant.items()]
            c = settings_struct(s)
            lines += [f"s {name} {float(getattr(c, name))!r}" for name, _ in PcSettings._fields_]
            lines.append("end")
            count += 1
    return "\n".join(lines) + "\n", count


@register_section("C controller: its longest update as a fraction of T on realism.toml's "
                  "runs (a C host: example/update_time.c)")
def worst_update(context: BenchContext) -> list[Row]:
    """The longest ``pc_update`` over every sample of the realism runs (quick: plant seed 1),
    timed by the C host with the monotonic clock."""
    seeds = (1,) if context.quick else None
    text, runs = realism_input(seeds)
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        program = build_update_timer(Path(tmp))
        done = subprocess.run([str(program)], input=text, capture_output=True, text=True,
                              timeout=3600, check=False)
    if done.returncode != 0:
        raise PapwcError(f"bench: update_time failed: {done.stderr.strip()[-2000:]}")
    worst = total = updates = 0
    worst_run, tick = "", 0
    for line in done.stdout.splitlines():
        fields = line.split()
        if fields[0] == "clock":
            tick = int(fields[1])
            continue
        if int(fields[1]) > worst:
            worst, worst_run = int(fields[1]), fields[0]
        total += int(fields[2])
        updates += int(fields[3])
    T = 0.01  # realism.toml's sample period
    fraction = worst * 1e-9 / T
    verdict = "met" if fraction <= UPDATE_FRACTION_GOAL else "MISSED"
    context.notes.append(
        f"{runs} runs (case x target x seed x controller of the kinds pwc, papwc, pid), "
        f"{updates} updates; the longest in {worst_run}; this thread's CPU clock (step "
        f"{tick} ns), each run 3 times, a run's longest the smallest of its 3")
    return [
        Row("longest update", worst * 1e-3, "us"),
        Row("mean update", total / max(updates, 1) * 1e-3, "us"),
        Row("longest update / T", fraction * 100.0, "% of T"),
        Row(f"goal: at most ({verdict})", UPDATE_FRACTION_GOAL * 100.0, "% of T"),
    ]


# --- the realism battery --------------------------------------------------------------------------

@register_section("C controller: scenarios/realism.toml on 2 local workers, C controllers "
                  "against the Python controllers", option="realism")
def realism_controllers(context: BenchContext) -> list[Row]:
    """Run scenarios/realism.toml on 2 workers with the C controllers (pwc, papwc, pid) and
    with the Python controllers, the native plant both times; compare results.csv."""
    from papwc.battery import BatteryError, load_battery, run_battery
    from papwc.resources import scenario_file

    battery = load_battery(scenario_file("realism.toml"))
    walls, cpus, results, outcomes = {}, {}, {}, {}
    for build, controller_fmu in (("Python", None), ("C", context.fmu("PulseController.fmu"))):
        with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
            start = time.perf_counter()
            outcomes[build] = run_battery([battery], Path(tmp), context.fmu("FrictionPlant.fmu"),
                                          workers=2, progress=False,
                                          controller_fmu=controller_fmu)
            walls[build] = time.perf_counter() - start
            cpus[build] = sum(r.get("cpu_s", math.nan) for r in outcomes[build].records.values())
            results[build] = (Path(tmp) / "results.csv").read_bytes()
        if outcomes[build].computed != outcomes[build].runs:
            raise BatteryError("bench realism: not every run was computed")
    same = results["C"] == results["Python"]
    context.notes.append(
        f"{outcomes['C'].runs} runs; wall time of run_battery (planning, workers, report); CPU "
        "time: the workers' over the runs (each run's process time, the journal's cpu_s: a "
        "shared machine's load does not count there); the exact controller is Python in "
        "both; Python controllers first")
    return [
        Row("wall time, Python controllers", walls["Python"], "s"),
        Row("wall time, C controllers", walls["C"], "s"),
        Row("runs' CPU time, Python controllers", cpus["Python"], "s"),
        Row("runs' CPU time, C controllers", cpus["C"], "s"),
        Row("factor Python / C (runs' CPU time)", cpus["Python"] / cpus["C"], "x"),
        Row("factor Python / C (wall time)", walls["Python"] / walls["C"], "x"),
        Row("results.csv byte for byte the same (1 yes)", float(same), ""),
    ]
