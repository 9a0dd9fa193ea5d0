"""Test helpers shared by the unit and integration tests (importable: ``tests/`` holds the
root conftest, so pytest puts this folder on ``sys.path``).

- :class:`FmuInstance`: the one fmpy harness. One instance of an FMU through fmpy's
  ``FMU2Slave`` with every log message kept, for the tests that must call FMI
  functions themselves (bad input, refusals, state get/set/serialize, logging). It
  also offers the master's :class:`papwc.master.Slave` interface, so that whatever
  stepping such a test needs is done by the master, not by a loop of its own.
- :class:`Recorder`: an observer of the master that records a slave's variables at
  every communication point.
- :func:`open_loop`: a plant driven open loop by a zero-order-hold force sequence
  through the master (:class:`papwc.master.SignalSlave` into the plant's ``u``).
- :class:`ScriptedController`: plays a fixed force sequence with the interface of
  :class:`papwc.controllers.Controller`.
- :func:`step_pulse`, :func:`segment`, :func:`stop_time`: independent references of
  the plant's motion (its own steps, to rest; 40-digit closed forms).
"""

from __future__ import annotations

import json
import math
import random
from collections.abc import Callable, Mapping, Sequence
from ctypes import byref
from decimal import Decimal, localcontext
from pathlib import Path
from typing import Any, NamedTuple

from papwc.controllers import Controller
from papwc.master import (
    Execution,
    FixedStepAlgorithm,
    Maneuver,
    PhysicsSlave,
    SignalSlave,
    Slave,
    run_controller,
)
from papwc.model.controller_settings import fmu_parameters
from papwc.model.plant import ACCELERATION_MAX, DAMPING_RATE_MAX, MODE_FREQUENCY_MAX
from papwc.model.stickslip import simulate

#: The plant of the paper's Table 1 (SI units), and as a scenario file's table.
TABLE_1 = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
TABLE_1_TOML = "".join(["[plant]\n", *(f"{k} = {v!r}\n" for k, v in TABLE_1.items())])


