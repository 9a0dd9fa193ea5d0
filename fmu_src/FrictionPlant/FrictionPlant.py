"""FrictionPlant: a mass with Coulomb, stiction and viscous friction, as an FMI 2.0 CS slave.

The motion is the exact solution of the corrected Eq. (1) of the paper with the
force ``u`` held constant over each communication step (zero-order hold); every
``doStep``, of any size, calls :func:`stickslip.step` once with the step size.
Parameters add the deviations of a real machine (Stribeck curve, LuGre
pre-sliding, friction ripple, random stiction, actuator lag, a flexible drive,
encoder noise); with any of them set, each ``doStep`` advances the model
layer's :class:`~papwc.model.dynamics.Plant` instead (the same object the
master's in-process plant steps). See ``readme.md`` beside this file for the
equations, the integration and the variables.

Inside the FMU this file sits in ``resources/`` beside the package
``papwc_friction_plant`` (the project's model layer and FMI glue, under a name
no other FMU uses), so it imports nothing outside it, pythonfmu and the
standard library.
"""

from __future__ import annotations

import math
from typing import Any

from papwc_friction_plant.fmi.glue import CheckedSlave
from papwc_friction_plant.model.dynamics import Plant
from papwc_friction_plant.model.plant import PLANT_CONSTRAINTS, PLANT_VARIABLES
from papwc_friction_plant.model.stickslip import quantize, step
from pythonfmu import DefaultExperiment

_isfinite = math.isfinite
_INF = math.inf


class FrictionPlant(CheckedSlave):
    """Mass with stick-slip friction, advanced exactly over each communication step.

    Parameters (kg, N, N, N.s/m, m, m/s, m) are read when initialization ends;
    ``u`` (N) is the input held over a step; ``x`` (m), ``v`` (m/s), ``x_meas``
    (m), ``stuck``, ``x_d`` (m, the motor side; ``x`` on a rigid drive) and ``x_d_meas``
    (m, the motor encoder) are the outputs at the end of the last step.
    """

    author = "papwc"
    license = "BSD-2-Clause"
    description = (
        "Mass with Coulomb, stiction and viscous friction (m*dv/dt = u - f_c*sgn(v) - c*v, "
        "stuck while v = 0 and |u| <= f_s), advanced exactly with the force held constant "
        "over each communication step; optional deviations of a real machine (Stribeck "
        "curve, LuGre pre-sliding, friction ripple, random stiction, actuator lag, flexible "
        "drive, encoder noise), integrated with error control where no closed form exists"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.0, step_size=0.01)
    VARIABLES = PLANT_VARIABLES
    CONSTRAINTS = PLANT_CONSTRAINTS
    #: The model layer's plant (parameters and every state beyond x and v).
    STATE = ("_plant",)

    def __init__(self, **kwargs: Any) -> None:
        #: Set by :meth:`start` when a deviation is present; None: Eq. (1) exactly.
        self._plant: Plant | None = None
        super().__init__(**kwargs)

    def parameter_set(self, name: str) -> None:
        """Until initialization ends, the outputs follow x0, v0 and x_resolution."""
        if name in ("x0", "v0", "x_resolution", "x_d_resolution"):
            self.x = self.x0
            self.v = self.v0
            self._plant = None
            self.state_restored()

    def start(self) -> None:
        """The state at the start: x = x0, v = v0 (and the deviations' initial state)."""
        plant = Plant(self.parameter_values())
        self._plant = None if plant.is_eq1 else plant
        self.x = self.x0
        self.v = self.v0
        self.state_restored()

    def state_restored(self) -> None:
        """Bind the outputs' getters and the step to Eq. (1) or to the plant with deviations."""
        by_name = {var.name: var for var in self.vars.values()}
        plant = self._plant
        if plant is not None:
            by_name["x"].getter = lambda: plant.x
            by_name["v"].getter = lambda: plant.v
            by_name["x_meas"].getter = plant.x_meas
            by_name["stuck"].getter = lambda: plant.v == 0.0
            by_name["x_d"].getter = plant.x_d_now
            by_name["x_d_meas"].getter = plant.x_d_meas
            self._advance = plant.step
            return
        by_name["x"].getter = lambda: self.x
        by_name["v"].getter = lambda: self.v
        resolution = self.x_resolution
        if 0.0 < resolution < _INF:
            by_name["x_meas"].getter = lambda: quantize(self.x, resolution)
        else:
            by_name["x_meas"].getter = lambda: self.x
        by_name["stuck"].getter = lambda: self.v == 0.0
        # A rigid drive with an ideal or noiseless motor encoder: x read at its resolution.
        by_name["x_d"].getter = lambda: self.x
        resolution_d = self.x_d_resolution
        if 0.0 < resolution_d < _INF:
            by_name["x_d_meas"].getter = lambda: quantize(self.x, resolution_d)
        else:
            by_name["x_d_meas"].getter = lambda: self.x
        self._advance = self._advance_exact

    def step(self, current_time: float, step_size: float) -> str | None:
        """Advance over ``step_size`` (s) with ``u`` held; refuse non-finite input."""
        u = self.u
        if not _isfinite(u):
            return f"input u = {u!r} N is not finite"
        if not 0.0 < step_size < _INF:
            return f"step size {step_size!r} s must be finite and > 0"
        return self._advance(u, step_size)

    def _advance_exact(self, u: float, step_size: float) -> str | None:
        """Eq. (1) exactly: one call of :func:`stickslip.step`."""
        x, v = step(self.x, self.v, u, step_size, self.m, self.f_c, self.f_s, self.c)
        if not (_isfinite(x) and _isfinite(v)):
            return "the result would not be finite"
        self.x = x
        self.v = v
        return None

    # -- state -----------------------------------------------------------------------------
    def encode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        """The plant with deviations as its state dict (x and v as the plant has them)."""
        plant = fields["_plant"]
        if plant is not None:
            fields["_plant"] = plant.state()
            fields["x"], fields["v"] = plant.x, plant.v
        return fields

    def decode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        """Rebuild the plant from the state's parameters and its state dict."""
        values = fields["_plant"]
        if values is None:
            return fields
        params = {v.name: fields[v.name] for v in self.VARIABLES if v.causality == "parameter"}
        try:
            plant = Plant(params)
        except ArithmeticError as exc:
            raise ValueError(f"the state's parameters do not make a plant: {exc}") from None
        if plant.is_eq1:
            raise ValueError("the state holds a plant with deviations, its parameters none")
        plant.set_state(values)
        fields["_plant"] = plant
        return fields
