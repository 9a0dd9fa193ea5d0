"""Manipulators: they change what one slave shows the others, between steps.

A manipulator implements :class:`Manipulator`: ``setup`` (watch what it acts
on), ``initialized`` when the slaves are (re)initialized and ``slave_stepped``
after a slave's step. It acts on the slave's watched values, which is what
connections pass on and observers record, never on the slave's own state.
"""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, Protocol

from papwc.master.slave import Slave

if TYPE_CHECKING:
    from papwc.master.execution import Execution

__all__ = ["Manipulator", "MeasurementNoise"]


class Manipulator(Protocol):
    """What the execution calls on a manipulator."""

    def setup(self, execution: Execution) -> None:
        """Watch the variables it acts on."""
        ...

    def initialized(self, t: float) -> None:
        """The slaves are (re)initialized at ``t`` (s)."""
        ...

    def slave_stepped(self, slave: Slave) -> None:
        """``slave`` has just stepped (its values are fresh)."""
        ...


class MeasurementNoise:
    """Gaussian noise added to a slave's output at every communication point.

    The noise of iteration ``i`` (from 1) is drawn from
    ``random.Random(seed * 1_000_003 + i)``, one number per communication point,
    so a run is reproduced exactly by its seed.

    Parameters
    ----------
    slave : Slave
        The slave whose output is measured (the plant).
    variable : str
        The output (``x_meas``).
    std : float
        Standard deviation, in the output's unit (m).
    seed : int
        Seed of the noise.
    """

    def __init__(self, slave: Slave, variable: str, std: float, seed: int) -> None:
        self.slave = slave
        self.variable = variable
        self.std = float(std)
        self.seed = int(seed)
        self.iteration = 1
        self._rng = random.Random(0)

    def setup(self, execution: Execution) -> None:
        """Watch the measured output."""
        (self._index,) = self.slave.watch((self.variable,))

    def initialized(self, t: float) -> None:
        """Seed the noise of this iteration; add it to the initial value."""
        self._rng = random.Random(self.seed * 1_000_003 + self.iteration)
        self._add()

    def slave_stepped(self, slave: Slave) -> None:
        """Add noise to the fresh value after the measured slave's step."""
        if slave is self.slave:
            self._add()

    def _add(self) -> None:
        values = self.slave.values
        values[self._index] = values[self._index] + self._rng.gauss(0.0, self.std)
