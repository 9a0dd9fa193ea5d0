"""What the master steps: the :class:`Slave` interface and the in-process slaves.

A slave is a model with named variables that the master steps in time, as in
libcosim: an FMU (:class:`papwc.master.fmu.FmuSlave`), the plant's physics
computed in this process (:class:`PhysicsSlave`) or a Python controller
(:class:`ControllerSlave`). The master talks to every slave through the same
small interface:

1. ``set_start_values(values)``: parameters and input start values, applied at
   every (re)initialization;
2. ``watch(names)``: the variables (inputs or outputs) the master reads; their
   values are in the list ``slave.values`` after ``initialize``, ``restart``
   and every ``do_step``, at the indexes ``watch`` returns;
3. ``input_setter(names)``: a function ``set(*values)`` that sets those inputs;
4. ``initialize(t0)``, ``restart(t0)`` (back to the state right after
   initialization; a learning controller keeps what it has learned),
   ``do_step(t, h)`` and ``close()``.

Reading and writing go through prepared functions and a refreshed list so that
an FMU is called with prepared arguments, once per step and direction.
Failures raise :class:`papwc.errors.FmuError` naming the time and the call.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from operator import attrgetter
from types import SimpleNamespace
from typing import Any, Protocol

from papwc.controllers import Controller
from papwc.errors import FmuError
from papwc.model.controller_settings import CONTROLLER_INPUTS, CONTROLLER_OUTPUTS
from papwc.model.dynamics import OUTPUTS, Plant, output_reader
from papwc.model.plant import PLANT_DEFAULTS, PLANT_PARAMETERS, PLANT_VARIABLES, plant_problems

__all__ = ["ControllerInputs", "ControllerSlave", "PhysicsSlave", "SignalSlave", "Slave"]


class Slave(Protocol):
    """The interface every slave offers the master (see the module docstring)."""

    #: Instance name (e.g. ``"plant"``, ``"controller"``).
    name: str
    #: Values of the watched variables, in the order of the indexes ``watch`` returned.
    values: list[Any]

    def variables(self) -> Mapping[str, str]:
        """Causality (``"parameter"``, ``"input"``, ``"output"``, ...) of every variable."""
        ...

    def set_start_values(self, values: Mapping[str, Any]) -> None:
        """Parameters and input start values applied at every (re)initialization."""
        ...

    def watch(self, names: Sequence[str]) -> list[int]:
        """Have ``names`` read into :attr:`values` after each step; return their indexes."""
        ...

    def input_setter(self, names: Sequence[str]) -> Callable[..., None]:
        """A function ``set(*values)`` that sets the inputs ``names``, in that order."""
        ...

    def initialize(self, start_time: float) -> None:
        """Initialize with the start values; :attr:`values` then holds the initial values."""
        ...

    def restart(self, start_time: float) -> None:
        """Back to the state right after initialization (learned estimates are kept)."""
        ...

    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` over ``h`` (s) and refresh :attr:`values`."""
        ...

    def close(self) -> None:
        """Release what the slave holds."""
        ...


def _attribute_reader(paths: Sequence[str]) -> Callable[[Any], Sequence[Any]]:
    """``f(obj)`` returning ``(obj.<path>, ...)`` (dotted paths allowed).

    Two or more paths are read by one :func:`operator.attrgetter`, a single call
    without a Python frame: the cheapest way to read several attributes.
    """
    for path in paths:
        if not all(part.isidentifier() for part in path.split(".")):
            raise ValueError(f"not an attribute path: {path!r}")
    if len(paths) >= 2:
        return attrgetter(*paths)
    if not paths:
        return lambda obj: ()
    get_one = attrgetter(paths[0])
    return lambda obj: (get_one(obj),)


