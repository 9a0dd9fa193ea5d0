"""Measured figures printed by ``papwc bench``: a registry of sections.

A section is a function ``f(context) -> list[Row]`` registered with
:func:`register_section`; :func:`run_sections` calls every registered section
in order and prints its rows as a small table. Add a section by writing such a
function in any module imported by ``papwc.commands.bench`` and decorating it::

    @register_section("closed loop")
    def closed_loop(context: BenchContext) -> list[Row]:
        ...
        return [Row("master overhead per step", 12.3, "us")]

The FMUs a section needs are in ``context.fmu_dir`` (built once, before any FMU
is loaded into the process); ``context.quick`` asks for fewer iterations.

Timings on a shared machine are noisy, so sections measure the things they
compare in the same run, interleaved, and report medians over rounds.
"""

from __future__ import annotations

import gc
import statistics
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from papwc.errors import PapwcError

__all__ = [
    "SECTIONS",
    "BenchContext",
    "Row",
    "Section",
    "format_rows",
    "register_section",
    "run_sections",
]


@dataclass(frozen=True)
class Row:
    """One measured figure: what, how much, in which unit."""

    label: str
    value: float
    unit: str


@dataclass
class BenchContext:
    """What every section receives.

    Attributes
    ----------
    fmu_dir : Path
        Folder holding the built FMUs (``FrictionPlant.fmu``, ``PapwcTrivial.fmu``, ...).
    quick : bool
        Fewer iterations (a smoke run; the figures are less precise).
    notes : list of str
        Remarks a section adds; printed under its table.
    """

    fmu_dir: Path
    quick: bool = False
    notes: list[str] = field(default_factory=list)

    def fmu(self, name: str) -> Path:
        """Path of the FMU ``name`` (e.g. ``"FrictionPlant.fmu"``) in :attr:`fmu_dir`.

        Raises
        ------
        PapwcError
            If the FMU is not there.
        """
        path = self.fmu_dir / name
        if not path.is_file():
            raise PapwcError(f"bench: {name} not found in {self.fmu_dir}; run `papwc build` first")
        return path


@dataclass(frozen=True)
class Section:
    """A registered section: its title and the function that measures it."""

    title: str
    measure: Callable[[BenchContext], list[Row]]


#: Registered sections, in the order they run.
SECTIONS: list[Section] = []


def register_section(
    title: str,
) -> Callable[[Callable[[BenchContext], list[Row]]], Callable[[BenchContext], list[Row]]]:
    """Decorator: register ``f(context) -> list[Row]`` as a section titled ``title``."""

    def decorator(
        measure: Callable[[BenchContext], list[Row]],
    ) -> Callable[[BenchContext], list[Row]]:
        SECTIONS.append(Section(title, measure))
        return measure

    return decorator


def format_rows(rows: list[Row]) -> str:
    """Format rows as an aligned table, one line per row."""
    width = max((len(r.label) for r in rows), default=0)
    return "\n".join(f"  {r.label:<{width}}  {r.value:>10.4g}  {r.unit}" for r in rows)


def run_sections(
    context: BenchContext, sections: list[Section] | None = None, out: TextIO | None = None
) -> dict[str, list[Row]]:
    """Run sections (default: all registered) in order, printing each table as it is measured.

    Returns
    -------
    dict of str to list of Row
        The rows of each section, by title.
    """
    out = sys.stdout if out is None else out
    results = {}
    for section in SECTIONS if sections is None else sections:
        context.notes.clear()
        rows = section.measure(context)
        results[section.title] = rows
        print(f"{section.title}:", file=out)
        print(format_rows(rows), file=out)
        for note in context.notes:
            print(f"  note: {note}", file=out)
        print(file=out, flush=True)
    return results


# --- helpers for sections ------------------------------------------------------------------


