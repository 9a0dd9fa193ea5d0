"""FrictionPlant: a mass with Coulomb, stiction and viscous friction, as an FMI 2.0 CS slave.

The motion is the exact solution of the corrected Eq. (1) of the paper with the
force ``u`` held constant over each communication step (zero-order hold); every
``doStep``, of any size, calls :func:`stickslip.step` once with the step size.
See ``readme.md`` beside this file for the equations and the variables.

Inside the FMU this file sits in ``resources/`` beside the package
``papwc_friction_plant`` (the project's model layer and FMI glue, under a name
no other FMU uses), so it imports nothing outside it, pythonfmu and the
standard library.
"""

from __future__ import annotations

import math

from papwc_friction_plant.fmi.glue import CheckedSlave
from papwc_friction_plant.model.plant import PLANT_CONSTRAINTS, PLANT_VARIABLES
from papwc_friction_plant.model.stickslip import quantize, step
from pythonfmu import DefaultExperiment

_isfinite = math.isfinite
_INF = math.inf


class FrictionPlant(CheckedSlave):
    """Mass with stick-slip friction, advanced exactly over each communication step.

    Parameters (kg, N, N, N.s/m, m, m/s, m) are read when initialization ends;
    ``u`` (N) is the input held over a step; ``x`` (m), ``v`` (m/s), ``x_meas``
    (m) and ``stuck`` are the outputs at the end of the last step.
    """

    author = "papwc"
    license = "BSD-2-Clause"
    version = "0.1.0"
    description = (
        "Mass with Coulomb, stiction and viscous friction (m*dv/dt = u - f_c*sgn(v) - c*v, "
        "stuck while v = 0 and |u| <= f_s), advanced exactly with the force held constant "
        "over each communication step"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.0, step_size=0.01)
    VARIABLES = PLANT_VARIABLES
    CONSTRAINTS = PLANT_CONSTRAINTS

    def parameter_set(self, name: str) -> None:
        """Until initialization ends, the outputs follow x0, v0 and x_resolution."""
        if name in ("x0", "v0", "x_resolution"):
            self.start()

    def start(self) -> None:
        """The state at the start: x = x0, v = v0."""
        self.x = self.x0
        self.v = self.v0
        self.state_restored()

    def state_restored(self) -> None:
        """Bind the getters of x_meas and stuck, which are computed from x and v."""
        by_name = {var.name: var for var in self.vars.values()}
        resolution = self.x_resolution
        if 0.0 < resolution < _INF:
            by_name["x_meas"].getter = lambda: quantize(self.x, resolution)
        else:
            by_name["x_meas"].getter = lambda: self.x
        by_name["stuck"].getter = lambda: self.v == 0.0

    def step(self, current_time: float, step_size: float) -> str | None:
        """Advance exactly over ``step_size`` (s) with ``u`` held; refuse non-finite input."""
        u = self.u
        if not _isfinite(u):
            return f"input u = {u!r} N is not finite"
        if not 0.0 < step_size < _INF:
            return f"step size {step_size!r} s must be finite and > 0"
        x, v = step(self.x, self.v, u, step_size, self.m, self.f_c, self.f_s, self.c)
        if not (_isfinite(x) and _isfinite(v)):
            return "the result would not be finite"
        self.x = x
        self.v = v
        return None
