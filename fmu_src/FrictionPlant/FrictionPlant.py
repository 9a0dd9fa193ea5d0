"""FrictionPlant: a mass with Coulomb, stiction and viscous friction, as an FMI 2.0 CS slave.

The motion is the exact solution of the corrected Eq. (1) of the paper with the
force ``u`` held constant over each communication step (zero-order hold); every
``doStep``, of any size, calls :func:`papwc_stickslip.step` once with the step
size. See ``readme.md`` beside this file for the equations and the variables.

Inside the FMU this file and ``papwc_stickslip.py`` sit in ``resources/`` and are
loaded by file name, so the module uses the Python standard library only.
"""

from __future__ import annotations

import math
from typing import Any

from papwc_stickslip import check_parameters, quantize, step
from pythonfmu import (
    Boolean,
    DefaultExperiment,
    Fmi2Causality,
    Fmi2Initial,
    Fmi2Slave,
    Fmi2Variability,
    Real,
)
from pythonfmu.enums import Fmi2Status

_isfinite = math.isfinite
_INF = math.inf

#: The attributes that make up the plant's state (getFMUstate, serialization).
_STATE_FIELDS = (
    "m",
    "f_c",
    "f_s",
    "c",
    "x0",
    "v0",
    "x_resolution",
    "u",
    "x",
    "v",
    "time",
    "_m",
    "_f_c",
    "_f_s",
    "_c",
    "_resolution",
    "_ready",
    "_problems",
)