@contextmanager
def _gc_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector inside a timed region."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _median_interleaved(
    loops: dict[str, Callable[[], float]], rounds: int
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Run every loop once per round, rotating the order; return medians and all rounds.

    Each loop returns its own cost per call (s).
    """
    names = list(loops)
    per_round = []
    for r in range(rounds):
        shift = r % len(names)
        measured = {}
        for name in names[shift:] + names[:shift]:
            measured[name] = loops[name]()
        per_round.append(measured)
    medians = {n: statistics.median(m[n] for m in per_round) for n in names}
    return medians, per_round


# --- section: the plant FMU against the trivial FMU -----------------------------------------

#: The plant's cost per call may be at most this multiple of the trivial FMU's.
PLANT_RATIO_GOAL = 1.3


def _plant_forces(n: int) -> list[float]:
    """A realistic ZOH force sequence (N): pulses above f_s, coasting, sticking, reversals."""
    cycle = [300.0] * 3 + [0.0] * 12 + [120.0] * 5 + [-280.0] * 4 + [0.0] * 6
    cycle += [250.0] * 5 + [-200.0] * 3 + [0.0] * 12
    return [cycle[k % len(cycle)] for k in range(n)]


def _fmpy_loop(fmu_path: Path, unzip_root: Path, input_name: str, output_name: str):
    """Instantiate an FMU with fmpy; return (loop(forces) -> s per call, close())."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu_path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipdir = extract(str(fmu_path), str(unzip_root / fmu_path.stem))
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=fmu_path.stem,
    )
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    vr_in, vr_out = [vr[input_name]], [vr[output_name]]
    clock = {"t": 0.0, "k": 0}
    h = 0.01

    def loop(forces: list[float]) -> float:
        set_real, do_step, get_real = slave.setReal, slave.doStep, slave.getReal
        k0 = clock["k"]
        with _gc_paused():
            start = time.perf_counter_ns()
            for i, u in enumerate(forces):
                set_real(vr_in, [u])
                do_step((k0 + i) * h, h)
                get_real(vr_out)
            elapsed = time.perf_counter_ns() - start
        clock["k"] = k0 + len(forces)
        return elapsed * 1e-9 / len(forces)

    def close() -> None:
        slave.terminate()
        slave.freeInstance()

    return loop, close


def _direct_loop() -> Callable[[list[float]], float]:
    """Return loop(forces) -> s per call of papwc_stickslip.step, state carried over."""
    from papwc.model.stickslip import step

    state = [0.0, 0.0]

    def loop(forces: list[float]) -> float:
        x, v = state
        with _gc_paused():
            start = time.perf_counter_ns()
            for u in forces:
                x, v = step(x, v, u, 0.01, 150.0, 100.0, 130.0, 700.0)
            elapsed = time.perf_counter_ns() - start
        state[:] = [x, v]
        return elapsed * 1e-9 / len(forces)

    return loop


