"""The FMI glue of the project's FMUs, written once: :class:`CheckedSlave`.

Bundled into each FMU (under that FMU's own package name) beside the model
layer; each model class (``fmu_src/<Model>/<Model>.py``) keeps only its
variable table, its start-of-simulation and its step. The base class does the
rest, the same way in every FMU:

- declares the variables from the model layer's table (names, causality,
  variability, initial, description; units and ranges are added to the model
  description by the build);
- refuses invalid parameters when initialization ends: one message per problem
  (name, value, allowed range) logged with status Error, and every later
  ``doStep`` returns Discard repeating them (an exception would be fmi2Fatal
  with pythonfmu 0.7.0, which frees the instance and aborts libcosim);
- refuses a parameter or an output set after initialization (logged, value
  kept), and any input set or step after ``fmi2Terminate``;
- ``doStep`` returns Discard with a logged reason and the state untouched when
  the model's step refuses (a non-finite input, a bad step size), and when the
  step would end past the stop time ``fmi2SetupExperiment`` defined (FMI 2.0 asks
  for fmi2Error there, which pythonfmu 0.7.0 cannot return from ``doStep``: the
  message is logged with status Error);
- keeps the time of the last communication point;
- writes ``%`` in log messages as ``%%`` (a host formats an FMI message as a
  printf format string; a value holding ``%n`` would otherwise be read as one);
- gets, sets, serializes and deserializes the state; a state that does not
  parse or does not belong to this FMU is refused before anything changes,
  and the instance keeps working; an instance whose initialization was refused
  gives no state (``getFMUstate`` logs the refusal and returns a state that
  ``setFMUstate`` refuses, naming why).

pythonfmu 0.7.0 returns fmi2OK for a refused ``setReal`` (``setInteger``,
``setBoolean``, ``setString``) or ``setFMUstate``: it ignores what the Python
method returns, and an exception becomes fmi2Fatal, which frees the instance.
An FMU made with it cannot return fmi2Error or fmi2Discard from these calls, so
the refusal is logged with status Error and written to stderr (see below);
papwc's master (:class:`papwc.master.fmu.FmuSlave`) reads the log after each
such call and raises on a refusal, as if the call had returned fmi2Error.

pythonfmu 0.7.0 also drops every log message unless the host turned debug
logging on, and does not tell the model whether it did. So that a refusal is
never silent (``fmpy simulate`` ends a run at a Discard with exit status 0), the
refused initialization, a refused set or ``setFMUstate`` and the first refused
step of an instance are also written to the process's stderr, one line each,
unless the environment sets ``PAPWC_FMU_STDERR=0`` (a host that reads the log
itself, as ``papwc cosim``).
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Callable, Mapping
from typing import Any

from pythonfmu import (
    Boolean,
    Fmi2Causality,
    Fmi2Initial,
    Fmi2Slave,
    Fmi2Variability,
    Integer,
    Real,
    String,
)
from pythonfmu.enums import Fmi2Status

from ..model.variables import (
    Constraint,
    Variable,
    problems,
    switch_conflicts,
    switched_values,
)

__all__ = ["CheckedSlave"]

_KINDS = {"Real": Real, "Integer": Integer, "Boolean": Boolean, "String": String}
_PY = {"Real": float, "Integer": int, "Boolean": bool, "String": str}
#: Key of the marker that names the FMU a state belongs to.
_STATE_KEY = "papwc_fmu_state"


class CheckedSlave(Fmi2Slave):
    """Base of the project's FMUs (see the module docstring).

    A subclass sets :attr:`VARIABLES` (and :attr:`CONSTRAINTS`), and implements
    :meth:`start` (initialization has ended with valid parameters) and
    :meth:`step` (advance; return ``None``, or the reason to refuse the step).
    Variables are attributes named like the variables; parameters are read
    only when initialization ends.
    """

    #: The model description's author and license, the same for every FMU of the project.
    author = "papwc"
    license = "BSD-2-Clause"
    #: Every variable of the FMU, in the order of their value references.
    VARIABLES: tuple[Variable, ...] = ()
    #: Rules between parameters.
    CONSTRAINTS: tuple[Constraint, ...] = ()
    #: Further attributes that make up the state (besides the variables).
    STATE: tuple[str, ...] = ()

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        #: Communication point at the end of the last step, s.
        self.time = 0.0
        #: True once initialization has ended (valid or not).
        self._initialized = False
        #: True once initialization has ended with valid parameters.
        self._ready = False
        self._terminated = False
        #: Messages for the parameters refused when initialization ended.
        self._problems: list[str] = []
        #: Whether a refused step has been written to stderr.
        self._step_told = False
        #: The stop time fmi2SetupExperiment defined, s (None: none).
        self._stop_time: float | None = None
        for var in self.VARIABLES:
            setattr(self, var.name, var.fmi_start)
            self.register_variable(self._declare(var))
        #: Declared variables by value reference, per type (fast get/set).
        self._typed = {kind: {vr: v for vr, v in self.vars.items() if isinstance(v, cls)}
                       for kind, cls in _KINDS.items()}

    def log(self, msg: str, status: Fmi2Status = Fmi2Status.ok, category: str | None = None,
            debug: Any = None) -> None:
        """Log ``msg`` with ``%`` written ``%%``: an FMI message is a printf format string
        (a host formats it), so a value holding ``%`` must not be read as a conversion."""
        super().log(msg.replace("%", "%%"), status, category)

    # -- declarations ------------------------------------------------------------------------
    def _declare(self, var: Variable):
        causality = Fmi2Causality[var.causality]
        kwargs: dict[str, Any] = {
            "causality": causality,
            "variability": Fmi2Variability[var.fmi_variability],
            "description": var.description,
        }
        if var.causality == "parameter":
            kwargs["initial"] = Fmi2Initial.exact
            kwargs["setter"] = self._parameter_setter(var)
        elif var.causality == "output":
            kwargs["initial"] = Fmi2Initial[var.initial or "exact"]
            kwargs["setter"] = self._output_setter(var)
        elif var.causality == "input":
            kwargs["setter"] = self._input_setter(var)
        getter = self.output_getter(var)
        if getter is not None:
            kwargs["getter"] = getter
        return _KINDS[var.type](var.name, **kwargs)

    def output_getter(self, var: Variable) -> Callable[[], Any] | None:
        """A getter for ``var`` other than its attribute (override), or None."""
        return None

    def parameter_set(self, name: str) -> None:
        """Parameter ``name`` was set before initialization ended (override)."""

    def _parameter_setter(self, var: Variable):
        name = var.name

        def set_parameter(value: Any) -> None:
            if self._initialized:
                self.refuse(f"parameter {name} cannot be set after initialization: "
                            f"{value!r} refused, it stays {getattr(self, name)!r}")
                return
            setattr(self, name, value)
            self.parameter_set(name)

        return set_parameter

    def _input_setter(self, var: Variable):
        name = var.name

        def set_input(value: Any) -> None:
            if self._terminated:
                self.refuse(f"input {name} cannot be set after fmi2Terminate: {value!r} "
                            "refused")
                return
            setattr(self, name, value)

        return set_input

    def _output_setter(self, var: Variable):
        name = var.name

        def refuse(value: Any) -> None:
            self.refuse(f"{name} is an output and cannot be set: {value!r} refused")

        return refuse

    def refuse(self, message: str) -> None:
        """Refuse a call: log ``message`` with status Error and write it to stderr.

        (The call still returns fmi2OK under pythonfmu 0.7.0; see the module docstring.)
        """
        self.log(f"{self.instance_name}: {message}", Fmi2Status.error)
        self.tell(message + " (pythonfmu returns fmi2OK for this call; the refusal is "
                  "logged with status Error)")

    # -- values ------------------------------------------------------------------------------
    # pythonfmu's own get/set methods test the type of every variable at every call;
    # these look the variable up in a table of its type (a wrong type is a KeyError,
    # which pythonfmu turns into fmi2Fatal as it does its own TypeError).
    def get_real(self, vrs: list[int]) -> list[float]:
        """Values of the Real variables ``vrs``."""
        reals = self._typed["Real"]
        return [reals[vr].getter() for vr in vrs]

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        """Set the Real variables ``vrs``."""
        reals = self._typed["Real"]
        for vr, value in zip(vrs, values, strict=True):
            reals[vr].setter(value)

    def get_integer(self, vrs: list[int]) -> list[int]:
        """Values of the Integer variables ``vrs``."""
        ints = self._typed["Integer"]
        return [int(ints[vr].getter()) for vr in vrs]

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        """Set the Integer variables ``vrs``."""
        ints = self._typed["Integer"]
        for vr, value in zip(vrs, values, strict=True):
            ints[vr].setter(value)

    # -- parameters --------------------------------------------------------------------------
    def _parameters(self) -> list[Variable]:
        return [v for v in self.VARIABLES if v.causality == "parameter"]

    def parameter_values(self) -> dict[str, Any]:
        """The parameters as the model layer reads them: a Real whose switch ``<name>_given``
        is false takes its default (None: computed; inf), the switches left out."""
        params = self._parameters()
        return switched_values(params, {v.name: getattr(self, v.name) for v in params})

    def _parameter_problems(self, raw: Mapping[str, Any]
                            ) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
        """``(name, message)`` per invalid parameter of the FMU's values ``raw``: the Reals
        set while their switch is false, and what the model layer refuses of the others."""
        params = self._parameters()
        conflicts = switch_conflicts(params, raw)
        conflicted = {name for name, _ in conflicts}
        return conflicts, [(name, message) for name, message in problems(
            params, switched_values(params, raw), self.CONSTRAINTS) if name not in conflicted]

    def check(self) -> list[str]:
        """One message per invalid parameter (override to add checks of a model's own)."""
        params = self._parameters()
        switches = {v.name: f"{v.switch} = false selects "
                    + ("the default" if v.optional else "no bound") for v in params if v.switch}
        conflicts, others = self._parameter_problems(
            {v.name: getattr(self, v.name) for v in params})
        return [f"parameter {message}" for _, message in conflicts] + [
            f"parameter {message}" + (f"; {switches[name]}" if name in switches else "")
            for name, message in others
        ]

    # -- to implement ------------------------------------------------------------------------
    def start(self) -> None:
        """Initialization has ended with valid parameters: set the state from them."""

    def step(self, current_time: float, step_size: float) -> str | None:
        """Advance over ``step_size`` (s); return None, or why the step is refused."""
        raise NotImplementedError

    # -- FMI ---------------------------------------------------------------------------------
    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        """Take the start time (s) as the first communication point, and the stop time (s,
        None: not defined) past which no step goes; refuse (logged) a time that is not a
        finite number, or a stop time before the start time."""
        if not math.isfinite(start_time):
            self.refuse(f"fmi2SetupExperiment refused: start time {start_time!r} s is not a "
                        "finite number")
            return
        if stop_time is not None and not (math.isfinite(stop_time)
                                          and stop_time >= start_time):
            self.refuse(f"fmi2SetupExperiment refused: stop time {stop_time!r} s must be a "
                        f"finite number >= the start time {start_time!r} s")
            return
        self.time = start_time
        self._stop_time = stop_time

    def exit_initialization_mode(self) -> None:
        """Check the parameters; refuse invalid ones (logged), else :meth:`start`."""
        try:
            found = self.check()
        except Exception as exc:  # noqa: BLE001 - a check must not kill the instance
            found = [f"parameters could not be checked: {type(exc).__name__}: {exc}"]
        if not found:
            try:
                self.start()
            except Exception as exc:  # noqa: BLE001
                found = [f"the simulation could not start: {type(exc).__name__}: {exc}"]
        self._problems = found
        for problem in found:
            self.log(f"{self.instance_name}: {problem}; initialization refused, doStep will "
                     "return Discard", Fmi2Status.error)
        if found:
            self.tell("; ".join(found) + "; initialization refused, doStep will return Discard")
        self._initialized = True
        self._ready = not found

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Advance by :meth:`step`; False (Discard, logged, state unchanged) if refused."""
        status = Fmi2Status.discard
        stop = self._stop_time
        if self._ready and not self._terminated and stop is not None and (
                current_time + step_size > stop + 1e-9 * max(abs(stop), step_size)):
            status = Fmi2Status.error
            reason = (f"the step ends at t = {current_time + step_size!r} s, past the stop "
                      f"time {stop!r} s that fmi2SetupExperiment defined (FMI 2.0: computing "
                      "past stopTime is an error; pythonfmu returns fmi2Discard for it)")
        elif self._ready and not self._terminated:
            reason = self.step(current_time, step_size)
            if reason is None:
                self.time = current_time + step_size
                return True
        elif self._terminated:
            reason = "the simulation was terminated (fmi2Terminate)"
        elif self._problems:
            reason = "invalid parameters: " + "; ".join(self._problems)
        else:
            reason = "initialization has not ended (call exitInitializationMode first)"
        message = (f"doStep(t = {current_time!r} s, h = {step_size!r} s) refused: {reason}; "
                   "the state is left as it was")
        self.log(f"{self.instance_name}: {message}", status)
        if not self._step_told and not self._problems:
            self._step_told = True
            self.tell(message + " (later refusals are only logged)")
        return False

    def tell(self, message: str) -> None:
        """Write ``message`` to stderr as one line naming the model and the instance.

        Skipped when the environment sets ``PAPWC_FMU_STDERR=0``; never raises.
        """
        if os.environ.get("PAPWC_FMU_STDERR") == "0":
            return
        try:
            stream = sys.stderr if sys.stderr is not None else sys.__stderr__
            stream.write(f"{type(self).__name__} {self.instance_name}: {message}\n")
            stream.flush()
        except Exception:  # noqa: BLE001 - a closed stream must not kill the instance
            pass

    def terminate(self) -> None:
        """End the simulation: later steps are refused."""
        self._terminated = True

    # -- state -------------------------------------------------------------------------------
    def _state_names(self) -> list[str]:
        return [v.name for v in self.VARIABLES] + list(self.STATE) + [
            "time", "_initialized", "_ready", "_terminated", "_problems"]

    def _refused_initialization(self) -> str:
        """Why initialization was refused ("" if it was not)."""
        return "; ".join(self._problems) if self._initialized and not self._ready else ""

    def _get_fmu_state(self) -> dict[str, Any]:
        """The complete state, a JSON-able dict marked with the model's name; of an instance
        whose initialization was refused, a state that :meth:`_set_fmu_state` refuses."""
        refused = self._refused_initialization()
        if refused:
            why = (f"fmi2ExitInitializationMode refused this instance's parameters ({refused}), "
                   "so a state of it could never step; correct the parameters and "
                   "initialize first")
            self.refuse(f"getFMUstate refused: {why}")
            return {"invalid": f"the state was taken from an instance whose initialization "
                               f"was refused ({refused})"}
        fields = {name: getattr(self, name) for name in self._state_names()}
        return {_STATE_KEY: type(self).__name__, "fields": self.encode_state(fields)}

    def encode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        """Turn attributes that are objects into JSON-able values (override)."""
        return fields

    def decode_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        """Inverse of :meth:`encode_state`; raise ValueError if the fields do not fit."""
        return fields

    def _set_fmu_state(self, state: Any) -> None:
        """Restore a state from :meth:`_get_fmu_state`; refuse (logged) one that does not fit."""
        try:
            fields = self._checked_state(state)
        except (ValueError, TypeError, KeyError) as exc:
            self.refuse(f"setFMUstate refused: {exc}; the instance keeps its state")
            return
        for name, value in fields.items():
            setattr(self, name, value)
        self.state_restored()

    def state_restored(self) -> None:
        """A state was restored (override to refresh what derives from it)."""

    def _checked_state(self, state: Any) -> dict[str, Any]:
        if not isinstance(state, dict):
            raise ValueError(f"the state is a {type(state).__name__}, not a state of this FMU")
        if "invalid" in state and len(state) == 1:
            raise ValueError(str(state["invalid"]))
        owner = state.get(_STATE_KEY)
        if owner is None:
            raise ValueError(f"not a state of {type(self).__name__} (it names no model)")
        if owner != type(self).__name__:
            raise ValueError(f"the state belongs to {owner!r}, not to {type(self).__name__!r}")
        fields = state.get("fields")
        names = self._state_names()
        if not isinstance(fields, dict) or sorted(fields) != sorted(names):
            missing = sorted(set(names) - set(fields or {}))
            raise ValueError(f"the state does not hold this FMU's fields (missing: {missing})")
        by_name = {v.name: v for v in self.VARIABLES}
        for name, var in by_name.items():
            value = fields[name]
            want = _PY[var.type]
            ok = isinstance(value, want) or (want is float and isinstance(value, int)
                                            and not isinstance(value, bool))
            if not ok or (want is int and isinstance(value, bool)):
                raise ValueError(f"field {name} = {value!r} is not a {var.type}")
            if want is float and var.causality != "input" and not (
                    math.isfinite(value) or (var.inf_ok and value > 0)):
                raise ValueError(f"field {name} = {value!r} is not a finite number")
        if not isinstance(fields["time"], (int, float)) or not math.isfinite(fields["time"]):
            raise ValueError(f"field time = {fields['time']!r} is not a finite number")
        for flag in ("_initialized", "_ready", "_terminated"):
            if not isinstance(fields[flag], bool):
                raise ValueError(f"field {flag} = {fields[flag]!r} is not true or false")
        if not (isinstance(fields["_problems"], list)
                and all(isinstance(p, str) for p in fields["_problems"])):
            raise ValueError("field _problems is not a list of strings")
        if fields["_initialized"] and not fields["_ready"] and fields["_problems"]:
            raise ValueError("the state is of an instance whose initialization was refused ("
                             + "; ".join(fields["_problems"]) + ")")
        if fields["_ready"]:
            conflicts, others = self._parameter_problems(
                {v.name: fields[v.name] for v in self._parameters()})
            found = conflicts + others
            if found:
                raise ValueError(f"its parameters are invalid: {found[0][1]}")
        return self.decode_state(dict(fields))

    @staticmethod
    def _fmu_state_to_bytes(state: dict[str, Any]) -> bytes:
        return json.dumps(state).encode("utf-8")

    @staticmethod
    def _fmu_state_from_bytes(state: bytes) -> dict[str, Any]:
        """Parse serialized bytes; never raises (a bad state is refused by setFMUstate)."""
        try:
            value = json.loads(state.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            return {"invalid": f"the serialized state is not one of this FMU ({exc})"}
        if not isinstance(value, dict):
            return {"invalid": "the serialized state is not one of this FMU"}
        return value
