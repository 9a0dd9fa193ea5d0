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
from typing import TYPE_CHECKING, Any

from papwc.errors import FmuError
from papwc.master.slave import Slave
from papwc.model.maneuver import TIMINGS

if TYPE_CHECKING:
    from papwc.master.execution import Execution

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
        #: Per slave in stepping order: the slave, its ``do_step`` and its connections as
        #: (source, index of the source variable in ``source.values``, setter of the input).
        self._plan: list[tuple[Slave, Callable[[float, float], None],
                               tuple[tuple[Slave, int, Callable[[Any], None]], ...]]] = []
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
            transfers = []
            for c in connections:
                if c.target is slave:
                    setter = slave.input_setter([c.input])
                    transfers.append((c.source, c.source.watch([c.output])[0], setter))
            plan.append((slave, slave.do_step, tuple(transfers)))
        self._plan = plan
        self._after = after_step

    def run(self, execution: Execution, n: int) -> None:
        """Do ``n`` communication steps of ``execution`` from its step ``execution.k``.

        Each step k (from ``t_k = t0 + k*h``, ``t0`` the execution's start time)
        transfers, steps every slave and calls ``after_step``; with ``"immediate"``
        timing each slave takes its inputs just before it steps, with ``"delayed"``
        every slave takes them before any steps. Each connection sets its input by a
        setter of that input alone, with the source's current value. Then
        ``execution.k`` becomes k + 1 and every observer's ``step_complete(k,
        t_(k+1))`` is called (an observer that raises stops the run there).

        Raises
        ------
        FmuError
            From the slave whose step failed; ``execution.k`` is then that step's k.
        """
        h = self.step_size
        after = self._after
        plan = self._plan
        immediate = self.timing == "immediate"
        complete = [o.step_complete for o in execution.observers]
        t0 = execution.start_time
        k0 = execution.k
        steps_done = k0
        try:
            for k in range(k0, k0 + max(n, 0)):
                t = t0 + k * h
                for slave, do_step, transfers in plan:
                    for source, index, set_input in transfers:
                        set_input(source.values[index])
                    if immediate:
                        do_step(t, h)
                        if after is not None:
                            after(slave)
                if not immediate:
                    for slave, do_step, _ in plan:
                        do_step(t, h)
                        if after is not None:
                            after(slave)
                steps_done = k + 1
                t = t0 + steps_done * h
                for done in complete:
                    done(k, t)
        finally:
            execution.k = steps_done
