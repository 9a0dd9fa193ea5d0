"""PulseControllerPython: the project's controllers as an FMI 2.0 CS slave, in Python.

Every controller kind of :mod:`papwc.controllers` (pwc, papwc, exact, pid, dual_loop), built
with pythonfmu as ``PulseControllerPython.fmu``; it runs in the host's Python 3.10 or newer.
The kinds pwc, papwc and pid are also in the native ``PulseController.fmu`` (the C controller
of ``controller.c``, bit for bit the same numbers, no Python in the host).

At every communication step ``doStep(t, T)`` the controller takes the measured
position ``x_meas`` and the reference ``x_ref`` present at ``t``, and sets the
force ``u`` to hold over the next sample. In a co-simulation whose master
steps plant and controller side by side, the force computed from ``x_meas(t_k)``
therefore reaches the plant at ``t_(k+1)``. See ``readme.md`` beside this file.

Inside the FMU this file sits in ``resources/`` beside the package
``papwc_pulse_controller`` (the project's model layer, controllers and FMI
glue, under a name no other FMU uses), so that it can share a process with
other FMUs.
"""

from __future__ import annotations

import math
from typing import Any

from papwc_pulse_controller.controllers import (
    CONTROLLER_KINDS,
    OUTPUT_NAMES,
    default_outputs,
    make_controller,
)
from papwc_pulse_controller.controllers.settings import ControllerSettings
from papwc_pulse_controller.fmi.glue import CheckedSlave
from papwc_pulse_controller.model.controller_settings import (
    CONTROLLER_CONSTRAINTS,
    CONTROLLER_SETTINGS,
    PULSE_CONTROLLER_VARIABLES,
    STEP_RTOL,
    kind_from_code,
)
from papwc_pulse_controller.model.variables import switched_values
from pythonfmu import DefaultExperiment

_isfinite = math.isfinite


