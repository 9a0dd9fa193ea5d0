"""The co-simulation algorithm: steps slaves at a fixed period over their connections.

Two ways of passing values between slaves (libcosim's fixed-step algorithm is
the second):

- ``"immediate"`` (Gauss-Seidel): the slaves step one after another in the
  order they were added, each taking its inputs from the latest values of the
  slaves it is connected to. A controller added before the plant reads the
  plant at t_k and the plant gets the force computed at t_k over
  [t_k, t_k+1], as a sampled-data controller with negligible computing time.
- ``"delayed"`` (Jacobi): every input is taken from the values at t_k before
  any slave steps, then all step. The force computed from the measurement at
  t_k reaches the plant one step later.

Time is the integer step counter k, ``t_k = t0 + k*h``; it is never accumulated.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from papwc.errors import FmuError
from papwc.master.slave import Slave
from papwc.model.maneuver import TIMINGS

__all__ = ["Connection", "FixedStepAlgorithm", "TIMINGS"]


@dataclass(frozen=True)
class Connection:
    """Output (or any watched variable) ``source.output`` feeds input ``target.input``."""

    source: Slave
    output: str
    target: Slave
    input: str


class FixedStepAlgorithm:
    """Steps slaves at a fixed step size with ``"immediate"`` or ``"delayed"`` transfer.

    Parameters
    ----------
    step_size : float
        Communication step h, s (> 0).
    timing : str
        ``"immediate"`` (Gauss-Seidel in the order the slaves were added) or
        ``"delayed"`` (Jacobi).
    """

    def __init__(self, step_size: float, timing: str = "immediate") -> None:
        if timing not in TIMINGS:
            raise FmuError(f"timing {timing!r}: must be one of {', '.join(TIMINGS)}")
        if not step_size > 0.0:
            raise FmuError(f"step size {step_size!r} s: must be > 0")
        self.step_size = float(step_size)
        self.timing = timing
        self._plan: list[_SlaveStep] = []
        self._after: Callable[[Slave], None] | None = None

    def setup(
        self,
        slaves: Sequence[Slave],
        connections: Sequence[Connection],
        after_step: Callable[[Slave], None] | None = None,
    ) -> None:
        """Prepare the transfers: watch every connected output, bind every connected input.

        ``after_step(slave)``, if given, is called after each slave's step (the
        manipulators act there).
        """
        plan = []
        for slave in slaves:
            links = [c for c in connections if c.target is slave]
            setter = slave.input_setter([c.input for c in links]) if links else None
            sources = tuple((c.source, c.source.watch([c.output])[0]) for c in links)
            plan.append(_SlaveStep(slave, setter, sources))
        self._plan = plan
        self._after = after_step

    def step(self, t: float) -> None:
        """One communication step from ``t``: transfer, step every slave, call ``after_step``.

        With ``"immediate"`` timing each slave takes its inputs just before it steps;
        with ``"delayed"`` every slave takes them before any steps.

        Raises
        ------
        FmuError
            From the slave whose step failed.
        """
        h = self.step_size
        after = self._after
        if self.timing == "immediate":
            for part in self._plan:
                part.transfer()
                part.slave.do_step(t, h)
                if after is not None:
                    after(part.slave)
            return
        for part in self._plan:
            part.transfer()
        for part in self._plan:
            part.slave.do_step(t, h)
            if after is not None:
                after(part.slave)


class _SlaveStep:
    """One slave of the plan: the setter of its connected inputs and where their values are.

    ``sources`` holds, per connected input in the setter's order, the source slave and
    the index of the source variable in its :attr:`~papwc.master.slave.Slave.values`.
    """

    __slots__ = ("setter", "slave", "sources")

    def __init__(self, slave: Slave, setter: Callable[..., None] | None,
                 sources: tuple[tuple[Slave, int], ...]) -> None:
        self.slave = slave
        self.setter = setter
        self.sources = sources

    def transfer(self) -> None:
        """Set the slave's connected inputs from the sources' current values."""
        setter = self.setter
        if setter is None:
            return
        sources = self.sources
        if len(sources) == 1:
            ((source, index),) = sources
            setter(source.values[index])
        else:
            setter(*[source.values[index] for source, index in sources])