class _WatchedAttributes:
    """Watching and setting variables that are attributes of a Python object.

    A subclass maps each variable to an attribute path (:meth:`_path`), or gives
    its own reader (:meth:`_reader`); each refresh reads the watched values by one
    call of it into a new list.
    """

    name: str
    values: list[Any]

    def _init_watch(self) -> None:
        self.values = []
        self._watched: list[str] = []
        self._read: Callable[[Any], Sequence[Any]] = lambda obj: ()

    def watch(self, names: Sequence[str]) -> list[int]:
        """Read ``names`` into :attr:`values` after each step; return their indexes."""
        known = self.variables()
        indexes = []
        for name in names:
            if name not in known:
                raise FmuError(f"{self.name}: has no variable {name!r}; variables: "
                               + ", ".join(known))
            if name not in self._watched:
                self._watched.append(name)
            indexes.append(self._watched.index(name))
        self._read = self._reader(self._watched)
        return indexes

    def _refresh(self) -> None:
        self.values = list(self._read(self))

    def _attribute_setter(self, names: Sequence[str]) -> Callable[..., None]:
        """A setter of attribute inputs that also shows the values if they are watched."""
        shown = [(j, self._watched.index(n)) for j, n in enumerate(names) if n in self._watched]
        if len(names) == 1:
            (name,) = names
            if not shown:
                return partial(setattr, self, name)  # set_one below without the index
            index = shown[0][1]

            def set_one(value: Any) -> None:
                setattr(self, name, value)
                self.values[index] = value

            return set_one

        def set_all(*values: Any) -> None:
            for name, value in zip(names, values, strict=True):
                setattr(self, name, value)
            for j, i in shown:
                self.values[i] = values[j]

        return set_all

    def _reader(self, names: Sequence[str]) -> Callable[[Any], Sequence[Any]]:
        """``read(self)``: the values of ``names`` in order (by default the attributes
        :meth:`_path` names)."""
        return _attribute_reader([self._path(name) for name in names])

    def _path(self, name: str) -> str:
        raise NotImplementedError

    def variables(self) -> Mapping[str, str]:
        """Causality of every variable."""
        raise NotImplementedError


#: Parameters of the plant that are whole numbers.
_INTEGER_PARAMETERS = frozenset(v.name for v in PLANT_PARAMETERS if v.type == "Integer")


