"""Observers: they watch slaves' variables and record them; they never change anything.

An observer implements :class:`Observer`: the execution calls ``setup`` once
(the observer asks to watch variables there), ``initialized`` when the slaves
are (re)initialized, ``step_complete`` after every step, ``step_failed`` when a
step fails and ``finished`` at the end of a run. An observer may stop a run
between two steps by raising from ``step_complete`` (:class:`StepGuard` does, after
a Ctrl-C or past the run's time limit); it never changes a slave.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from papwc.controllers import OUTPUT_NAMES
from papwc.interrupts import RunTimeout, interrupt_requested, interruption
from papwc.master.slave import Slave
from papwc.master.trace import PLANT_COLUMNS, REQUIRED_PLANT_COLUMNS, Trace

if TYPE_CHECKING:
    from papwc.master.execution import Execution

__all__ = ["Observer", "StepGuard", "TraceObserver", "VariableObserver"]


class Observer(Protocol):
    """What the execution calls on an observer."""

    def setup(self, execution: Execution) -> None:
        """Ask to watch variables (``slave.watch``) before the slaves are initialized."""
        ...

    def initialized(self, t: float) -> None:
        """The slaves are (re)initialized at time ``t`` (s)."""
        ...

    def step_complete(self, k: int, t: float) -> None:
        """Step ``k`` is done; the slaves are at ``t = t_(k+1)`` (s)."""
        ...

    def step_failed(self, k: int, t: float) -> None:
        """Step ``k`` from ``t`` (s) failed; the slave that failed is unchanged."""
        ...

    def finished(self, k: int, t: float) -> None:
        """The run ended after ``k`` steps, at ``t`` (s)."""
        ...


#: Trace columns read from the controller after its sample at t_k: its outputs but u.
_CONTROLLER = OUTPUT_NAMES


class TraceObserver:
    """Records one iteration of a closed loop as a :class:`~papwc.master.trace.Trace`.

    Row k holds the plant's outputs of :data:`~papwc.master.trace.PLANT_COLUMNS`
    (``x``, ``v``, ``x_meas``, ...) at t_k (after the manipulators: what the
    controller saw; NaN for an output the plant does not have, but ``x``, ``v`` and
    ``x_meas``, which it must have), the force ``u`` the plant got over
    [t_k, t_k+1], ``e = x_ref - x`` and the controller's ``mode``, ``pulses``
    and estimates and outcome after its sample at t_k. The last row is the
    state at the end, with ``u`` NaN.

    While running, it keeps a reference to each slave's list of values per
    sample (a slave makes a new list at every step); the columns are made from
    them when the iteration ends. The force is the controller's output ``u``
    as the plant got it: the one of the same sample with ``"immediate"``
    timing, of the sample before with ``"delayed"``.

    Parameters
    ----------
    plant, controller : Slave
        The plant (outputs x, v, x_meas at least) and the controller (the model layer's
        CONTROLLER_OUTPUTS), connected
        ``controller.u -> plant.u``.
    label : str
        Controller label of the trace.
    iteration : int
        Iteration number.
    T : float
        Sample period, s.
    x_ref : float
        Reference position, m.
    """

    def __init__(self, plant: Slave, controller: Slave, label: str, iteration: int,
                 T: float, x_ref: float) -> None:
        self.plant = plant
        self.controller = controller
        self.trace = Trace(label, iteration, T, x_ref)
        self._plant_rows: list[list] = []
        self._controller_rows: list[list] = []
        self._t0 = 0.0
        self._delayed = False

    def setup(self, execution: Execution) -> None:
        """Watch the plant's outputs and the controller's outputs; learn the timing."""
        known = self.plant.variables()
        self._plant_names = tuple(name for name in PLANT_COLUMNS
                                  if name in known or name in REQUIRED_PLANT_COLUMNS)
        self._plant_index = self.plant.watch(self._plant_names)
        (self._u,) = self.controller.watch(("u",))
        self._ctrl = self.controller.watch(_CONTROLLER)
        self._delayed = execution.algorithm.timing == "delayed"

    def new_trace(self, iteration: int) -> None:
        """Start recording a new iteration (same label, period and reference)."""
        old = self.trace
        self.trace = Trace(old.controller, iteration, old.T, old.x_ref)
        self._plant_rows = []
        self._controller_rows = []

    def initialized(self, t: float) -> None:
        """Start the rows with the plant's initial values at ``t`` (s)."""
        self._t0 = t
        self._plant_rows = [self.plant.values]
        self._controller_rows = []
        self._controller_start = self.controller.values

    def step_complete(self, k: int, t: float) -> None:
        """Keep the controller's values of sample k and the plant's at t_(k+1)."""
        self._controller_rows.append(self.controller.values)
        self._plant_rows.append(self.plant.values)

    def step_failed(self, k: int, t: float) -> None:
        """End the trace at sample k (its force is the one the plant refused)."""
        self._controller_rows.append(self.controller.values)
        self._fill()

    def finished(self, k: int, t: float) -> None:
        """End the trace with the state at the end (force NaN)."""
        self._controller_rows.append(self.controller.values)
        self._fill(last_u=math.nan)

    def cut(self) -> Trace:
        """The trace of a run stopped between two steps (Ctrl-C): the samples so far, the
        state reached last with force NaN, as :meth:`finished` ends it (no sample if the run
        stopped before its initialization ended)."""
        if self._plant_rows and len(self._plant_rows) > len(self._controller_rows):
            self.finished(0, 0.0)
        return self.trace

    def _fill(self, last_u: float | None = None) -> None:
        """The trace's columns from the rows kept (``last_u``: the force of the last row)."""
        plant_rows, ctrl_rows = self._plant_rows, self._controller_rows
        n = len(ctrl_rows)
        T, t0, x_ref = self.trace.T, self._t0, self.trace.x_ref
        cols = self.trace.columns
        cols["k"] = list(range(n))
        cols["t"] = [t0 + k * T for k in range(n)]
        # The rows transposed at once: one tuple per watched variable (all rows have
        # the length of the slave's watch list).
        plant = list(zip(*plant_rows[:n], strict=True)) if n else None
        ctrl = list(zip(*ctrl_rows, strict=True)) if n else None
        for name in PLANT_COLUMNS:
            cols[name] = [math.nan] * n
        for name, i in zip(self._plant_names, self._plant_index, strict=True):
            cols[name] = list(plant[i]) if n else []
        cols["e"] = [x_ref - x for x in cols["x"]]
        iu = self._u
        u = list(ctrl[iu]) if n else []
        if self._delayed and n:
            u = [self._controller_start[iu]] + u[:-1]
        if last_u is not None:
            u[-1] = last_u
        cols["u"] = u
        for name, i in zip(_CONTROLLER, self._ctrl, strict=True):
            cols[name] = list(ctrl[i]) if n else []