class PulseControllerPython(CheckedSlave):
    """Adaptive pulse controller (PWC, PAPWC, exact, dual_loop, the 1 kHz hybrid; or the PID
    baseline) sampled at each step.

    Parameters (the settings of a scenario's ``[[controller]]`` table and the
    sample period ``T``) are read when initialization ends; ``x_meas`` (m) and
    ``x_ref`` (m) are the inputs read at the start of each step (the reference is
    ``x_ref_offset + x_ref``, so a host that leaves ``x_ref`` unconnected sets the
    parameter ``x_ref_offset``); ``u`` (N) is the
    force to hold over the next sample, and ``b_hat`` (m/s2), ``f_c_hat`` (N),
    ``pulses``, ``mode``, ``f_low`` (N), ``outcome`` and ``outcome_reason`` let
    the controller be observed. The dual_loop kind also reads the input ``x_d_meas`` (m,
    the motor encoder).
    """

    VARIABLES = PULSE_CONTROLLER_VARIABLES
    CONSTRAINTS = CONTROLLER_CONSTRAINTS
    STATE = ("_controller", "_maneuver_seen", "_kind_set")
    description = (
        "Adaptive pulse controller for positioning a mass with stick-slip friction (PWC, PAPWC "
        "or exact; or the PID baseline, kind pid): at each communication step of size T it "
        "reads the measured position and the reference and sets the force to hold over the "
        "next sample"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.0, step_size=0.01)

    def __init__(self, **kwargs: Any) -> None:
        #: The controller, created when initialization ends with valid parameters.
        self._controller = None
        self._maneuver_seen = 0
        #: Whether the String parameter kind was set (kind_code must then agree with it).
        self._kind_set = False
        super().__init__(**kwargs)

    def parameter_set(self, name: str) -> None:
        """Remember that ``kind`` was set: a kind_code naming another kind is refused."""
        if name == "kind":
            self._kind_set = True

    # -- variables -------------------------------------------------------------------------
    def output_getter(self, var):
        """The controller's outputs (all but u) come from its ``outputs()``."""
        if var.name in OUTPUT_NAMES:
            name = var.name
            return lambda: self._outputs()[name]
        if var.name == "maneuver":
            return lambda: self.maneuver
        return None

    def _declare(self, var):
        declared = super()._declare(var)
        if var.name == "maneuver":
            declared.setter = self._set_maneuver
        return declared

    def _set_maneuver(self, value: int) -> None:
        """A new maneuver number starts a new maneuver from rest (estimates kept)."""
        self.maneuver = value
        if self._controller is not None and value != self._maneuver_seen:
            self._controller.reset()
            self._maneuver_seen = value
            self.u = 0.0

    def _kind(self) -> tuple[str, str | None]:
        """The kind that ``kind`` and ``kind_code`` select, and a conflict if any."""
        return kind_from_code(self.kind, self.kind_code, self._kind_set)

    def _settings(self) -> ControllerSettings:
        values = self.parameter_values()
        settings = {v.name: values[v.name] for v in CONTROLLER_SETTINGS}
        settings["kind"] = self._kind()[0]
        return ControllerSettings.from_mapping(settings)

    def _outputs(self) -> dict[str, Any]:
        """The controller's outputs; before it exists, those of a controller made from the
        current parameters (integer outputs at their start values and real ones NaN if
        the parameters do not make one)."""
        controller = self._controller
        if controller is None:
            if self.check():
                return default_outputs()
            try:
                controller = make_controller(self._settings(), self.T)
            except (ValueError, TypeError, ZeroDivisionError):
                return default_outputs()
        return controller.outputs()

    # -- the model -------------------------------------------------------------------------
    def check(self) -> list[str]:
        """The settings' checks, and the kind among the registered controllers."""
        found = []
        kind, conflict = self._kind()
        if conflict is not None:
            found.append(conflict)
        elif kind not in CONTROLLER_KINDS:
            found.append(f"parameter kind = {kind!r}: must be one of "
                         + ", ".join(repr(k) for k in sorted(CONTROLLER_KINDS)))
        return found + super().check()

    def start(self) -> None:
        """Create the controller from the parameters; ``kind`` then names the kind in use."""
        self.kind = self._kind()[0]
        self._controller = make_controller(self._settings(), self.T)
        self._maneuver_seen = self.maneuver
        self.u = 0.0

    def step(self, current_time: float, step_size: float) -> str | None:
        """Sample at ``current_time``: the force to hold over the next sample."""
        T = self.T
        if not abs(step_size - T) <= STEP_RTOL * T:
            return (f"the communication step size {step_size!r} s differs from the sample "
                    f"period T = {T!r} s; the controller samples only at period T, so every "
                    "communication step must be T")
        x_meas, x_ref = self.x_meas, self.x_ref
        if not _isfinite(x_meas):
            return f"input x_meas = {x_meas!r} m is not finite"
        if not _isfinite(x_ref):
            return f"input x_ref = {x_ref!r} m is not finite"
        offset = self.x_ref_offset
        if offset:
            x_ref = offset + x_ref
            if not _isfinite(x_ref):
                return (f"the reference x_ref_offset + x_ref = {offset!r} + {self.x_ref!r} m is "
                        "not finite")
        controller = self._controller
        if controller.reads_x_d_meas:
            x_d_meas = self.x_d_meas
            if not _isfinite(x_d_meas):
                return f"input x_d_meas = {x_d_meas!r} m is not finite"
            controller.x_d_meas = x_d_meas
        self.u = controller.update(current_time, x_meas, x_ref)
        return None

    # -- state -----------------------------------------------------------------------------
    def encode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        controller = fields["_controller"]
        fields["_controller"] = None if controller is None else controller.state()
        return fields

    def decode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        values = fields["_controller"]
        if values is None:
            return fields
        if not isinstance(values, dict) or not all(
                isinstance(k, str) and _numbers(v) for k, v in values.items()):
            raise ValueError("the controller state does not fit: field _controller is not a "
                             "mapping of names to numbers or lists of numbers")
        params = switched_values(PULSE_CONTROLLER_VARIABLES, fields)
        settings = {v.name: params[v.name] for v in CONTROLLER_SETTINGS}
        try:
            controller = make_controller(ControllerSettings.from_mapping(settings), fields["T"])
            controller.set_state(values)
        except (ValueError, TypeError, KeyError, ZeroDivisionError) as exc:
            raise ValueError(f"the controller state does not fit: {exc}") from None
        fields["_controller"] = controller
        return fields


def _numbers(value: Any) -> bool:
    """Whether value is a number (not a bool) or a list of numbers."""
    items = value if isinstance(value, list) else [value]
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items)
