"""``papwc bench`` section: the master's closed-loop step against fmpy's per-call cost.

Beside the closed loop as it is, the same run measures it without each of the master's speed
tricks (each written in one place, named in the row), so that the table shows what each one
pays:

- *prepared FMI calls* (:class:`papwc.master.fmu.FmuSlave`: the library's functions called
  with ctypes arguments made once): the slave's own set + doStep + read against fmpy's;
- *an input sent only when it changes* (``FmuSlave.input_setter``): the loop with every
  force sent;
- *outputs read only after a sample that computed* (:class:`papwc.master.slave.ControllerSlave`:
  nothing is read after a sample that only counted, the estimates only when they changed):
  the loop with every output read after every sample;
- *one attrgetter per read* (``papwc.master.slave._attribute_reader``): the loop with each
  watched attribute read by its own call.
"""

from __future__ import annotations

import math
import statistics
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from papwc.bench import BenchContext, Row, gc_paused, median_interleaved, register_section
from papwc.bench.plant_calls import fmpy_loop
from papwc.master.fmu import FmuSlave
from papwc.master.slave import ControllerSlave

#: The clock of this section: CPU time of this thread, ns (the other processes of a loaded
#: machine do not count; everything measured here runs in this thread).
_timer = time.thread_time_ns

#: A closed-loop step of the master (controller and recording included) may cost at most
#: this multiple of fmpy's FMU2Slave.setReal + doStep + getReal on the same FMU.
MASTER_RATIO_GOAL = 1.0


class EveryInputSent(FmuSlave):
    """FmuSlave whose input setters send every value (no skip of an unchanged input)."""

    def input_setter(self, names: Sequence[str]) -> Callable[..., None]:
        """The setter of FmuSlave, told before each call that the inputs are not known."""
        setter = super().input_setter(names)
        cells = [self._held_cell(name) for name in names]

        def send(*values: Any) -> None:
            for held in cells:
                held[0] = math.nan
            setter(*values)

        return send


class EveryOutputRead(ControllerSlave):
    """ControllerSlave that reads every output and estimate after every sample."""

    def do_step(self, t: float, h: float) -> None:
        """Sample, then read all the controller's outputs and estimates."""
        controller = self.controller
        self.u = controller.update(t, self.x_meas, self.x_ref)
        self.out.__dict__.update(controller.estimates())
        self._refresh()


class ReadOneByOne(ControllerSlave):
    """ControllerSlave whose watched attributes are read by one call each."""

    def _reader(self, names: Sequence[str]) -> Callable[[Any], Sequence[Any]]:
        from operator import attrgetter

        getters = [attrgetter(self._path(name)) for name in names]
        return lambda obj: [get(obj) for get in getters]


@register_section("Master: closed-loop step (PAPWC + recording) against fmpy's "
                  "setReal + doStep + getReal")
def master_step_cost(context: BenchContext) -> list[Row]:
    """Cost per sample of :func:`papwc.master.run_closed_loop` through FrictionPlant.fmu.

    Beside it, interleaved in the same run: fmpy's ``FMU2Slave.setReal([u]) +
    doStep + getReal([x])`` on the same FMU with the forces the controller
    produced, the master's own slave doing the same, and the closed loop
    without each speed trick (see the module docstring).
    """
    from papwc.controllers import make_controller
    from papwc.controllers.settings import ControllerSettings
    from papwc.master import Maneuver, run_closed_loop

    iterations, rounds = (2, 3) if context.quick else (10, 9)
    maneuver = Maneuver(x_ref=0.01, T=0.01, duration=2.0, iterations=iterations)
    settings = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8)
    n = maneuver.n_steps * iterations
    fmu = context.fmu("FrictionPlant.fmu")
    params = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        plants = {"master": FmuSlave(fmu), "every force sent": EveryInputSent(fmu)}
        fmpy, close_fmpy = fmpy_loop(fmu, Path(tmp), "u", "x", _timer)
        try:
            for plant in plants.values():
                plant.set_start_values(params)
            forces: list[float] = []

            def closed_loop(plant: FmuSlave, controller_slave: type[ControllerSlave]
                            ) -> Callable[[], float]:
                def measure() -> float:
                    controller = controller_slave(make_controller(settings, maneuver.T))
                    with gc_paused():
                        start = _timer()
                        result = run_closed_loop(plant, controller, maneuver, settings)
                        elapsed = _timer() - start
                    if result.error:
                        raise RuntimeError(f"bench closed loop failed: {result.error}")
                    if plant is plants["master"] and controller_slave is ControllerSlave:
                        forces[:] = [u for tr in result.traces for u in tr.column("u")[:-1]]
                    return elapsed * 1e-9 / n

                return measure

            def slave_calls() -> float:
                """The master's plant slave alone: set u (always sent), doStep, read x."""
                plant = plants["every force sent"]
                plant.watch(["x"])
                set_u = plant.input_setter(["u"])
                plant.initialize(0.0)
                h = maneuver.T
                do_step = plant.do_step
                with gc_paused():
                    start = _timer()
                    for k, u in enumerate(forces):
                        set_u(u)
                        do_step(k * h, h)
                    elapsed = _timer() - start
                return elapsed * 1e-9 / len(forces)

            loops = {
                "master": closed_loop(plants["master"], ControllerSlave),
                "fmpy": lambda: fmpy(forces),
                "slave calls": slave_calls,
                "every force sent": closed_loop(plants["every force sent"], ControllerSlave),
                "every output read": closed_loop(plants["master"], EveryOutputRead),
                "one call per attribute": closed_loop(plants["master"], ReadOneByOne),
            }
            loops["master"]()  # warm-up, and the forces fmpy replays
            fmpy(forces)
            medians, per_round = median_interleaved(loops, rounds)
        finally:
            for plant in plants.values():
                plant.close()
            close_fmpy()

    def ratio(name: str, base: str = "fmpy") -> float:
        return statistics.median(m[name] / m[base] for m in per_round)

    master_ratio = ratio("master")
    verdict = "met" if master_ratio <= MASTER_RATIO_GOAL else "MISSED"
    context.notes.append(
        f"{rounds} interleaved rounds of {iterations} iterations x {maneuver.n_steps} steps; "
        "the master reads x, v, x_meas, x_d, x_d_meas, records the trace and sets u only "
        "when it changes (an FMU keeps an input until it is set); fmpy sets u, steps and "
        f"reads x; ratios = medians of the per-round ratios; goal {verdict}. A trick pays "
        "what its 'without' row costs above 1.0 x the master"
    )
    return [
        Row("closed-loop step (master + PAPWC + recording)", medians["master"] * 1e6, "us/step"),
        Row("fmpy FMU2Slave setReal + doStep + getReal", medians["fmpy"] * 1e6, "us/step"),
        Row("ratio master / fmpy", master_ratio, "x"),
        Row(f"goal: ratio at most ({verdict})", MASTER_RATIO_GOAL, "x"),
        Row("prepared FMI calls: FmuSlave set + doStep + read / fmpy", ratio("slave calls"),
            "x"),
        Row("without sending u only when it changes / master",
            ratio("every force sent", "master"), "x"),
        Row("without reading outputs only after a computed sample / master",
            ratio("every output read", "master"), "x"),
        Row("without one attrgetter per read / master",
            ratio("one call per attribute", "master"), "x"),
    ]
