"""``papwc bench`` section: the master's closed-loop step against fmpy's per-call cost."""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from papwc.bench import BenchContext, Row, gc_paused, median_interleaved, register_section
from papwc.bench.plant_calls import fmpy_loop

#: A closed-loop step of the master (controller and recording included) may cost at most
#: this multiple of fmpy's FMU2Slave.setReal + doStep + getReal on the same FMU.
MASTER_RATIO_GOAL = 1.0


@register_section("Master: closed-loop step (PAPWC + recording) against fmpy's "
                  "setReal + doStep + getReal")
def master_step_cost(context: BenchContext) -> list[Row]:
    """Cost per sample of :func:`papwc.master.run_controller` through FrictionPlant.fmu.

    Beside it, interleaved in the same run: fmpy's ``FMU2Slave.setReal([u]) +
    doStep + getReal([x])`` on the same FMU with the forces the controller
    produced.
    """
    from papwc.controllers.settings import ControllerSettings
    from papwc.master import FmuSlave, Maneuver, run_controller

    iterations, rounds = (2, 3) if context.quick else (10, 9)
    maneuver = Maneuver(x_ref=0.01, T=0.01, duration=2.0, iterations=iterations)
    settings = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8)
    n = maneuver.n_steps * iterations
    fmu = context.fmu("FrictionPlant.fmu")
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        plant = FmuSlave(fmu)
        fmpy, close_fmpy = fmpy_loop(fmu, Path(tmp), "u", "x")
        try:
            plant.set_start_values({"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0})
            forces: list[float] = []

            def closed_loop() -> float:
                with gc_paused():
                    start = time.perf_counter_ns()
                    result = run_controller(plant, settings, maneuver)
                    elapsed = time.perf_counter_ns() - start
                forces[:] = [u for tr in result.traces for u in tr.column("u")[:-1]]
                return elapsed * 1e-9 / n

            closed_loop()  # warm-up, and the forces fmpy replays
            fmpy(forces)
            medians, per_round = median_interleaved(
                {"master": closed_loop, "fmpy": lambda: fmpy(forces)}, rounds
            )
        finally:
            plant.close()
            close_fmpy()
    ratio = statistics.median(m["master"] / m["fmpy"] for m in per_round)
    verdict = "met" if ratio <= MASTER_RATIO_GOAL else "MISSED"
    context.notes.append(
        f"{rounds} interleaved rounds of {iterations} iterations x {maneuver.n_steps} steps; "
        "the master reads x, v, x_meas, records the trace and sets u only when it changes "
        "(an FMU keeps an input until it is set); fmpy sets u, steps and reads "
        f"x; ratio = median of the per-round ratios; goal {verdict}"
    )
    return [
        Row("closed-loop step (master + PAPWC + recording)", medians["master"] * 1e6, "us/step"),
        Row("fmpy FMU2Slave setReal + doStep + getReal", medians["fmpy"] * 1e6, "us/step"),
        Row("ratio master / fmpy", ratio, "x"),
        Row(f"goal: ratio at most ({verdict})", MASTER_RATIO_GOAL, "x"),
    ]
