"""An execution: slaves, connections, an algorithm, observers and manipulators, assembled.

As in libcosim, the parts have one job each: the slaves compute
(:mod:`papwc.master.slave`, :mod:`papwc.master.fmu`), the algorithm steps them
over the connections (:mod:`papwc.master.algorithm`), manipulators change what
passes between them (:mod:`papwc.master.manipulators`) and observers record
(:mod:`papwc.master.observers`). Time is an integer step counter,
``t_k = t0 + k*h``.

Example: a closed loop stepped for 200 samples::

    execution = Execution(FixedStepAlgorithm(0.01, "immediate"))
    controller = execution.add_slave(ControllerSlave(make_controller(settings, 0.01)))
    plant = execution.add_slave(PhysicsSlave())
    execution.connect(plant, "x_meas", controller, "x_meas")
    execution.connect(controller, "u", plant, "u")
    execution.initialize()
    execution.step(200)
"""

from __future__ import annotations

from papwc.errors import FmuError
from papwc.master.algorithm import Connection, FixedStepAlgorithm
from papwc.master.manipulators import Manipulator
from papwc.master.observers import Observer
from papwc.master.slave import Slave

__all__ = ["Execution"]


class Execution:
    """Slaves stepped together by an algorithm, from ``start_time``.

    Parameters
    ----------
    algorithm : FixedStepAlgorithm
        How the slaves are stepped and values passed.
    start_time : float
        Time of the first communication point, s.
    """

    def __init__(self, algorithm: FixedStepAlgorithm, start_time: float = 0.0) -> None:
        self.algorithm = algorithm
        self.start_time = float(start_time)
        self.slaves: list[Slave] = []
        self.connections: list[Connection] = []
        self.observers: list[Observer] = []
        self.manipulators: list[Manipulator] = []
        #: Steps done since the last (re)initialization.
        self.k = 0
        self._ready = False

    # -- assembling ------------------------------------------------------------------------
    def add_slave(self, slave: Slave) -> Slave:
        """Add a slave (immediate timing steps the slaves in the order they are added)."""
        self.slaves.append(slave)
        self._ready = False
        return slave

    def connect(self, source: Slave, output: str, target: Slave, input: str) -> None:
        """Pass ``source.output`` to ``target.input`` at every step.

        Raises
        ------
        FmuError
            If a slave is not part of the execution, or a variable does not exist
            or has the wrong causality.
        """
        for slave, name, want in ((source, output, ("output", "input", "local")),
                                  (target, input, ("input",))):
            if slave not in self.slaves:
                raise FmuError(f"connection {source.name}.{output} -> {target.name}.{input}: "
                               f"{slave.name} is not a slave of this execution")
            causality = slave.variables().get(name)
            if causality not in want:
                raise FmuError(f"connection {source.name}.{output} -> {target.name}.{input}: "
                               f"{slave.name} has no {' or '.join(want[:1])} {name!r}")
        self.connections.append(Connection(source, output, target, input))
        self._ready = False

    def add_observer(self, observer: Observer) -> Observer:
        """Add an observer (it records; it changes nothing)."""
        self.observers.append(observer)
        self._ready = False
        return observer

    def add_manipulator(self, manipulator: Manipulator) -> Manipulator:
        """Add a manipulator (it changes the values slaves show each other)."""
        self.manipulators.append(manipulator)
        self._ready = False
        return manipulator

    # -- running ---------------------------------------------------------------------------
    def _setup(self) -> None:
        for part in (*self.observers, *self.manipulators):
            part.setup(self)
        manipulators = self.manipulators

        def after_step(slave: Slave) -> None:
            for m in manipulators:
                m.slave_stepped(slave)

        self.algorithm.setup(self.slaves, self.connections,
                             after_step if manipulators else None)
        self._ready = True

    def initialize(self) -> None:
        """Initialize every slave with its start values, at ``start_time``."""
        if not self._ready:
            self._setup()
        for slave in self.slaves:
            slave.initialize(self.start_time)
        self._initialized()

    def restart(self) -> None:
        """Every slave back to its state right after initialization (what controllers
        learned is kept)."""
        if not self._ready:
            self._setup()
        for slave in self.slaves:
            slave.restart(self.start_time)
        self._initialized()

    def _initialized(self) -> None:
        self.k = 0
        t = self.start_time
        for m in self.manipulators:
            m.initialized(t)
        for o in self.observers:
            o.initialized(t)

    def time(self, k: int | None = None) -> float:
        """Time of communication point ``k`` (default: the current one), s."""
        return self.start_time + (self.k if k is None else k) * self.algorithm.step_size

    def step(self, n: int = 1) -> None:
        """Do ``n`` communication steps; after each, every observer's ``step_complete``.

        An observer may stop the run between two steps by raising (the step guard of
        :mod:`papwc.master.observers` does); ``k`` then counts the steps done.

        Raises
        ------
        FmuError
            When a slave's step fails; observers are told (``step_failed``) first,
            and ``k`` stays at the failed step.
        """
        try:
            self.algorithm.run(self, n)
        except FmuError:
            k = self.k
            t = self.start_time + k * self.algorithm.step_size
            for o in self.observers:
                o.step_failed(k, t)
            raise

    def finish(self) -> None:
        """Tell the observers the run has ended."""
        for o in self.observers:
            o.finished(self.k, self.time())

    def close(self) -> None:
        """Close every slave."""
        for slave in self.slaves:
            slave.close()
