"""FrictionPlant: a mass with Coulomb, stiction and viscous friction, as an FMI 2.0 CS slave.

Every ``doStep``, of any size, advances the model layer's
:class:`~papwc.model.dynamics.Plant` (the same object the master's in-process
plant steps) with the force ``u`` held over the step: without deviations that
is the exact solution of the corrected Eq. (1) of the paper, one call of
:func:`stickslip.step` with the step size. Parameters add the deviations of a
real machine (Stribeck curve, LuGre pre-sliding, friction ripple, random
stiction, actuator lag, a flexible drive, encoder noise). The outputs are the
plant's, read by the model layer's names (:data:`~papwc.model.dynamics.OUTPUTS`).
See ``readme.md`` beside this file for the equations, the integration and the
variables.

Inside the FMU this file sits in ``resources/`` beside the package
``papwc_friction_plant`` (the project's model layer and FMI glue, under a name
no other FMU uses), so it imports nothing outside it, pythonfmu and the
standard library.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from papwc_friction_plant.fmi.glue import CheckedSlave
from papwc_friction_plant.model.dynamics import OUTPUTS, Plant
from papwc_friction_plant.model.plant import PLANT_CONSTRAINTS, PLANT_VARIABLES
from papwc_friction_plant.model.variables import Variable
from pythonfmu import DefaultExperiment

_isfinite = math.isfinite
_INF = math.inf
#: The parameters the outputs show before initialization ends: the plant at rest there.
_SHOWN_BEFORE_START = ("x0", "v0", "x_resolution", "x_d_resolution")


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
    #: The model layer's plant (parameters and state).
    STATE = ("_plant",)

    def __init__(self, **kwargs: Any) -> None:
        #: What the outputs are read from: until initialization ends, a plant at rest at x0
        #: with v0 and the encoders' resolutions; then the plant of the parameters.
        self._plant = Plant({})
        super().__init__(**kwargs)
        self._plant = self._plant_before_start()

    def output_getter(self, var: Variable) -> Callable[[], Any] | None:
        """An output's getter reads the plant (:data:`~papwc.model.dynamics.OUTPUTS`)."""
        if var.causality != "output":
            return None
        value = OUTPUTS[var.name]
        return lambda: value(self._plant)

    def _plant_before_start(self) -> Plant:
        """The plant the outputs show before initialization ends: Eq. (1) at rest at x0 with
        v0, read by the encoders at their resolutions (one that is not a length: ideal)."""
        shown = {name: getattr(self, name) for name in _SHOWN_BEFORE_START}
        for name in ("x_resolution", "x_d_resolution"):
            if not 0.0 < shown[name] < _INF:
                shown[name] = 0.0
        return Plant(shown)

    def parameter_set(self, name: str) -> None:
        """Until initialization ends, the outputs follow x0, v0 and the resolutions."""
        if name in _SHOWN_BEFORE_START:
            self._plant = self._plant_before_start()

    def start(self) -> None:
        """The state at the start: the plant of the parameters, at x0 with v0."""
        self._plant = Plant(self.parameter_values())

    def step(self, current_time: float, step_size: float) -> str | None:
        """Advance over ``step_size`` (s) with ``u`` held; refuse non-finite input."""
        u = self.u
        if not _isfinite(u):
            return f"input u = {u!r} N is not finite"
        if not 0.0 < step_size < _INF:
            return f"step size {step_size!r} s must be finite and > 0"
        return self._plant.step(u, step_size)

    # -- state -----------------------------------------------------------------------------
    def encode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        """The plant as its state dict; the outputs' fields as the plant gives them (once
        started: before, they are the variables' start values)."""
        plant = fields["_plant"]
        fields["_plant"] = plant.state()
        if fields["_ready"]:
            fields.update(plant.outputs())
        return fields

    def decode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        """Rebuild the plant from the state's parameters and its state dict."""
        values = fields["_plant"]
        if fields["_ready"]:
            params = {v.name: fields[v.name] for v in self.VARIABLES
                      if v.causality == "parameter"}
        else:
            params = {name: fields[name] for name in _SHOWN_BEFORE_START}
            for name in ("x_resolution", "x_d_resolution"):
                if not 0.0 < params[name] < _INF:
                    params[name] = 0.0
        try:
            plant = Plant(params)
        except ArithmeticError as exc:
            raise ValueError(f"the state's parameters do not make a plant: {exc}") from None
        plant.set_state(values)
        fields["_plant"] = plant
        return fields