@register_section("FrictionPlant.fmu: cost of one setReal + doStep + getReal (fmpy FMU2Slave)")
def plant_step_cost(context: BenchContext) -> list[Row]:
    """Cost per call on FrictionPlant.fmu beside PapwcTrivial.fmu and the bare physics step."""
    n_calls, rounds = (1_000, 5) if context.quick else (20_000, 11)
    forces = _plant_forces(n_calls)
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        plant, close_plant = _fmpy_loop(context.fmu("FrictionPlant.fmu"), Path(tmp), "u", "x")
        trivial, close_trivial = _fmpy_loop(context.fmu("PapwcTrivial.fmu"), Path(tmp), "u", "y")
        direct = _direct_loop()
        try:
            for loop in (plant, trivial, direct):  # warm-up
                loop(forces[: max(100, n_calls // 10)])
            medians, per_round = _median_interleaved(
                {
                    "plant": lambda: plant(forces),
                    "trivial": lambda: trivial(forces),
                    "direct": lambda: direct(forces),
                },
                rounds,
            )
        finally:
            close_plant()
            close_trivial()
    ratio = statistics.median(m["plant"] / m["trivial"] for m in per_round)
    verdict = "met" if ratio <= PLANT_RATIO_GOAL else "MISSED"
    context.notes.append(
        f"{rounds} interleaved rounds of {n_calls} calls each; medians; "
        f"ratio = median of the per-round ratios; goal {verdict}"
    )
    return [
        Row("FrictionPlant.fmu", medians["plant"] * 1e6, "us/call"),
        Row("PapwcTrivial.fmu (wrapper floor)", medians["trivial"] * 1e6, "us/call"),
        Row("papwc_stickslip.step, direct", medians["direct"] * 1e6, "us/call"),
        Row("ratio FrictionPlant / PapwcTrivial", ratio, "x"),
        Row(f"goal: ratio at most ({verdict})", PLANT_RATIO_GOAL, "x"),
    ]


# --- section: the master's closed-loop step against a bare plant step ------------------------

#: A closed-loop step may cost at most this multiple of a bare plant step.
MASTER_RATIO_GOAL = 2.0


@register_section("Master: closed-loop step (PAPWC + recording) against a bare plant step")
def master_overhead(context: BenchContext) -> list[Row]:
    """Cost per sample of ``run_iteration`` beside stepping the same FMU with the same forces."""
    from papwc.controllers.settings import ControllerSettings
    from papwc.master import FmuSlave, Maneuver, run_controller

    iterations, rounds = (2, 3) if context.quick else (10, 7)
    maneuver = Maneuver(x_ref=0.01, T=0.01, duration=2.0, iterations=iterations)
    settings = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8)
    n = maneuver.n_steps * iterations
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        plant = FmuSlave(context.fmu("FrictionPlant.fmu"), unzip_dir=_extract(context, tmp))
        try:
            plant.set_parameters({"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0})
            forces: list[float] = []

            def closed_loop() -> float:
                with _gc_paused():
                    start = time.perf_counter_ns()
                    result = run_controller(plant, settings, maneuver)
                    elapsed = time.perf_counter_ns() - start
                forces[:] = [u for tr in result.traces for u in tr.column("u")[:-1]]
                return elapsed * 1e-9 / n

            def bare() -> float:
                T = maneuver.T
                set_input, do_step, get_outputs = plant.set_input, plant.do_step, plant.get_outputs
                with _gc_paused():
                    start = time.perf_counter_ns()
                    for it in range(iterations):
                        plant.restart(0.0)
                        for k in range(maneuver.n_steps):
                            get_outputs()
                            set_input(forces[it * maneuver.n_steps + k])
                            do_step(k * T, T)
                    elapsed = time.perf_counter_ns() - start
                return elapsed * 1e-9 / n

            closed_loop()  # warm-up, and the force sequence the bare loop replays
            medians, per_round = _median_interleaved(
                {"closed": closed_loop, "bare": bare}, rounds
            )
        finally:
            plant.close()
    ratio = statistics.median(m["closed"] / m["bare"] for m in per_round)
    verdict = "met" if ratio <= MASTER_RATIO_GOAL else "MISSED"
    context.notes.append(
        f"{rounds} interleaved rounds of {iterations} iterations x {maneuver.n_steps} steps; "
        f"bare = get outputs + set u + doStep with the forces the controller produced; "
        f"goal {verdict}"
    )
    return [
        Row("closed-loop step (master + PAPWC + recording)", medians["closed"] * 1e6, "us/step"),
        Row("bare plant step (FmuSlave)", medians["bare"] * 1e6, "us/step"),
        Row("ratio closed loop / bare", ratio, "x"),
        Row(f"goal: ratio at most ({verdict})", MASTER_RATIO_GOAL, "x"),
    ]


def _extract(context: BenchContext, tmp: str) -> str:
    from fmpy import extract

    return extract(str(context.fmu("FrictionPlant.fmu")), str(Path(tmp) / "plant"))


@register_section("Battery: runs per second, local pool (1 and 2 workers) and Dask")
def battery_throughput(context: BenchContext) -> list[Row]:
    """Battery throughput; measured by :func:`papwc.battery.bench_section`."""
    from papwc.battery import bench_section

    return bench_section(context)
