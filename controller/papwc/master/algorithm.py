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
from typing import Any

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
        self._after: Callable[[Slave], None] | None = None
        self._step: Callable[[float], None] = lambda t: None
        self._run: Callable[..., None] = lambda k0, k1, t0, done, at: None

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
        self._after = after_step
        namespace: dict[str, Any] = {"h": self.step_size, "after": after_step}
        transfers: list[str] = []
        steps: list[str] = []
        for j, slave in enumerate(slaves):
            links = [c for c in connections if c.target is slave]
            namespace[f"slave{j}"] = slave
            namespace[f"do_step{j}"] = slave.do_step
            lines: list[str] = []
            if links:
                namespace[f"set{j}"] = slave.input_setter([c.input for c in links])
                args = []
                for i, c in enumerate(links):
                    namespace[f"source{j}_{i}"] = c.source
                    index = c.source.watch([c.output])[0]
                    args.append(f"source{j}_{i}.values[{index}]")
                lines.append(f"set{j}({', '.join(args)})")
            transfers.append(lines)
            steps.append([f"do_step{j}(t, h)"]
                         + ([f"after(slave{j})"] if after_step is not None else []))
        if self.timing == "immediate":
            body = [line for tr, st in zip(transfers, steps, strict=True) for line in tr + st]
        else:
            body = [line for tr in transfers for line in tr] + [line for st in steps
                                                                for line in st]
        # One function made of the plan's statements, as dataclasses makes its methods:
        # a step costs no loop over slaves and no test of what the plan holds. ``run``
        # is the same statements in a loop over steps k0 <= k < k1 from t0, calling
        # each of ``done(k, t_(k+1))`` after a step and putting a failed step's k in
        # ``at[0]``; the parts are its local names (default arguments).
        lines = body or ["pass"]
        namespace["FmuError"] = FmuError
        local = ", ".join(f"{name}={name}" for name in namespace)
        source = ("def step(t):\n" + "".join(f"    {line}\n" for line in lines)
                  + f"def run(k0, k1, t0, done, at, {local}):\n"
                  + "    t = t0 + k0 * h\n"
                  + "    for k in range(k0, k1):\n"
                  + "        try:\n"
                  + "".join(f"            {line}\n" for line in lines)
                  + "        except FmuError:\n"
                  + "            at[0] = k\n"
                  + "            raise\n"
                  + "        t = t0 + (k + 1) * h\n"
                  + "        for f in done:\n"
                  + "            f(k, t)\n")
        exec(source, namespace)  # noqa: S102 - the statements are made here, from indexes
        self._step = namespace["step"]
        self._run = namespace["run"]

    def step(self, t: float) -> None:
        """One communication step from ``t``: transfer, step every slave, call ``after_step``.

        Raises
        ------
        FmuError
            From the slave whose step failed.
        """
        self._step(t)

    def run(self, k0: int, k1: int, t0: float, done: Sequence[Callable[[int, float], None]],
            at: list[int]) -> None:
        """Steps ``k0 <= k < k1`` from ``t_k = t0 + k*h``: what :meth:`step` does for each,
        then each of ``done(k, t_(k+1))``.

        Raises
        ------
        FmuError
            From the slave whose step failed; ``at[0]`` is then that step's k.
        """
        self._run(k0, k1, t0, done, at)