class FrictionPlant(Fmi2Slave):
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

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.m = 150.0
        self.f_c = 100.0
        self.f_s = 130.0
        self.c = 700.0
        self.x0 = 0.0
        self.v0 = 0.0
        self.x_resolution = 0.0
        self.u = 0.0
        self.x = 0.0
        self.v = 0.0
        #: Communication point at the end of the last step, s.
        self.time = 0.0
        # Parameter values in use, fixed when initialization ends.
        self._m = self.m
        self._f_c = self.f_c
        self._f_s = self.f_s
        self._c = self.c
        self._resolution = self.x_resolution
        #: True once initialization has ended with valid parameters.
        self._ready = False
        #: Messages for the parameters refused when initialization ended.
        self._problems: list[str] = []

        parameter = {
            "causality": Fmi2Causality.parameter,
            "variability": Fmi2Variability.fixed,
            "initial": Fmi2Initial.exact,
        }
        self.register_variable(Real("m", description="Mass, > 0", **parameter))
        self.register_variable(
            Real("f_c", description="Coulomb (sliding) friction force, >= 0", **parameter)
        )
        self.register_variable(
            Real("f_s", description="Stiction (breakaway) force, >= f_c", **parameter)
        )
        self.register_variable(Real("c", description="Viscous damping, >= 0", **parameter))
        self.register_variable(
            Real("x0", description="Initial position", setter=self._set_x0, **parameter)
        )
        self.register_variable(
            Real("v0", description="Initial velocity", setter=self._set_v0, **parameter)
        )
        self.register_variable(
            Real(
                "x_resolution",
                description="Encoder resolution of x_meas, >= 0 (0 = ideal encoder)",
                **parameter,
            )
        )
        self.register_variable(
            Real(
                "u",
                causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous,
                description="Force on the mass, held constant over each communication step",
            )
        )
        output = {
            "causality": Fmi2Causality.output,
            "variability": Fmi2Variability.continuous,
            "initial": Fmi2Initial.exact,
        }
        self.register_variable(
            Real("x", description="Position at the end of the last step", **output)
        )
        self.register_variable(
            Real("v", description="Velocity at the end of the last step", **output)
        )
        self.register_variable(
            Real(
                "x_meas",
                description="Position read by the encoder: x rounded to x_resolution",
                getter=self._x_meas,
                **output,
            )
        )
        self.register_variable(
            Boolean(
                "stuck",
                description="Mass at rest (v exactly 0)",
                getter=lambda: self.v == 0.0,
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.discrete,
                initial=Fmi2Initial.exact,
            )
        )

    def _set_x0(self, value: float) -> None:
        """Set the initial position x0 (m); until initialization ends, x follows it."""
        self.x0 = value
        if not self._ready:
            self.x = value

    def _set_v0(self, value: float) -> None:
        """Set the initial velocity v0 (m/s); until initialization ends, v follows it."""
        self.v0 = value
        if not self._ready:
            self.v = value

    def _x_meas(self) -> float:
        """Position read by the encoder (m): x rounded to x_resolution (ideal if not > 0)."""
        resolution = self._resolution if self._ready else self.x_resolution
        if resolution > 0.0 and resolution < _INF:
            return quantize(self.x, resolution)
        return self.x

    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        """Take the start time (s) as the first communication point."""
        self.time = start_time

    def exit_initialization_mode(self) -> None:
        """Check the parameters and fix the values in use for the simulation.

        Invalid parameters are refused: one message per problem, naming the
        parameter, its value and the allowed range, is logged with status
        Error, and every later ``doStep`` returns Discard (repeating the
        messages) with ``x`` and ``v`` left at ``x0`` and ``v0``.

        The refusal is not an exception on purpose: pythonfmu 0.7.0 turns any
        exception into fmi2Fatal and frees the Python instance, after which a
        host that still calls the FMU (libcosim does) aborts; a False return is
        ignored (fmi2OK).
        """
        problems = check_parameters(self.m, self.f_c, self.f_s, self.c)
        for name, value, unit in (("x0", self.x0, "m"), ("v0", self.v0, "m/s")):
            if not _isfinite(value):
                problems.append(f"parameter {name} = {value!r} {unit} must be a finite number")
        resolution = self.x_resolution
        if not _isfinite(resolution):
            problems.append(f"parameter x_resolution = {resolution!r} m must be a finite number")
        elif resolution < 0.0:
            problems.append(f"parameter x_resolution = {resolution!r} m must be >= 0")
        self._problems = problems
        for problem in problems:
            self.log(
                f"{self.instance_name}: {problem}; initialization refused, doStep will "
                "return Discard",
                Fmi2Status.error,
            )
        self._m = self.m
        self._f_c = self.f_c
        self._f_s = self.f_s
        self._c = self.c
        self._resolution = resolution
        self.x = self.x0
        self.v = self.v0
        self._ready = not problems

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Advance the plant exactly from ``current_time`` over ``step_size`` (s).

        Returns
        -------
        bool
            False (fmi2Discard, state unchanged, message logged) if the
            parameters were refused, if ``u`` is not finite, if ``step_size`` is
            not a finite number > 0, or if the result would not be finite; True
            otherwise.
        """
        u = self.u
        if self._ready and _isfinite(u) and 0.0 < step_size < _INF:
            x, v = step(self.x, self.v, u, step_size, self._m, self._f_c, self._f_s, self._c)
            if _isfinite(x) and _isfinite(v):
                self.x = x
                self.v = v
                self.time = current_time + step_size
                return True
        return self._discard(current_time, step_size)

    def _discard(self, current_time: float, step_size: float) -> bool:
        """Log why the step from ``current_time`` is refused; return False."""
        if self._problems:
            reason = "invalid parameters: " + "; ".join(self._problems)
        elif not self._ready:
            reason = "initialization has not ended (call exitInitializationMode first)"
        elif not _isfinite(self.u):
            reason = f"input u = {self.u!r} N is not finite"
        elif not 0.0 < step_size < _INF:
            reason = f"step size {step_size!r} s must be finite and > 0"
        else:
            reason = "the result would not be finite"
        self.log(
            f"{self.instance_name}: doStep(t = {current_time!r} s, h = {step_size!r} s) "
            f"refused: {reason}; x and v are left as they were",
            Fmi2Status.discard,
        )
        return False

    def _get_fmu_state(self) -> dict[str, Any]:
        """Return the complete state (parameters, input, x, v, time) as a dict."""
        return {name: getattr(self, name) for name in _STATE_FIELDS}

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Restore a state returned by :meth:`_get_fmu_state` exactly."""
        for name in _STATE_FIELDS:
            setattr(self, name, state[name])
