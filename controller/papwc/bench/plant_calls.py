"""``papwc bench`` section: the plant FMU's cost per call against the floor pythonfmu sets."""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from papwc.bench import BenchContext, Row, gc_paused, median_interleaved, register_section

#: The plant's cost per call may be at most this multiple of the trivial FMU's.
PLANT_RATIO_GOAL = 1.3


def plant_forces(n: int) -> list[float]:
    """A realistic ZOH force sequence (N): pulses above f_s, coasting, sticking, reversals."""
    cycle = [300.0] * 3 + [0.0] * 12 + [120.0] * 5 + [-280.0] * 4 + [0.0] * 6
    cycle += [250.0] * 5 + [-200.0] * 3 + [0.0] * 12
    return [cycle[k % len(cycle)] for k in range(n)]


def fmpy_loop(fmu_path: Path, unzip_root: Path, input_name: str, output_name: str,
              timer: Callable[[], int] = time.perf_counter_ns,
              ) -> tuple[Callable[[list[float]], float], Callable[[], None]]:
    """Instantiate an FMU with fmpy; return (loop(forces) -> s per call, close()).

    ``timer`` is the clock in ns (default: wall time, ``time.perf_counter_ns``).
    """
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
    return slave_methods_loop(slave, [vr[input_name]], [vr[output_name]], {"k": 0}, 0.01,
                              timer)


def slave_methods_loop(slave: Any, vr_in: list[int], vr_out: list[int], clock: dict[str, int],
                       h: float, timer: Callable[[], int] = time.perf_counter_ns,
                       ) -> tuple[Callable[[list[float]], float], Callable[[], None]]:
    """(loop(forces) -> s per step, close()) of an initialized fmpy ``FMU2Slave``.

    Each step is ``setReal(vr_in, [u])``, ``doStep(t, h)``, ``getReal(vr_out)`` through the
    slave's methods, as a script calls them; ``clock["k"]`` counts the steps taken so far;
    ``timer`` is the clock in ns.
    """

    def loop(forces: list[float]) -> float:
        set_real, do_step, get_real = slave.setReal, slave.doStep, slave.getReal
        k0 = clock["k"]
        with gc_paused():
            start = timer()
            for i, u in enumerate(forces):
                set_real(vr_in, [u])
                do_step((k0 + i) * h, h)
                get_real(vr_out)
            elapsed = timer() - start
        clock["k"] = k0 + len(forces)
        return elapsed * 1e-9 / len(forces)

    def close() -> None:
        slave.terminate()
        slave.freeInstance()

    return loop, close


def _direct_loop() -> Callable[[list[float]], float]:
    """Return loop(forces) -> s per call of papwc.model.stickslip.step, state carried over."""
    from papwc.model.stickslip import step

    state = [0.0, 0.0]

    def loop(forces: list[float]) -> float:
        x, v = state
        with gc_paused():
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
    forces = plant_forces(n_calls)
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        plant, close_plant = fmpy_loop(context.fmu("FrictionPlant.fmu"), Path(tmp), "u", "x")
        trivial, close_trivial = fmpy_loop(context.fmu("PapwcTrivial.fmu"), Path(tmp), "u", "y")
        direct = _direct_loop()
        try:
            for loop in (plant, trivial, direct):  # warm-up
                loop(forces[: max(100, n_calls // 10)])
            medians, per_round = median_interleaved(
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
        Row("papwc.model.stickslip.step, direct", medians["direct"] * 1e6, "us/call"),
        Row("ratio FrictionPlant / PapwcTrivial", ratio, "x"),
        Row(f"goal: ratio at most ({verdict})", PLANT_RATIO_GOAL, "x"),
    ]


def realism_plants() -> dict[str, dict[str, float]]:
    """Plant parameters of each case of ``scenarios/realism.toml``, by case name."""
    from papwc.battery import load_battery
    from papwc.resources import scenario_file

    battery = load_battery(scenario_file("realism.toml"))
    base = dict(battery.data.get("plant", {}))
    return {name: {**base, **{path.split(".", 1)[1]: value for path, value in overrides.items()
                              if path.startswith("plant.")}}
            for name, overrides in battery.cases}


def _plant_loop(params: dict[str, float]) -> Callable[[list[float]], float]:
    """Return loop(forces) -> s per :meth:`papwc.model.dynamics.Plant.step`, state carried over."""
    from papwc.model.dynamics import Plant

    plant = Plant(params)
    step = plant.step

    def loop(forces: list[float]) -> float:
        with gc_paused():
            start = time.perf_counter_ns()
            for u in forces:
                reason = step(u, 0.01)
                if reason is not None:
                    raise RuntimeError(f"bench plant {params}: step refused: {reason}")
            elapsed = time.perf_counter_ns() - start
        return elapsed * 1e-9 / len(forces)

    return loop


@register_section("FrictionPlant deviations: cost of one 10 ms step (model layer, in process)")
def deviation_step_cost(context: BenchContext) -> list[Row]:
    """Cost of one communication step of each case of ``scenarios/realism.toml``.

    The model layer's :class:`~papwc.model.dynamics.Plant` (what FrictionPlant.fmu
    and the master's in-process plant step) under :func:`plant_forces`, each case
    beside the exact plant (case ``exact``: :func:`papwc.model.stickslip.step`),
    interleaved over rounds; medians.
    """
    n_steps, rounds = (200, 1) if context.quick else (1_000, 3)
    forces = plant_forces(n_steps)
    plants = realism_plants()
    loops = {name: _plant_loop(params) for name, params in plants.items()}
    for loop in loops.values():  # warm-up
        loop(forces[:50])
    medians, per_round = median_interleaved(
        {name: (lambda loop=loop: loop(forces)) for name, loop in loops.items()}, rounds)
    exact = "exact" if "exact" in medians else next(iter(medians))
    context.notes.append(
        f"{rounds} interleaved round(s) of {n_steps} steps of 10 ms each (the forces of the "
        "FrictionPlant.fmu row: pulses, coasting, sticking, reversals), every case's state "
        "carried over; parameters of the cases of scenarios/realism.toml; the FMU adds its "
        "per-call cost (rows above) to each")
    rows = []
    for name, cost in medians.items():
        ratio = statistics.median(m[name] / m[exact] for m in per_round)
        rows.append(Row(f"{name}: Plant.step", cost * 1e6, "us/step"))
        if name != exact:
            rows.append(Row(f"{name}: ratio to {exact}", ratio, "x"))
    return rows
