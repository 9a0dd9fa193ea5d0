"""The co-simulation master: steps a plant at period T alongside a controller.

Time is kept by an integer step counter, ``t_k = k*T``. Two timing semantics:

- ``"immediate"`` (default): at t_k the master reads the plant's outputs, asks
  the controller for u_k and applies u_k over [t_k, t_k+1], as a sampled-data
  controller with negligible computing time does.
- ``"delayed"``: what a master that steps plant and controller side by side
  (libcosim's fixed-step algorithm, an SSP run) does: the force computed from
  the measurement at t_k reaches the plant one step later, so the plant gets
  u_(k-1) over [t_k, t_k+1] (u_(-1) = 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from papwc.core import Controller, make_controller
from papwc.core.settings import ControllerSettings
from papwc.errors import FmuError
from papwc.recording import Trace

TIMINGS = ("immediate", "delayed")


@dataclass
class Maneuver:
    """A rest-to-rest maneuver: from rest at x0 = 0 to ``x_ref`` (m) at period ``T`` (s)."""

    x_ref: float = 0.01
    T: float = 0.01
    duration: float = 2.0
    iterations: int = 10
    timing: str = "immediate"
    noise_std: float = 0.0
    noise_seed: int = 0

    @property
    def n_steps(self) -> int:
        """Samples per iteration, ``round(duration / T)``."""
        return int(round(self.duration / self.T))


@dataclass
class RunResult:
    """Traces of all iterations of one controller; ``error`` is set if the run stopped."""

    label: str
    settings: ControllerSettings
    traces: list[Trace] = field(default_factory=list)
    error: str = ""


def run_iteration(
    plant, controller: Controller, maneuver: Maneuver, label: str = "", iteration: int = 0
) -> Trace:
    """Run one maneuver from the plant's initial state; return its trace.

    An FMU failure stops the iteration: the trace keeps every sample recorded
    before it and ``trace.error`` holds the message (time, call, FMU log).
    """
    T = maneuver.T
    x_ref = maneuver.x_ref
    trace = Trace(label, iteration, T, x_ref)
    rows = trace.rows
    rng = None
    if maneuver.noise_std > 0.0:
        import random

        rng = random.Random(maneuver.noise_seed * 1_000_003 + iteration)
    delayed = maneuver.timing == "delayed"
    u_prev = 0.0
    estimates = controller.estimates
    for k in range(maneuver.n_steps):
        t = k * T
        x, v, x_meas = plant.get_outputs()
        if rng is not None:
            x_meas = x_meas + rng.gauss(0.0, maneuver.noise_std)
        u = controller.update(t, x_meas, x_ref)
        u_applied = u_prev if delayed else u
        u_prev = u
        est = estimates()
        rows.append((k, t, x, v, x_meas, u_applied, x_ref - x, controller.mode,
                     controller.pulses, est["b_hat"], est["f_c_hat"]))
        plant.set_input(u_applied)
        try:
            plant.do_step(t, T)
        except FmuError as exc:
            trace.error = str(exc)
            return trace
    x, v, x_meas = plant.get_outputs()
    est = estimates()
    k = maneuver.n_steps
    rows.append((k, k * T, x, v, x_meas, math.nan, x_ref - x, controller.mode,
                 controller.pulses, est["b_hat"], est["f_c_hat"]))
    return trace


def run_controller(
    plant, settings: ControllerSettings, maneuver: Maneuver, label: str = ""
) -> RunResult:
    """Run all iterations of one controller; estimates carry over between iterations.

    ``plant`` must already have its parameters set. The first iteration
    initializes it, later ones restart it from the same initial state. An FMU
    error stops the run and is kept in ``result.error``; the traces recorded
    until then are kept.
    """
    controller = make_controller(settings, maneuver.T)
    result = RunResult(label or settings.kind, settings)
    for it in range(maneuver.iterations):
        try:
            if it == 0:
                plant.initialize(0.0)
            else:
                plant.restart(0.0)
        except FmuError as exc:
            result.error = f"iteration {it + 1}: {exc}"
            return result
        controller.reset()
        trace = run_iteration(plant, controller, maneuver, result.label, it + 1)
        result.traces.append(trace)
        if trace.error:
            result.error = f"iteration {it + 1}: {trace.error}"
            return result
    return result
