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
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from papwc.errors import FmuError, SspError
from papwc.master.algorithm import FixedStepAlgorithm
from papwc.master.execution import Execution
from papwc.master.observers import VariableObserver
from papwc.master.ssd import MAX_MEMBER_BYTES, SspArchive, SspSystem, read_ssp

__all__ = ["SspRun", "read_ssp", "run_ssp"]

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


def run_ssp(
    system: SspSystem,
    variables: Sequence[str] | None = None,
    step: float | None = None,
    stop: float | None = None,
    start: float | None = None,
) -> SspRun:
    """Run a checked SSP system; record ``variables`` (default: every output).

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
    from papwc.master.fmu import FmuSlave

    t0, _t1, h, n = _check_experiment(system, step, stop, start)
    names = list(variables) if variables else system.outputs()
    watched: list[tuple[str, str]] = []
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
        watched.append((owner, variable))
    with tempfile.TemporaryDirectory(prefix="papwcssp") as tmp:
        archive = SspArchive(system.path)
        slaves: dict[str, FmuSlave] = {}
        execution = Execution(FixedStepAlgorithm(h, "delayed"), start_time=t0)
        try:
            for name, component in system.components.items():
                fmu_path = Path(tmp) / f"{len(slaves)}.fmu"
                where = f"{system.path}: component {name!r} ({component.source})"
                fmu_path.write_bytes(archive.read(component.source, where, MAX_MEMBER_BYTES))
                slave = FmuSlave(fmu_path, name, where=where)
                slaves[name] = slave
                slave.set_start_values(component.start_values)
                execution.add_slave(slave)
            for c in system.connections:
                execution.connect(slaves[c.start], c.output, slaves[c.end], c.input)
            observer = VariableObserver([(slaves[o], v) for o, v in watched])
            execution.add_observer(observer)
            execution.initialize()
            result = SspRun(system, ["time", *names], observer.rows, h)
            try:
                execution.step(n)
            except FmuError as exc:
                result.error = str(exc)
            else:
                execution.finish()
            return result
        finally:
            archive.close()
            execution.close()
            for slave in slaves.values():
                if slave not in execution.slaves:
                    slave.close()