class StepGuard:
    """Stops a run between two steps: after a deferred Ctrl-C or SIGTERM, or past a deadline.

    Raises from :meth:`step_complete` KeyboardInterrupt (or
    :class:`~papwc.interrupts.Terminated`) once :func:`papwc.interrupts.deferred_interrupt`
    has caught a Ctrl-C or SIGTERM (looked at after every step), and
    :class:`~papwc.interrupts.RunTimeout` once ``time.monotonic()`` is past ``deadline``
    (looked at every :attr:`CLOCK_EVERY` steps; the clock costs more than the flag).

    Parameters
    ----------
    deadline : float, optional
        ``time.monotonic()`` value after which the run stops (None: no time limit).
    limit : float, optional
        The time limit the deadline stands for, s (for the message).
    """

    #: Communication steps between two looks at the clock of a run with a time limit.
    CLOCK_EVERY = 256

    def __init__(self, deadline: float | None = None, limit: float | None = None) -> None:
        self.deadline = deadline
        self.limit = limit
        self._steps = 0

    def setup(self, execution: Execution) -> None:
        """Nothing to watch."""

    def initialized(self, t: float) -> None:
        """Nothing to record (the steps are counted over every iteration of a run)."""

    def step_complete(self, k: int, t: float) -> None:
        """Raise if the run must stop now, at ``t`` (s); see :meth:`check`."""
        self.check(t)

    def check(self, t: float) -> None:
        """Raise KeyboardInterrupt after a deferred Ctrl-C, RunTimeout past the deadline.

        Parameters
        ----------
        t : float
            The communication point reached, s (named in the message).
        """
        if interrupt_requested():
            raise interruption()
        if self.deadline is not None:
            self._steps += 1
            if self._steps % self.CLOCK_EVERY == 0 and time.monotonic() > self.deadline:
                limit = "its time limit" if self.limit is None else f"{self.limit:g} s"
                raise RunTimeout(f"timed out: the run took longer than {limit} "
                                 f"(stopped at t = {t!r} s)")

    def step_failed(self, k: int, t: float) -> None:
        """Nothing to do: the failure ends the run."""

    def finished(self, k: int, t: float) -> None:
        """Nothing to do."""


class VariableObserver:
    """Records chosen variables of any slaves at every communication point.

    ``rows`` holds ``[t, value, ...]`` per communication point: the values
    after (re)initialization, then after every step; a failed step adds no row,
    so the rows before it stay. The list object is kept for the observer's
    life (a reader may hold it while the run goes on).

    Parameters
    ----------
    variables : sequence of (Slave, str)
        The slave and the name of each variable recorded, in column order.
    sink : callable, optional
        Called with each row instead of keeping it in ``rows``.
    """

    def __init__(self, variables: list[tuple[Slave, str]],
                 sink: Callable[[list], None] | None = None) -> None:
        self.variables = list(variables)
        self.rows: list[list] = []
        self._reads: list[tuple[Slave, list[int]]] = []
        #: Given, each row goes to it instead of into ``rows`` (a stream; none is kept).
        self.sink = sink

    def setup(self, execution: Execution) -> None:
        slaves: dict[int, tuple[Slave, list[str]]] = {}
        for slave, name in self.variables:
            slaves.setdefault(id(slave), (slave, []))[1].append(name)
        indexes = {id(slave): dict(zip(names, slave.watch(names), strict=True))
                   for slave, names in slaves.values()}
        self._columns = [(slave, indexes[id(slave)][name]) for slave, name in self.variables]

    def _record(self, t: float) -> None:
        row = [t, *[slave.values[i] for slave, i in self._columns]]
        if self.sink is None:
            self.rows.append(row)
        else:
            self.sink(row)

    def initialized(self, t: float) -> None:
        self.rows.clear()
        self._record(t)

    def step_complete(self, k: int, t: float) -> None:
        self._record(t)

    def step_failed(self, k: int, t: float) -> None:
        """Nothing to add: the rows before the failed step are kept."""

    def finished(self, k: int, t: float) -> None:
        """Nothing to add: every communication point is recorded."""