#: The deviations of a real machine of scenarios/realism.toml (one seed each), as plant
#: parameters to add to :data:`TABLE_1`.
DEVIATIONS = {
    "stribeck": {"v_s": 1e-3},
    "lugre": {"sigma_0": 6.5e7, "sigma_1": 2e5, "v_s": 1e-3},
    "ripple": {"ripple": 0.1, "ripple_period": 1e-3},
    "stiction": {"f_s_spread": 0.1, "seed": 3},
    "lag": {"tau_u": 2e-3},
    "flexible": {"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3},
    "noise": {"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 2},
}


#: Each deviation at the values of scenarios/realism.toml and at variants of them (a Stribeck
#: exponent of 1, a light LuGre with ripple, ripple with a phase), and all that combine.
REALISM_VARIANTS = {
    "stribeck": {"v_s": 1e-3},
    "stribeck_delta1": {"v_s": 2e-3, "delta_s": 1.0},
    "lugre": {"sigma_0": 6.5e7, "sigma_1": 2e5, "v_s": 1e-3},
    "lugre_light": {"sigma_0": 6.5e6, "sigma_1": 1e4, "v_s": 1e-3, "ripple": 0.1},
    "ripple": {"ripple": 0.1, "ripple_period": 1e-3, "ripple_phase": 0.3},
    "stiction": {"f_s_spread": 0.1, "seed": 3},
    "lag": {"tau_u": 2e-3},
    "flexible": {"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3},
    "all": {"v_s": 1e-3, "ripple": 0.1, "f_s_spread": 0.1, "seed": 8, "tau_u": 2e-3,
            "m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3},
}


def _realism_pulse_controllers() -> dict[str, dict[str, Any]]:
    """The pulse controllers of scenarios/realism.toml by kind (their settings, no label)."""
    import tomllib

    from papwc.resources import scenario_file

    with open(scenario_file("realism.toml"), "rb") as f:
        tables = tomllib.load(f)["controller"]
    return {t["kind"]: {k: v for k, v in t.items() if k != "label"}
            for t in tables if t["kind"] in ("pwc", "papwc", "exact")}


#: The settings of the pulse controllers of scenarios/realism.toml (pwc, papwc, exact).
REALISM_SETTINGS = _realism_pulse_controllers()


#: Relative margin a hypothesis strategy keeps from a bound it derives from values it drew:
#: a bound computed in floating point lands an ulp or so either side of the exact one (issue
#: 44: ``m = c / DAMPING_RATE_MAX`` gave ``c/m = 10000.000000000002``, which the plant rightly
#: refuses), so a strategy draws within the bound by this margin, never at it.
BOUND_MARGIN = 1e-9


def inside_max(bound: float) -> float:
    """The largest value a strategy draws under the derived upper bound ``bound`` (> 0)."""
    return bound * (1.0 - BOUND_MARGIN)


def inside_min(bound: float) -> float:
    """The smallest value a strategy draws over the derived lower bound ``bound`` (> 0)."""
    return bound * (1.0 + BOUND_MARGIN)


# The integrated plant's bounds between parameters (papwc.model.plant), as the strategies
# derive them from values they drew: each with its margin.


def lowest_integrated_mass(f_s: float, c: float) -> float:
    """The smallest mass, kg, of an integrated plant with breakaway force ``f_s`` (N) and
    damping ``c`` (N.s/m): ``f_s/m <= ACCELERATION_MAX`` and ``c/m <= DAMPING_RATE_MAX``."""
    return inside_min(max(f_s / ACCELERATION_MAX, c / DAMPING_RATE_MAX))


def highest_damping(m: float) -> float:
    """The largest damping ``c``, N.s/m, of an integrated plant of mass ``m`` (kg)."""
    return inside_max(m * DAMPING_RATE_MAX)


def highest_mode_stiffness(m: float, m_d: float = math.inf) -> float:
    """The largest stiffness, N/m, whose mode is at most MODE_FREQUENCY_MAX: the coupling
    ``k_t`` of a flexible drive of motor mass ``m_d`` (kg), or LuGre's ``sigma_0``
    (``m_d`` infinite)."""
    return inside_max((2.0 * math.pi * MODE_FREQUENCY_MAX) ** 2 / (1.0 / m + 1.0 / m_d))


def highest_coupling_damping(m: float, m_d: float) -> float:
    """The largest coupling damping ``c_t``, N.s/m, of a flexible drive."""
    return inside_max(DAMPING_RATE_MAX / (1.0 / m + 1.0 / m_d))


def table_1(**changes: Any) -> dict[str, Any]:
    """The plant of Table 1 with ``changes`` (other values, deviations of a real machine)."""
    return {**TABLE_1, **changes}


def run_on_physics(plant: Mapping[str, Any], settings: Any, **maneuver: Any) -> Any:
    """Run the controller of ``settings`` on the master's in-process plant with parameters
    ``plant`` over a :class:`papwc.master.Maneuver` of fields ``maneuver``; the run must
    end without error. Returns the :class:`papwc.master.RunResult`."""
    slave = PhysicsSlave()
    slave.set_start_values(plant)
    result = run_controller(slave, settings, Maneuver(**maneuver))
    assert not result.error, result.error
    return result

def toml_value(value: Any) -> str:
    """A value as a scenario file writes it (TOML; a mapping as an inline table)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(_toml_pairs(value)) + " }"
    return repr(value)


def _toml_pairs(values: Mapping[str, Any]) -> list[str]:
    """``key = value`` for each entry (a key with a dot, as ``"plant.m"``, quoted)."""
    return [f"{k if k.replace('_', '').isalnum() else json.dumps(k)} = {toml_value(v)}"
            for k, v in values.items()]


def scenario_toml(name: str, *, plant: Mapping[str, Any] | None = None,
                  maneuver: Mapping[str, Any] | None = None,
                  controllers: Sequence[Mapping[str, Any]] = (),
                  tables: Mapping[str, Mapping[str, Any]] | None = None,
                  tail: str = "") -> str:
    """The text of a scenario (or battery) file.

    ``name``; the ``[plant]`` and ``[maneuver]`` tables (left out when None); one
    ``[[controller]]`` table per mapping of ``controllers``; each of ``tables`` (a
    battery's ``sweep``, ``monte_carlo``, ``battery``) by its name; then ``tail``
    as it is.
    """
    lines = [f"name = {toml_value(name)}"]
    for table, values in (("plant", plant), ("maneuver", maneuver), *(tables or {}).items()):
        if values is not None:
            lines += [f"[{table}]", *_toml_pairs(values)]
    for controller in controllers:
        lines += ["[[controller]]", *_toml_pairs(controller)]
    return "\n".join(lines) + "\n" + tail


#: The paper's PWC and PAPWC controllers of scenarios/paper.toml (t_p_max = 0.03 s).
PWC_PAPER = {"kind": "pwc", "t_p_max": 0.03, "K_c": 0.5, "tolerance": 0.0}
PAPWC_PAPER = {"kind": "papwc", "t_p_max": 0.03, "K_c": 0.8}

#: A valid scenario: one PAPWC controller, one 0.5 s iteration.
GOOD = scenario_toml("t", plant={"m": 150.0},
                     maneuver={"x_ref": 0.01, "T": 0.01, "duration": 0.5, "iterations": 1},
                     controllers=[{"kind": "papwc"}])

#: A short version of the paper's scenario (two iterations of 0.5 s).
SHORT_PAPER = scenario_toml("short", maneuver={"x_ref": 0.01, "duration": 0.5, "iterations": 2},
                            controllers=[PWC_PAPER, PAPWC_PAPER])

__all__ = [
    "FmuInstance",
    "Message",
    "Recorder",
    "ScriptedController",
    "open_loop",
    "random_forces",
    "run_on_physics",
    "scenario_toml",
    "segment",
    "settings_start_values",
    "step_pulse",
    "stop_time",
    "table_1",
]

#: fmi2Status codes, as the logger and FMICallException report them.
FMI2_OK, FMI2_WARNING, FMI2_DISCARD, FMI2_ERROR, FMI2_FATAL = range(5)


class Message(NamedTuple):
    """One message the FMU logged."""

    status: int
    category: str
    text: str


#: Messages of every :class:`FmuInstance` by its componentEnvironment: fmpy's logger proxy
#: keeps one logger per process, so every instance shares :data:`_LOGGER`, which tells them
#: apart by the environment they were instantiated with.
_MESSAGES: dict[int, list[Message]] = {}


def _log(env, instance, status, category, message) -> None:
    _MESSAGES.setdefault(env or 0, []).append(
        Message(status, (category or b"").decode(), (message or b"").decode()))


_LOGGER = None


class FmuInstance:
    """One FMU instance through fmpy's ``FMU2Slave``, its log messages kept.

    The raw instance is :attr:`fmu` (``getFMUstate``, ``doStep``, ...); :meth:`set`
    and :meth:`get` set and read variables of any type by name, :meth:`init` runs
    the initialization with start values, :meth:`advance` steps from the
    communication point :attr:`t`. As a :class:`papwc.master.Slave` it can be
    added to an :class:`papwc.master.Execution` (start values from
    :meth:`set_start_values`; ``restart`` is not offered: use the raw state calls).

    Parameters
    ----------
    unzipdir : Path
        The extracted FMU.
    name : str
        Instance name.
    logging : bool
        ``loggingOn`` of fmi2Instantiate.
    guid : str, optional
        The GUID passed to fmi2Instantiate (default: the model description's).
    """

    def __init__(self, unzipdir: Path, name: str = "instance", logging: bool = True,
                 guid: str | None = None) -> None:
        from fmpy import read_model_description
        from fmpy.fmi1 import calloc, free
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )
        from fmpy.logging import addLoggerProxy

        global _LOGGER
        if _LOGGER is None:
            _LOGGER = fmi2CallbackLoggerTYPE(_log)
        self.name = name
        self.md = read_model_description(str(unzipdir))
        self.vars = {v.name: v for v in self.md.modelVariables}
        env = len(_MESSAGES) + 1
        self.messages: list[Message] = _MESSAGES.setdefault(env, [])
        self.values: list[Any] = []
        self.start: dict[str, Any] = {}
        self.watched: list[str] = []
        self.resume_state: Any = None
        #: Communication point of the next :meth:`advance`, s.
        self.t = 0.0
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.componentEnvironment = env
        self.callbacks.logger = _LOGGER
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(self.callbacks))
        self.fmu = FMU2Slave(
            guid=guid or self.md.guid,
            unzipDirectory=str(unzipdir),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate(callbacks=self.callbacks, loggingOn=logging)

    def logged(self, status: int) -> list[str]:
        """Texts of the messages logged with ``status``."""
        return [m.text for m in self.messages if m.status == status]

    # -- values by name ------------------------------------------------------------------------
    def set(self, name: str, value: Any) -> None:
        """Set one variable (Real, Integer, Boolean or String)."""
        var = self.vars[name]
        vr = [var.valueReference]
        if var.type == "Real":
            self.fmu.setReal(vr, [float(value)])
        elif var.type in ("Integer", "Enumeration"):
            self.fmu.setInteger(vr, [int(value)])
        elif var.type == "Boolean":
            self.fmu.setBoolean(vr, [bool(value)])
        else:
            self.fmu.setString(vr, [str(value)])

    def get(self, name: str) -> Any:
        """Value of one variable."""
        var = self.vars[name]
        vr = [var.valueReference]
        if var.type == "Real":
            return self.fmu.getReal(vr)[0]
        if var.type in ("Integer", "Enumeration"):
            return self.fmu.getInteger(vr)[0]
        if var.type == "Boolean":
            return bool(self.fmu.getBoolean(vr)[0])
        return self.fmu.getString(vr)[0].decode()

    def get_many(self, *names: str) -> list[Any]:
        """Values of several variables, in order."""
        return [self.get(name) for name in names]

    def init(self, start_time: float = 0.0, **start: Any) -> None:
        """setupExperiment, enter initialization, set ``start``, exit initialization."""
        self.t = start_time
        self.fmu.setupExperiment(startTime=start_time)
        self.fmu.enterInitializationMode()
        for name, value in start.items():
            self.set(name, value)
        self.fmu.exitInitializationMode()

    def advance(self, h: float, **inputs: Any) -> None:
        """Set ``inputs``, then fmi2DoStep from :attr:`t` over ``h`` (s); :attr:`t` moves on
        by ``h`` when the step is done."""
        for name, value in inputs.items():
            self.set(name, value)
        self.fmu.doStep(self.t, h)
        self.t += h

    # -- the master's Slave interface ----------------------------------------------------------
    def variables(self) -> Mapping[str, str]:
        return {name: v.causality for name, v in self.vars.items()}

    def set_start_values(self, values: Mapping[str, Any]) -> None:
        self.start.update(values)

    def watch(self, names: Sequence[str]) -> list[int]:
        for name in names:
            if name not in self.watched:
                self.watched.append(name)
        return [self.watched.index(name) for name in names]

    def refresh(self) -> None:
        """Read the watched variables into :attr:`values` (after a raw FMI call)."""
        self.values = self.get_many(*self.watched)

    def input_setter(self, names: Sequence[str]) -> Callable[..., None]:
        def set_inputs(*values: Any) -> None:
            for name, value in zip(names, values, strict=True):
                self.set(name, value)

        return set_inputs

    def resume_from(self, state: Any) -> None:
        """Have the next :meth:`initialize` restore the FMU state ``state`` (from
        ``fmu.getFMUstate`` or ``fmu.deSerializeFMUstate``) instead of initializing: a
        master then continues the instance from there."""
        self.resume_state = state

    def initialize(self, start_time: float = 0.0) -> None:
        if self.resume_state is not None:
            state, self.resume_state = self.resume_state, None
            self.fmu.setFMUstate(state)
        else:
            self.init(start_time, **self.start)
        self.refresh()

    def restart(self, start_time: float = 0.0) -> None:
        raise NotImplementedError("FmuInstance: restore a state with fmu.setFMUstate instead")

    def do_step(self, t: float, h: float) -> None:
        self.fmu.doStep(t, h)
        self.refresh()

    def close(self, terminate: bool = True) -> None:
        """fmi2Terminate (unless ``terminate`` is False: already done, or not allowed in the
        instance's state) and fmi2FreeInstance."""
        if terminate:
            self.fmu.terminate()
        self.fmu.freeInstance()


class Recorder:
    """Observer of the master: ``slave``'s variables ``names`` at every communication point.

    ``rows[k]`` holds the values at t_k (``rows[0]`` right after (re)initialization);
    a failed step adds no row.
    """

    def __init__(self, slave: Slave, names: Sequence[str]) -> None:
        self.slave = slave
        self.names = tuple(names)
        self.rows: list[tuple[Any, ...]] = []

    def setup(self, execution: Execution) -> None:
        self.index = self.slave.watch(self.names)

    def current_row(self) -> tuple[Any, ...]:
        """The watched values of the slave now."""
        values = self.slave.values
        return tuple(values[i] for i in self.index)

    def initialized(self, t: float) -> None:
        self.rows = [self.current_row()]

    def step_complete(self, k: int, t: float) -> None:
        self.rows.append(self.current_row())

    def step_failed(self, k: int, t: float) -> None:
        pass

    def finished(self, k: int, t: float) -> None:
        pass

    def column(self, name: str) -> list[Any]:
        """The values of ``name`` at every communication point recorded."""
        i = self.names.index(name)
        return [row[i] for row in self.rows]

    def states(self) -> list[tuple[float, float]]:
        """``(x, v)`` at every communication point (``names`` must hold x and v)."""
        return list(zip(self.column("x"), self.column("v"), strict=True))


def open_loop(
    plant: Slave,
    u_seq: Sequence[float],
    T: float,
    names: Sequence[str] = ("x", "v", "x_meas", "stuck"),
    steps: int | None = None,
    start_time: float = 0.0,
) -> tuple[Execution, Recorder]:
    """Drive ``plant`` open loop with the force sequence ``u_seq`` (N) through the master.

    A :class:`papwc.master.SignalSlave` plays ``u_seq`` (zero-order hold, step k over
    [t_k, t_k+1]) into the plant's input ``u``; a :class:`Recorder` keeps the
    plant's ``names``. The execution is initialized and stepped ``steps`` times
    (default: ``len(u_seq)``) from ``start_time`` (s); it is returned with the recorder
    to step further.
    """
    execution = Execution(FixedStepAlgorithm(T, "immediate"), start_time)
    signal = execution.add_slave(SignalSlave({"u": list(u_seq)}, name="force"))
    execution.add_slave(plant)
    execution.connect(signal, "u", plant, "u")
    recorder = execution.add_observer(Recorder(plant, names))
    execution.initialize()
    execution.step(len(u_seq) if steps is None else steps)
    return execution, recorder


def settings_start_values(settings, T: float) -> dict[str, Any]:
    """PulseController.fmu start values of ``settings`` (None and inf by their switches, see
    :func:`papwc.model.controller_settings.fmu_parameters`) and period ``T`` (s)."""
    values = fmu_parameters(settings.to_mapping(with_none=True))
    values["T"] = T
    return values


class ScriptedController(Controller):
    """Plays a fixed force sequence (N); the interface of papwc.controllers.Controller."""

    def __init__(self, forces: Sequence[float], T: float = 0.01) -> None:
        self.forces = list(forces)
        self.T = T
        self.mode = 1
        self.pulses = 0
        self.f_low = math.nan
        self.outcome = 0  # papwc.controllers.Outcome.ACTIVE
        self.outcome_reason = 0
        self.revision = 0
        self.idle_samples = 0  # never only counts a sample

    def reset(self) -> None:
        pass

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        k = int(round(t / self.T))
        return self.forces[k] if k < len(self.forces) else 0.0

    def estimates(self) -> dict[str, float]:
        return {"b_hat": math.nan, "f_c_hat": math.nan}


def random_forces(seed: int, n: int) -> list[float]:
    """``n`` zero-order-hold forces (N) of the Table 1 plant, drawn from ``seed``: pulses
    above f_s, rests, forces below breakaway."""
    rng = random.Random(seed)
    out: list[float] = []
    while len(out) < n:
        kind = rng.random()
        if kind < 0.3:
            out += [rng.choice((-1.0, 1.0)) * rng.uniform(140.0, 300.0)] * rng.randint(1, 4)
        elif kind < 0.65:
            out += [0.0] * rng.randint(1, 8)
        else:
            out += [rng.uniform(-130.0, 130.0)] * rng.randint(1, 5)
    return out[:n]


# -- independent references of the plant's motion ----------------------------------------------
def step_pulse(f_p, n, h, m, f_c, f_s, c):
    """Displacement of an n-sample pulse from rest to rest, from the plant's own steps.

    :func:`papwc.model.stickslip.simulate` applies ``f_p`` over n steps of size h,
    then u = 0 until the velocity is exactly 0.0 (the coast is bounded by the
    Coulomb friction alone: at most ``m*|v|/f_c`` s). A reference of the physics
    built from :func:`~papwc.model.stickslip.step`, independent of the closed
    forms of :mod:`papwc.model.pulse`.
    Returns (d, velocity at pulse end, number of coasting steps).
    """
    pulse = simulate([f_p] * n, h, m, f_c, f_s, c)
    x_end, v_end = pulse[-1]
    if v_end == 0.0:
        return x_end, v_end, 0
    assert f_c > 0.0, "without Coulomb friction the mass never comes to rest"
    n_coast = math.ceil(m * abs(v_end) / (f_c * h)) + 2
    coast = simulate([0.0] * n_coast, h, m, f_c, f_s, c, x0=x_end, v0=v_end)
    k = next(i for i, (_, v) in enumerate(coast) if v == 0.0)
    assert all(state == coast[k] for state in coast[k:]), "the mass did not stay at rest"
    return coast[k][0], v_end, k


def _dec(*values):
    return (Decimal(float(q)) for q in values)


def segment(x0, v0, force, t, m, c):
    """State after time t under a constant net force (no friction switching).

    Evaluated with 40 significant digits, so the closed forms are accurate for any
    c >= 0 despite their cancellation at small c*t/m.
    """
    with localcontext() as ctx:
        ctx.prec = 40
        x0, v0, force, t, m, c = _dec(x0, v0, force, t, m, c)
        if c == 0:
            return float(x0 + v0 * t + force * t * t / (2 * m)), float(v0 + force * t / m)
        a = c / m
        v_inf = force / c
        decay = (-a * t).exp()
        x = x0 + v_inf * t + (v0 - v_inf) * (1 - decay) / a
        return float(x), float(v_inf + (v0 - v_inf) * decay)


def stop_time(v0, force, m, c):
    """Time at which a mass sliding at v0 under a decelerating net force stops."""
    with localcontext() as ctx:
        ctx.prec = 40
        v0, force, m, c = _dec(v0, force, m, c)
        if c == 0:
            return float(-m * v0 / force)
        return float((m / c) * (1 - c * v0 / force).ln())


def hard_runaways(traces: Sequence[Any], plant: Mapping[str, Any], T: float) -> list[dict]:
    """The pulses of ``traces`` on ``plant`` that a hard requirement of the spec forbids
    (:func:`papwc.battery.spec.hard_pulses`: beyond their bound at abs(e) >= 50 um, planned
    and beyond it at abs(e) >= 1 um, or moving more than 20 um below 1 um), each with its
    iteration."""
    from papwc.battery.spec import hard_pulses
    from papwc.results.pulses import PulseBound

    bound = PulseBound(plant, T)
    return hard_pulses([{"iteration": trace.iteration, **row} for trace in traces
                        for row in bound.rows(trace)])

