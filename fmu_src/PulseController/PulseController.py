"""PulseController: the adaptive pulse controllers of ``papwc.core`` as an FMI 2.0 CS slave.

At every communication step ``doStep(t, T)`` the controller takes the measured
position ``x_meas`` and the reference ``x_ref`` present at ``t``, and sets the
force ``u`` to hold over the next sample. In a co-simulation whose master
steps plant and controller side by side, the force computed from ``x_meas(t_k)``
therefore reaches the plant at ``t_(k+1)``. See ``readme.md`` beside this file.

Inside the FMU this file sits in ``resources/`` beside the package
``papwc_pulse_core``, a copy of ``papwc.core`` (standard library only) under a
name of its own, so that it can share a process with other FMUs.
"""

from __future__ import annotations

import math
from typing import Any

from papwc_pulse_core import CONTROLLER_KINDS, Mode, make_controller
from papwc_pulse_core.settings import ControllerSettings
from pythonfmu import (
    DefaultExperiment,
    Fmi2Causality,
    Fmi2Initial,
    Fmi2Slave,
    Fmi2Variability,
    Integer,
    Real,
    String,
)
from pythonfmu.enums import Fmi2Status

_isfinite = math.isfinite

#: Value of an optional setting (f_p_min, k_p, k_d) that selects its default.
DEFAULT_SENTINEL = -1.0

#: Relative tolerance of the check that the communication step equals T.
STEP_RTOL = 1e-9

#: Real settings: name as in a scenario file -> description (unit in the model description).
REAL_SETTINGS: dict[str, str] = {
    "f_p_max": "Largest pulse amplitude, > 0 (PWC always pulses at f_p_max)",
    "t_p_max": "Largest pulse width, > 0; INF for no bound",
    "K_c": "Gain of Eq. (6), 0 < K_c < 2",
    "tolerance": "Error band inside which the mass at rest counts as settled, >= 0",
    "m_est": "Initial estimate of the mass, > 0",
    "f_c_est": "Initial estimate of the Coulomb friction, 0 < f_c_est < f_p_max",
    "f_p_min": (
        "Initial floor of the pulse amplitude, 0 <= f_p_min <= f_p_max; "
        "-1 selects the default f_c_est"
    ),
    "floor_raise": (
        "Relative step by which the amplitude floor rises above an amplitude that did "
        "not move the mass, 0 < floor_raise <= 1"
    ),
    "F_inv0": "Initial inverse gain F^-1(0) of the PWC estimator, Eq. (8), > 0",
    "lambda_1": "Forgetting parameter lambda_1 of Eq. (8), 0 < lambda_1 <= 1",
    "lambda_2": "Forgetting parameter lambda_2 of Eq. (8), 0 <= lambda_2 < 2",
    "delta_inv": "P(0) = delta_inv*I of the PAPWC estimator, Eq. (13)-(17), > 0",
    "lambda": "Forgetting factor lambda of Eq. (14)-(15), 0 < lambda <= 1",
    "e_band": (
        "Error band inside which the mass at rest is handed over from the coarse "
        "feedback to pulse mode, > tolerance"
    ),
    "k_p": "Proportional gain of the coarse feedback, > 0; -1 selects m_est*(10 rad/s)**2",
    "k_d": "Derivative gain of the coarse feedback, >= 0; -1 selects 2*0.7*(10 rad/s)*m_est",
    "rest_band": (
        "Largest change of the measured position that still counts as unchanged "
        "(rest detection), >= 0"
    ),
}

#: Settings whose value ``DEFAULT_SENTINEL`` stands for ``None`` (the default).
OPTIONAL_SETTINGS = ("f_p_min", "k_p", "k_d")

#: The attributes that make up the controller's FMU state (besides the controller's own).
_STATE_FIELDS = ("kind", "rest_samples", "T", "x_meas", "x_ref", "u", "time", "_problems")


