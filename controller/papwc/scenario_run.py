"""Run a scenario's controllers against the plant (what ``papwc run`` computes).

:func:`run_scenario` runs every ``[[controller]]`` of a scenario on the plant it names
(FrictionPlant.fmu or the in-process physics), between two communication steps honouring a
deferred Ctrl-C and the run's time limit (:mod:`papwc.interrupts`); what it returns is
written by :mod:`papwc.results.folder`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

from papwc.errors import FmuError
from papwc.interrupts import deferred_interrupt
from papwc.master import FmuSlave, PhysicsSlave, RunResult, Slave, StepGuard, run_controller
from papwc.output_files import refuse_link
from papwc.scenario import Scenario


def ensure_plant_fmu(fmu: str | os.PathLike | None, out: str | os.PathLike) -> Path:
    """The plant FMU to use: ``fmu`` if given, else one built from the current sources.

    Without ``fmu``: the checkout's build/FrictionPlant.fmu when it is current,
    else ``out/fmu/FrictionPlant.fmu`` (built there if missing or stale).
    """
    if fmu is not None:
        path = Path(fmu)
        if not path.is_file():
            what = "is not a file" if path.exists() else "does not exist"
            raise FmuError(f"plant FMU {str(path)!r} {what}")
        from papwc.master.fmu import check_fmu

        where = f"plant FMU {str(path)!r}"
        _check_plant_variables(check_fmu(path, where=where), where)
        return path
    from papwc.fmubuild.fmus import current_fmu

    refuse_link(Path(out) / "fmu")  # a folder the command fills is not followed
    return current_fmu("FrictionPlant", Path(out) / "fmu")



def ensure_controller_fmu(out: str | os.PathLike) -> Path:
    """The native PulseController.fmu built from the current sources: the checkout's
    build/PulseController.fmu when it is current, else ``out/fmu/PulseController.fmu`` (built
    there if missing or stale)."""
    from papwc.fmubuild.fmus import current_fmu

    refuse_link(Path(out) / "fmu")
    return current_fmu("PulseController", Path(out) / "fmu")


def controller_fmu(controllers: str, out: str | os.PathLike) -> Path | None:
    """The native PulseController.fmu whose C controller runs the kinds it implements, or
    None for the Python controllers:

    - ``"native"``: :func:`ensure_controller_fmu` (built into ``out/fmu/`` if needed);
    - ``"auto"``: the checkout's build/PulseController.fmu where it is current (what
      ``papwc build`` wrote), else None: nothing is built for it;
    - ``"python"``: None.
    """
    if controllers == "native":
        return ensure_controller_fmu(out)
    if controllers == "auto":
        from papwc.fmubuild.fmus import is_current
        from papwc.resources import checkout_root

        root = checkout_root()
        built = None if root is None else root / "build" / "PulseController.fmu"
        return built if built is not None and is_current(built, "PulseController") else None
    return None


def controller_library(controllers: str, out: str | os.PathLike):
    """The C controller the master runs for ``controllers`` (:func:`controller_fmu`), or
    None for the Python controllers."""
    from papwc.master.native_controller import fmu_controller_library

    return fmu_controller_library(controller_fmu(controllers, out))


def _check_plant_variables(md, where: str) -> None:
    """Refuse (FmuError) an FMU that is not a plant the master can close the loop on: a
    Real input ``u`` (the force) and the Real outputs every trace records."""
    from papwc.master.trace import REQUIRED_PLANT_COLUMNS

    kinds = {v.name: (v.causality, v.type) for v in md.modelVariables}
    wanted = [("u", "input")] + [(name, "output") for name in REQUIRED_PLANT_COLUMNS]
    missing = [f"{name} ({causality})" for name, causality in wanted
               if kinds.get(name) != (causality, "Real")]
    if missing:
        raise FmuError(f"{where}: not a plant FMU: it has no Real {', '.join(missing)} (the "
                       f"model is {md.modelName}); give FrictionPlant.fmu (papwc build) or "
                       "another plant with a force input u and position outputs x, v, x_meas")


def make_plant(scenario: Scenario, plant: str = "fmu", fmu: str | os.PathLike | None = None,
               unzip_dir: str | os.PathLike | None = None) -> Slave:
    """A plant with the scenario's parameters: ``"fmu"`` (an FMU file) or ``"physics"``.

    ``unzip_dir`` is an extracted copy of the FMU to use (a battery worker
    extracts it once).
    """
    if plant != "physics" and unzip_dir is not None:
        idle = _IDLE_PLANTS.pop((str(fmu), str(unzip_dir)), None)
        if idle is not None:  # fmi2Reset at its initialization: as good as a new instance
            idle.log.clear()
            idle.replace_start_values(dict(scenario.plant))
            return idle
    slave = PhysicsSlave() if plant == "physics" else FmuSlave(fmu, unzip_dir=unzip_dir)
    slave.set_start_values(dict(scenario.plant))
    return slave


#: Plant instances of this process not in use, by (FMU, extracted copy): a battery worker
#: (which passes its extracted copy) takes the one of the run before instead of loading the
#: FMU again, where the FMU can be reset (:attr:`papwc.master.FmuSlave.reusable`).
_IDLE_PLANTS: dict[tuple[str, str], Slave] = {}


def release_plant(slave: Slave, fmu: str | os.PathLike | None,
                  unzip_dir: str | os.PathLike | None) -> None:
    """Done with a plant of :func:`make_plant`: keep it for the next run, or close it."""
    key = (str(fmu), str(unzip_dir))
    if (unzip_dir is not None and isinstance(slave, FmuSlave) and slave.reusable
            and key not in _IDLE_PLANTS):
        _IDLE_PLANTS[key] = slave
        return
    slave.close()


def run_scenario(scenario: Scenario, plant: str = "fmu", fmu: str | os.PathLike | None = None,
                 progress: Callable[[RunResult], None] | None = None,
                 unzip_dir: str | os.PathLike | None = None,
                 timeout: float | None = None, library=None,
                 stopped: Callable[[RunResult], None] | None = None) -> list[RunResult]:
    """Run every controller of the scenario (each with a fresh plant instance).

    ``fmu`` is the plant FMU's path when ``plant`` is ``"fmu"`` (and
    ``unzip_dir`` an extracted copy of it, if there is one); ``progress`` is
    called with each controller's result as it finishes. With ``timeout`` (s),
    :class:`RunTimeout` is raised once the whole run has taken longer. Ctrl-C
    raises KeyboardInterrupt between two steps (:func:`deferred_interrupt`), after
    ``stopped`` was given what the controller under way had computed (its traces, the
    last one cut; see :func:`papwc.master.run_closed_loop`).
    ``library`` (:func:`controller_library`): the C controller runs the kinds it
    implements, the Python controllers the others (None: all Python); the same numbers.
    """
    results = []
    deadline = None if timeout is None else time.monotonic() + timeout
    keep = {} if stopped is None else {"stopped": stopped}
    with deferred_interrupt():
        for settings, label in zip(scenario.controllers, scenario.labels, strict=True):
            slave = make_plant(scenario, plant, fmu, unzip_dir)
            guard = StepGuard(deadline, timeout)
            try:
                results.append(run_controller(slave, settings, scenario.maneuver, label,
                                              observers=[guard], library=library,
                                              **keep))
            finally:
                release_plant(slave, fmu, unzip_dir)
            if progress is not None:
                progress(results[-1])
    return results