class PhysicsSlave(_WatchedAttributes):
    """The friction plant computed in this process by :class:`papwc.model.dynamics.Plant`.

    Same variables, units and parameter checks as FrictionPlant.fmu (both read
    :data:`papwc.model.plant.PLANT_VARIABLES`) and the same stepping object, whose
    outputs it reads as the FMU does (:data:`papwc.model.dynamics.OUTPUTS`), so
    the same trajectory to the last bit; fast, for analysis and tests.
    """

    def __init__(self, name: str = "plant") -> None:
        self.name = name
        self.params: dict[str, Any] = dict(PLANT_DEFAULTS)
        self.plant = Plant(self.params)
        self.u = 0.0
        self.p = SimpleNamespace(**self.params)
        self._init_watch()

    def variables(self) -> Mapping[str, str]:
        """Causality of every variable."""
        return {v.name: v.causality for v in PLANT_VARIABLES}

    def _reader(self, names: Sequence[str]) -> Callable[[Any], Sequence[Any]]:
        """Outputs from the plant (:func:`papwc.model.dynamics.output_reader`), the input
        ``u`` and the parameters from this slave."""
        if all(name in OUTPUTS for name in names):
            read_plant = output_reader(names)
            return lambda slave: read_plant(slave.plant)
        getters = []
        for name in names:
            if name in OUTPUTS:
                getters.append(lambda slave, value=OUTPUTS[name]: value(slave.plant))
            else:
                getters.append(attrgetter(name if name == "u" else f"p.{name}"))
        return lambda slave: [get(slave) for get in getters]

    @property
    def x(self) -> float:
        """Position, m."""
        return self.plant.x

    @property
    def v(self) -> float:
        """Velocity, m/s (exactly 0.0 while the mass is stuck)."""
        return self.plant.v

    def set_start_values(self, values: Mapping[str, Any]) -> None:
        """Parameters and input start values, applied at every (re)initialization."""
        unknown = [n for n in values if n not in self.params and n != "u"]
        if unknown:
            raise FmuError(f"{self.name}: the plant has no parameter "
                           + ", ".join(sorted(unknown)))
        for key, value in values.items():
            if key == "u":
                self.u = float(value)
            elif key in _INTEGER_PARAMETERS:
                # A whole float becomes an int; anything else is refused at initialization.
                whole = isinstance(value, float) and value.is_integer()
                self.params[key] = int(value) if whole else value
            else:
                self.params[key] = float(value)

    def input_setter(self, names: Sequence[str]) -> Callable[..., None]:
        """A function ``set(*values)`` that sets the inputs ``names``, in that order."""
        if list(names) != ["u"]:
            raise FmuError(f"{self.name}: the plant's only input is u, not {list(names)}")
        return self._attribute_setter(names)

    def initialize(self, start_time: float = 0.0) -> None:
        """Initialize with the start values; :attr:`values` then holds the initial values."""
        problems = plant_problems(self.params)
        if problems:
            raise FmuError("exitInitializationMode refused: "
                           + "; ".join(f"parameter {m}" for _, m in problems))
        self.p = SimpleNamespace(**self.params)
        self.plant = Plant(self.params)
        self._refresh()

    restart = initialize

    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` over ``h`` (s) and refresh :attr:`values`."""
        u = self.u
        if not (math.isfinite(u) and h > 0.0):
            raise FmuError(f"doStep at t = {t!r} s discarded: u = {u!r} N, step size = {h!r} s")
        reason = self.plant.step(u, h)
        if reason is not None:
            raise FmuError(f"doStep at t = {t!r} s discarded: {reason}")
        self._refresh()

    def close(self) -> None:
        """Nothing to release."""
        pass


#: Variables of a Python controller slave: its inputs, and the outputs every controller has
#: (the model layer's CONTROLLER_INPUTS but ``maneuver``, which ``restart`` stands for, and
#: CONTROLLER_OUTPUTS).
CONTROLLER_SLAVE_VARIABLES = {
    **{v.name: "input" for v in CONTROLLER_INPUTS if v.name != "maneuver"},
    **{v.name: "output" for v in CONTROLLER_OUTPUTS},
}


class ControllerInputs(_WatchedAttributes):
    """What every controller slave of the master does with its inputs (x_meas, x_ref,
    x_d_meas): start values applied at each (re)initialization, setters, ``u`` 0 after
    initialization. A subclass gives the controller's outputs (:meth:`_path` of an output)
    and the sample (``do_step``, ``restart``)."""

    name: str
    u: float

    def _init_inputs(self) -> None:
        self.x_meas = 0.0
        self.x_ref = 0.0
        self.x_d_meas = 0.0
        self.u = 0.0
        self._start: dict[str, float] = {}
        self._init_watch()

    def set_start_values(self, values: Mapping[str, Any]) -> None:
        """Parameters and input start values, applied at every (re)initialization."""
        for key in values:
            if CONTROLLER_SLAVE_VARIABLES.get(key) != "input":
                raise FmuError(f"{self.name}: {key!r} is not an input of the controller; "
                               "its settings are given when it is made")
        self._start.update(values)

    def input_setter(self, names: Sequence[str]) -> Callable[..., None]:
        """A function ``set(*values)`` that sets the inputs ``names``, in that order."""
        for name in names:
            if CONTROLLER_SLAVE_VARIABLES.get(name) != "input":
                raise FmuError(f"{self.name}: {name!r} is not an input of the controller")
        return self._attribute_setter(names)

    def initialize(self, start_time: float = 0.0) -> None:
        """Initialize with the start values; :attr:`values` then holds the initial values."""
        for key, value in self._start.items():
            setattr(self, key, value)
        self.u = 0.0
        self._refresh()

    def close(self) -> None:
        """Nothing to release."""
        pass


class ControllerSlave(ControllerInputs):
    """A Python controller (:class:`papwc.controllers.Controller`) as a slave.

    Like PulseController.fmu: ``do_step(t, h)`` samples the inputs ``x_meas``
    and ``x_ref`` (m) present at ``t`` and sets ``u`` (N), the force to hold
    over the next sample; the controller's :meth:`~papwc.controllers.Controller.outputs`
    (the model layer's ``CONTROLLER_OUTPUTS``) and any further estimates (``m_hat``,
    ...) are outputs. ``restart`` starts a new maneuver from rest with what the
    controller learned. When the controller only counted a sample
    (``idle_samples`` grew) the outputs are those of the sample before.
    """

    def __init__(self, controller: Controller, name: str = "controller") -> None:
        self.name = name
        self.controller = controller
        self.out = SimpleNamespace(**controller.estimates())
        self.out.__dict__.update(controller.outputs())
        self._revision = controller.revision
        self._init_inputs()

    def variables(self) -> Mapping[str, str]:
        """Causality of every variable."""
        out = dict(CONTROLLER_SLAVE_VARIABLES)
        out.update({name: "output" for name in vars(self.out) if name not in out})
        return out

    def _path(self, name: str) -> str:
        if name in ("x_meas", "x_ref", "x_d_meas", "u"):
            return name
        return f"out.{name}"

    def restart(self, start_time: float = 0.0) -> None:
        """A new maneuver from rest, keeping what the controller learned."""
        self.controller.reset()
        self.initialize(start_time)

    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` over ``h`` (s) and refresh :attr:`values`."""
        controller = self.controller
        idle = controller.idle_samples
        if controller.reads_x_d_meas:
            controller.x_d_meas = self.x_d_meas
        self.u = controller.update(t, self.x_meas, self.x_ref)
        if controller.idle_samples > idle:
            return  # a sample only counted: every output is the one of the last sample
        self._refresh()

    def _refresh(self) -> None:
        """Take the controller's outputs (its estimates when they changed), then read the
        watched values."""
        controller = self.controller
        values = self.out.__dict__
        if controller.revision != self._revision:
            values.update(controller.estimates())
            self._revision = controller.revision
        values.update(controller.outputs())
        self.values = list(self._read(self))


class SignalSlave(_WatchedAttributes):
    """Outputs that play given sequences, held over each step (zero-order hold).

    Like a controller, the slave sets its outputs for step k when it steps at
    t_k: with ``"immediate"`` timing, output ``name`` is ``signals[name][k]``
    over step k (from t_k to t_k+1), and its last value after the sequence
    ends. A force sequence played into a plant drives it open-loop.

    Parameters
    ----------
    signals : mapping of str to sequence of float
        Output name -> value per step.
    name : str
        Instance name.
    """

    def __init__(self, signals: Mapping[str, Sequence[float]], name: str = "signal") -> None:
        self.name = name
        self.signals = {key: list(values) for key, values in signals.items()}
        for key, values in self.signals.items():
            if not key.isidentifier() or not values:
                raise FmuError(f"{name}: signal {key!r} needs an identifier name and values")
            setattr(self, key, values[0])
        self._k = 0
        self._init_watch()

    def variables(self) -> Mapping[str, str]:
        """Causality of every variable."""
        return {key: "output" for key in self.signals}

    def _path(self, name: str) -> str:
        return name

    def set_start_values(self, values: Mapping[str, Any]) -> None:
        """Parameters and input start values, applied at every (re)initialization."""
        if values:
            raise FmuError(f"{self.name}: a signal has no parameters or inputs")

    def input_setter(self, names: Sequence[str]) -> Callable[..., None]:
        """A function ``set(*values)`` that sets the inputs ``names``, in that order."""
        raise FmuError(f"{self.name}: a signal has no inputs")

    def _show(self, k: int) -> None:
        for key, values in self.signals.items():
            setattr(self, key, values[min(k, len(values) - 1)])
        self._refresh()

    def initialize(self, start_time: float = 0.0) -> None:
        """Initialize with the start values; :attr:`values` then holds the initial values."""
        self._k = 0
        self._show(0)

    restart = initialize

    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` over ``h`` (s) and refresh :attr:`values`."""
        self._show(self._k)
        self._k += 1

    def close(self) -> None:
        """Nothing to release."""
        pass