class PulseController(Fmi2Slave):
    """Adaptive pulse controller (PWC or PAPWC) sampled at the communication steps.

    Parameters are read when initialization ends; ``x_meas`` (m) and ``x_ref``
    (m) are the inputs read at the start of each step; ``u`` (N) is the force to
    hold over the next sample, and ``b_hat`` (m/s2), ``f_c_hat`` (N), ``pulses``
    and ``mode`` let the controller be observed.
    """

    author = "papwc"
    license = "BSD-2-Clause"
    version = "0.1.0"
    description = (
        "Adaptive pulse controller for positioning a mass with stick-slip friction "
        "(PWC or PAPWC): at each communication step of size T it reads the measured "
        "position and the reference and sets the force to hold over the next sample"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.0, step_size=0.01)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        defaults = ControllerSettings()
        self.kind = defaults.kind
        #: Real settings by their scenario-file names (``lambda``, not ``lam``).
        self.settings = {
            name: float(_value_or_sentinel(getattr(defaults, _attr(name))))
            for name in REAL_SETTINGS
        }
        self.rest_samples = int(defaults.rest_samples)
        self.T = 0.01
        self.x_meas = 0.0
        self.x_ref = 0.0
        self.u = 0.0
        #: Communication point at the end of the last step, s.
        self.time = 0.0
        #: The controller, created when initialization ends with valid parameters.
        self._controller = None
        #: Parameter values in use (fixed when initialization ends).
        self._in_use: dict[str, Any] = {}
        #: Messages for the parameters refused when initialization ended.
        self._problems: list[str] = []

        parameter = {
            "causality": Fmi2Causality.parameter,
            "variability": Fmi2Variability.fixed,
            "initial": Fmi2Initial.exact,
        }
        kinds = ", ".join(repr(k) for k in sorted(CONTROLLER_KINDS))
        self.register_variable(
            String("kind", description=f"Controller kind: one of {kinds}", **parameter)
        )
        for name, text in REAL_SETTINGS.items():
            self.register_variable(
                Real(
                    name,
                    description=text,
                    getter=lambda n=name: self.settings[n],
                    setter=lambda value, n=name: self._set_setting(n, value),
                    **parameter,
                )
            )
        self.register_variable(
            Integer(
                "rest_samples",
                description=(
                    "Samples with unchanged measured position that count as at rest, >= 1"
                ),
                **parameter,
            )
        )
        self.register_variable(
            Real(
                "T",
                description="Sample period: every communication step must be T, > 0",
                **parameter,
            )
        )
        continuous_input = {
            "causality": Fmi2Causality.input,
            "variability": Fmi2Variability.continuous,
        }
        self.register_variable(
            Real(
                "x_meas",
                description="Measured position, read at the start of each step",
                **continuous_input,
            )
        )
        self.register_variable(
            Real(
                "x_ref",
                description="Reference position, read at the start of each step",
                **continuous_input,
            )
        )
        output = {
            "causality": Fmi2Causality.output,
            "variability": Fmi2Variability.discrete,
        }
        self.register_variable(
            Real(
                "u",
                description=(
                    "Force to hold over the next sample, computed at the last step "
                    "(0 before the first step)"
                ),
                initial=Fmi2Initial.exact,
                **output,
            )
        )
        self.register_variable(
            Real(
                "b_hat",
                description=(
                    "Estimated pulse-model coefficient b at f_p_max (PWC: Eq. (7)-(9); "
                    "PAPWC: A1*f_p_max**2 - A2*f_p_max, Eq. (12))"
                ),
                getter=lambda: self._estimate("b_hat"),
                **output,
            )
        )
        self.register_variable(
            Real(
                "f_c_hat",
                description="Estimated Coulomb friction (PAPWC: A2/A1; PWC: implied by b_hat)",
                getter=lambda: self._estimate("f_c_hat"),
                **output,
            )
        )
        self.register_variable(
            Integer(
                "pulses",
                description="Number of pulses started since the start of the simulation",
                getter=lambda: 0 if self._controller is None else self._controller.pulses,
                initial=Fmi2Initial.exact,
                **output,
            )
        )
        self.register_variable(
            Integer(
                "mode",
                description=(
                    "Controller mode after the last step: 0 coarse, 1 pulse (also before "
                    "the first step), 2 wait, 3 settled"
                ),
                getter=lambda: Mode.PULSE if self._controller is None else self._controller.mode,
                initial=Fmi2Initial.exact,
                **output,
            )
        )

    # -- parameters --------------------------------------------------------------------
    def _set_setting(self, name: str, value: float) -> None:
        """Set the Real setting ``name`` (scenario-file name)."""
        self.settings[name] = value

    def _make_settings(self) -> ControllerSettings:
        """The ControllerSettings of the current parameter values."""
        values: dict[str, Any] = {"kind": self.kind, "rest_samples": self.rest_samples}
        for name, value in self.settings.items():
            if name in OPTIONAL_SETTINGS and value == DEFAULT_SENTINEL:
                continue
            values[name] = value
        return ControllerSettings.from_mapping(values)

    def _check(self) -> tuple[ControllerSettings, list[str]]:
        """Settings of the current parameters and one message per invalid parameter."""
        settings = self._make_settings()
        problems = [
            f"parameter {message}"
            + ("; -1 selects the default" if name in OPTIONAL_SETTINGS else "")
            for name, message in settings.problems(tuple(CONTROLLER_KINDS))
        ]
        T = self.T
        if not (_isfinite(T) and T > 0.0):
            problems.append(f"parameter T = {T!r} s: must be a finite number > 0 s")
        return settings, problems

    def _estimate(self, name: str) -> float:
        """Estimate ``name`` of the controller; before it exists, of the current parameters."""
        controller = self._controller
        if controller is None:
            settings, problems = self._check()
            if problems:
                return math.nan
            try:
                controller = make_controller(settings, self.T)
            except ValueError:
                return math.nan
        return float(controller.estimates()[name])

    # -- FMI ---------------------------------------------------------------------------
    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        """Take the start time (s) as the first communication point."""
        self.time = start_time

    def exit_initialization_mode(self) -> None:
        """Check the parameters and create the controller.

        Invalid parameters are refused: one message per problem, naming the
        parameter, its value and the allowed range, is logged with status
        Error, and every later ``doStep`` returns Discard (repeating the
        messages) with the outputs left at their start values.

        The refusal is not an exception on purpose: pythonfmu 0.7.0 turns any
        exception into fmi2Fatal and frees the Python instance, after which a
        host that still calls the FMU (libcosim does) aborts.
        """
        settings, problems = self._check()
        controller = None
        if not problems:
            try:
                controller = make_controller(settings, self.T)
            except ValueError as exc:  # a kind's own checks of its settings
                problems = [f"parameter kind = {settings.kind!r}: {exc}"]
        self._problems = problems
        for problem in problems:
            self.log(
                f"{self.instance_name}: {problem}; initialization refused, doStep will "
                "return Discard",
                Fmi2Status.error,
            )
        self._in_use = {"settings": settings.to_mapping(), "T": self.T}
        self._controller = controller
        self.u = 0.0

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Sample at ``current_time``: compute the force to hold over the next sample.

        Returns
        -------
        bool
            False (fmi2Discard, nothing changed, message logged) if the
            parameters were refused, if ``step_size`` differs from ``T`` by more
            than a relative 1e-9, or if an input is not finite; True otherwise.
        """
        controller = self._controller
        T = self._in_use.get("T", self.T)
        x_meas = self.x_meas
        x_ref = self.x_ref
        if (
            controller is not None
            and abs(step_size - T) <= STEP_RTOL * T
            and _isfinite(x_meas)
            and _isfinite(x_ref)
        ):
            self.u = controller.update(current_time, x_meas, x_ref)
            self.time = current_time + step_size
            return True
        return self._discard(current_time, step_size, T)

    def _discard(self, current_time: float, step_size: float, T: float) -> bool:
        """Log why the step from ``current_time`` is refused; return False."""
        if self._problems:
            reason = "invalid parameters: " + "; ".join(self._problems)
        elif self._controller is None:
            reason = "initialization has not ended (call exitInitializationMode first)"
        elif not abs(step_size - T) <= STEP_RTOL * T:
            reason = (
                f"the communication step size {step_size!r} s differs from the sample "
                f"period T = {T!r} s; the controller samples only at period T, so every "
                "communication step must be T"
            )
        elif not _isfinite(self.x_meas):
            reason = f"input x_meas = {self.x_meas!r} m is not finite"
        else:
            reason = f"input x_ref = {self.x_ref!r} m is not finite"
        self.log(
            f"{self.instance_name}: doStep(t = {current_time!r} s, h = {step_size!r} s) "
            f"refused: {reason}; the outputs are left as they were",
            Fmi2Status.discard,
        )
        return False

    def _get_fmu_state(self) -> dict[str, Any]:
        """Return the complete state (parameters, inputs, outputs, controller) as a dict."""
        state = {name: getattr(self, name) for name in _STATE_FIELDS}
        state["settings"] = dict(self.settings)
        state["_in_use"] = self._in_use
        controller = self._controller
        state["controller"] = None if controller is None else controller.state()
        return state

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Restore a state returned by :meth:`_get_fmu_state` exactly."""
        for name in _STATE_FIELDS:
            setattr(self, name, state[name])
        self.settings = dict(state["settings"])
        self._in_use = dict(state["_in_use"])
        values = state["controller"]
        if values is None:
            self._controller = None
        else:
            settings = ControllerSettings.from_mapping(self._in_use["settings"])
            self._controller = make_controller(settings, self._in_use["T"])
            self._controller.set_state(values)


def _attr(name: str) -> str:
    """Attribute of ControllerSettings for the scenario-file name ``name``."""
    return ControllerSettings.KEY_ALIASES.get(name, name)


def _value_or_sentinel(value: float | None) -> float:
    """``value``, or :data:`DEFAULT_SENTINEL` for ``None``."""
    return DEFAULT_SENTINEL if value is None else value
