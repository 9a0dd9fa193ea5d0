"""Running an SSP 1.0 system of FMI 2.0 Co-Simulation FMUs with the project's master.

:func:`run_ssp` runs a system read by :func:`papwc.master.ssd.read_ssp` as
libcosim's fixed-step algorithm does: every component an
:class:`~papwc.master.fmu.FmuSlave`, all stepped side by side at the fixed step
with the values of the previous communication point
(:class:`~papwc.master.algorithm.FixedStepAlgorithm` with ``"delayed"``
timing, Jacobi), the outputs passed to the connected inputs after
initialization, and records the chosen variables at every communication point
(:class:`~papwc.master.observers.VariableObserver`).
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from papwc.errors import FmuError, SspError
from papwc.master.algorithm import FixedStepAlgorithm
from papwc.master.execution import Execution
from papwc.master.observers import VariableObserver
from papwc.master.ssd import MAX_MEMBER_BYTES, SspArchive, SspSystem, read_ssp

__all__ = ["SspRun", "SspSession", "read_ssp", "run_ssp"]

#: Most communication steps one run may take.
MAX_STEPS = 10_000_000


@dataclass
class SspRun:
    """The recorded variables of a run: ``columns`` (``time`` first) and ``rows``."""

    system: SspSystem
    columns: list[str]
    rows: list[list[Any]]
    step_size: float
    error: str = ""


def _check_experiment(system: SspSystem, step: float | None, stop: float | None,
                      start: float | None) -> tuple[float, float, float, int]:
    t0 = system.start_time if start is None else float(start)
    t1 = system.stop_time if stop is None else float(stop)
    h = system.step_size if step is None else float(step)
    where = f"{system.path}"
    if step is None and system.step_conflict:
        raise SspError(system.step_conflict)
    if h is None:
        raise SspError(f"{where}: the SSD gives no fixed step (osp:FixedStepAlgorithm or "
                       "oms:FixedStepMaster): give --step")
    if t1 is None:
        raise SspError(f"{where}: the SSD's ssd:DefaultExperiment gives no stopTime: give "
                       "--stop")
    for name, value in (("start time", t0), ("stop time", t1), ("step", h)):
        if not math.isfinite(value):
            raise SspError(f"{where}: {name} = {value!r} s: must be a finite number")
    if not h > 0.0:
        raise SspError(f"{where}: step = {h!r} s: must be > 0")
    if not t1 > t0:
        raise SspError(f"{where}: stop time {t1!r} s: must be after the start time {t0!r} s")
    steps = (t1 - t0) / h  # finite or inf, never an exception
    if not steps <= MAX_STEPS:
        raise SspError(f"{where}: ({t1!r} - {t0!r}) s / {h!r} s = {steps:.4g} steps; at most "
                       f"{MAX_STEPS}")
    return t0, t1, h, max(round(steps), 1)


class SspSession:
    """A checked system's FMUs loaded, connected and observed, to initialize and run.

    Used as a context manager: entering loads every component (its FMU read
    from the archive into a private temporary folder, unpacked, loaded); leaving
    closes every FMU and removes every file it unpacked. Each recorded row
    (``[t, value, ...]``, columns :attr:`columns`) goes to :attr:`sink` if one
    is set, else into :attr:`pending`: a caller streams the rows of a long run
    to a file and holds none of them.

    Parameters
    ----------
    system, variables, step, stop, start
        As :func:`run_ssp`'s.

    Raises
    ------
    SspError
        For a variable or an experiment setting that does not fit (at
        construction, before any FMU is loaded).
    FmuError
        If an FMU cannot be loaded (entering) or refuses its initialization.
    """

    def __init__(self, system: SspSystem, variables: Sequence[str] | None = None,
                 step: float | None = None, stop: float | None = None,
                 start: float | None = None) -> None:
        self.system = system
        self.t0, _t1, self.step_size, self.steps = _check_experiment(system, step, stop, start)
        names = list(variables) if variables else system.outputs()
        self.watched: list[tuple[str, str]] = []
        for name in names:
            owner, _, variable = name.partition(".")
            component = system.components.get(owner)
            if component is None:
                raise SspError(f"--variables {name}: no component {owner!r}; write "
                               "component.variable, components: " + ", ".join(system.components))
            if variable not in component.variables:
                raise SspError(f"--variables {name}: the FMU {component.source} of component "
                               f"{owner!r} has no variable {variable!r}")
            if component.variables[variable][1] == "String":
                raise SspError(f"--variables {name}: a String variable cannot be recorded")
            self.watched.append((owner, variable))
        self.columns = ["time", *names]
        #: Rows recorded while no sink is set.
        self.pending: list[list[Any]] = []
        #: Called with each row as it is recorded (None: rows go to ``pending``).
        self.sink: Callable[[list[Any]], None] | None = None
        #: Communication steps done.
        self.k = 0
        self._tmp: tempfile.TemporaryDirectory | None = None
        self._slaves: dict[str, Any] = {}
        self._execution: Execution | None = None

    def _record(self, row: list[Any]) -> None:
        if self.sink is None:
            self.pending.append(row)
        else:
            self.sink(row)

    def __enter__(self) -> SspSession:
        from papwc.master.fmu import FmuSlave

        system = self.system
        self._tmp = tempfile.TemporaryDirectory(prefix="papwcssp")
        execution = self._execution = Execution(FixedStepAlgorithm(self.step_size, "delayed"),
                                                start_time=self.t0)
        try:
            archive = SspArchive(system.path)
            try:
                for name, component in system.components.items():
                    fmu_path = Path(self._tmp.name) / f"{len(self._slaves)}.fmu"
                    where = f"{system.path}: component {name!r} ({component.source})"
                    data = archive.read(component.source, where, MAX_MEMBER_BYTES)
                    _write_new(fmu_path, data)
                    slave = FmuSlave(fmu_path, name, where=where)
                    self._slaves[name] = slave
                    slave.set_start_values(component.start_values)
                    execution.add_slave(slave)
            finally:
                archive.close()
            slaves = self._slaves
            for c in system.connections:
                execution.connect(slaves[c.start], c.output, slaves[c.end], c.input)
            execution.add_observer(VariableObserver([(slaves[o], v) for o, v in self.watched],
                                                    sink=self._record))
        except BaseException:
            self.__exit__()
            raise
        return self

    def initialize(self) -> None:
        """Initialize every component (row 0 is recorded)."""
        self._execution.initialize()

    def run(self) -> str:
        """Do every step; return ``""``, or the error of the step that failed (rows before it
        recorded). An exception a sink raises (an interruption) propagates."""
        execution = self._execution
        try:
            execution.step(self.steps)
        except FmuError as exc:
            self.k = execution.k
            return str(exc)
        self.k = execution.k
        execution.finish()
        return ""

    def __exit__(self, *exc: object) -> None:
        if self._execution is not None:
            self._execution.close()
        for slave in self._slaves.values():
            if self._execution is None or slave not in self._execution.slaves:
                slave.close()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None


def _write_new(path: Path, data: bytes) -> None:
    """Write ``data`` into a new file ``path`` (never through a link planted there)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0),
                 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


def run_ssp(
    system: SspSystem,
    variables: Sequence[str] | None = None,
    step: float | None = None,
    stop: float | None = None,
    start: float | None = None,
) -> SspRun:
    """Run a checked SSP system; record ``variables`` (default: every output), in memory.

    (:class:`SspSession` streams the rows instead; ``papwc cosim`` uses it.)

    Parameters
    ----------
    system : SspSystem
        From :func:`read_ssp`.
    variables : sequence of str, optional
        ``component.variable`` names to record (Real, Integer or Boolean).
    step, stop, start : float, optional
        Override the SSD's fixed step and its DefaultExperiment's stop and start
        time, s.

    Returns
    -------
    SspRun
        Row 0 holds the values after initialization, row k those at
        ``t_k = start + k * step``; ``round((stop - start) / step)`` steps. A
        failed step ends the run with ``error`` set and the rows before it kept.

    Raises
    ------
    SspError
        For a variable or an experiment setting that does not fit, before any
        FMU is loaded.
    FmuError
        If an FMU cannot be loaded or refuses its initialization.
    """
    session = SspSession(system, variables, step, stop, start)
    with session:
        session.initialize()
        error = session.run()
    return SspRun(system, session.columns, session.pending, session.step_size, error)
