"""Plants the master can step: an FMI 2.0 Co-Simulation FMU through fmpy, or the
physics module called directly (same variables, for fast analysis and tests).

Both offer ``set_parameters``, ``initialize``, ``set_input``, ``do_step``,
``get_outputs``, ``restart`` and ``close``; times are passed in, never accumulated.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from ctypes import byref
from pathlib import Path

from papwc.errors import FmuError
from papwc.fmu_src import papwc_stickslip as physics

#: Outputs a plant offers the master, by FrictionPlant's names.
PLANT_OUTPUTS = ("x", "v", "x_meas")


class PhysicsSlave:
    """The friction plant computed by ``papwc_stickslip`` in this process.

    Parameters and outputs carry FrictionPlant.fmu's names and units.
    """

    DEFAULTS = {
        "m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0,
        "x0": 0.0, "v0": 0.0, "x_resolution": 0.0,
    }  # fmt: skip

    def __init__(self) -> None:
        self.params = dict(self.DEFAULTS)
        self.x = self.v = 0.0
        self.u = 0.0

    def set_parameters(self, values: dict[str, float]) -> None:
        unknown = set(values) - set(self.params)
        if unknown:
            raise FmuError(f"the plant has no parameter {', '.join(sorted(unknown))}")
        self.params.update({k: float(v) for k, v in values.items()})

    def initialize(self, start_time: float = 0.0) -> None:
        p = self.params
        problems = physics.check_parameters(p["m"], p["f_c"], p["f_s"], p["c"])
        if not p["x_resolution"] >= 0.0:
            problems.append(f"parameter x_resolution = {p['x_resolution']!r} m must be >= 0")
        if problems:
            raise FmuError("exitInitializationMode refused: " + "; ".join(problems))
        self.x, self.v, self.u = p["x0"], p["v0"], 0.0

    restart = initialize

    def set_input(self, u: float) -> None:
        self.u = u

    def do_step(self, t: float, h: float) -> None:
        if not (math.isfinite(self.u) and h > 0.0):
            raise FmuError(
                f"doStep at t = {t!r} s discarded: u = {self.u!r} N, step size = {h!r} s"
            )
        p = self.params
        self.x, self.v = physics.step(self.x, self.v, self.u, h, p["m"], p["f_c"], p["f_s"], p["c"])

    def get_outputs(self) -> tuple[float, float, float]:
        """``(x, v, x_meas)`` in m, m/s, m."""
        return self.x, self.v, physics.quantize(self.x, self.params["x_resolution"])

    def close(self) -> None:
        pass


class FmuSlave:
    """One instance of an FMI 2.0 Co-Simulation FMU, stepped through fmpy.

    The FMU is extracted once (to a directory whose path has ASCII letters and
    digits only) and its library stays loaded; :meth:`restart` re-creates the
    instance's initial state (from an FMU state snapshot when the FMU can get and
    set its state, by a new instance otherwise).

    Every FMI call that returns Discard, Error or Fatal raises :class:`FmuError`
    naming the time, the call and the FMU's log messages.

    Parameters
    ----------
    fmu_path : path
        The ``.fmu`` file.
    input_name : str
        Name of the force input (N).
    output_names : (str, str, str)
        Names of the position (m), velocity (m/s) and measured position (m)
        outputs. A name the FMU does not have falls back to the position.
    unzip_dir : path, optional
        An already extracted copy to use (it is not deleted).
    instance_name : str
        Instance name passed to fmi2Instantiate.
    """

    def __init__(
        self,
        fmu_path: str | os.PathLike,
        input_name: str = "u",
        output_names: tuple[str, str, str] = PLANT_OUTPUTS,
        unzip_dir: str | os.PathLike | None = None,
        instance_name: str = "plant",
    ) -> None:
        from fmpy import extract, read_model_description
        from fmpy.fmi1 import calloc, free
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        self.fmu_path = Path(fmu_path)
        if not self.fmu_path.is_file():
            raise FmuError(f"FMU file {str(self.fmu_path)!r} does not exist")
        try:
            self.md = read_model_description(str(self.fmu_path))
        except Exception as exc:  # fmpy raises plain Exceptions for broken files
            raise FmuError(f"{self.fmu_path}: cannot read modelDescription.xml: {exc}") from exc
        if self.md.coSimulation is None:
            raise FmuError(f"{self.fmu_path}: not a Co-Simulation FMU")
        self._owns_dir = unzip_dir is None
        if unzip_dir is None:
            unzip_dir = tempfile.mkdtemp(prefix="papwcfmu")
            extract(str(self.fmu_path), unzipdir=unzip_dir)
        self.unzip_dir = str(unzip_dir)
        self.vars = {v.name: v for v in self.md.modelVariables}
        if input_name not in self.vars:
            raise FmuError(f"{self.fmu_path}: has no input variable {input_name!r}")
        self._vr_u = [self.vars[input_name].valueReference]
        names = [n if n in self.vars else output_names[0] for n in output_names]
        for n in names:
            if n not in self.vars:
                raise FmuError(f"{self.fmu_path}: has no output variable {n!r}")
        self._vr_out = [self.vars[n].valueReference for n in names]
        self.log: list[str] = []

        def logger(component, instance_name, status, category, message):
            label = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")[status]
            self.log.append(f"[{label}] {category.decode(errors='replace')}: "
                            f"{message.decode(errors='replace')}")

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        from fmpy.logging import addLoggerProxy

        addLoggerProxy(byref(callbacks))
        self._callbacks = callbacks
        self._logger = logger
        self._fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.unzip_dir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=instance_name,
        )
        self._can_state = bool(self.md.coSimulation.canGetAndSetFMUstate)
        self._snapshot = None
        self._params: dict[str, float] = {}
        self._live = False
        self.time = 0.0
        self._call("fmi2Instantiate", self._fmu.instantiate, callbacks=self._callbacks,
                   loggingOn=True)
        self._live = True

    # -- helpers -----------------------------------------------------------------------
    def _call(self, name: str, fn, *args, **kwargs):
        from fmpy.fmi1 import FMICallException

        try:
            return fn(*args, **kwargs)
        except FMICallException as exc:
            log = "; ".join(self.log[-5:]) or "(the FMU logged nothing)"
            raise FmuError(f"{name} at t = {self.time!r} s: {exc}; FMU log: {log}") from exc
        except Exception as exc:
            raise FmuError(f"{name} at t = {self.time!r} s failed: {exc}") from exc

    def _set_values(self, values: dict[str, float]) -> None:
        for name, value in values.items():
            if name not in self.vars:
                raise FmuError(f"{self.fmu_path}: has no variable {name!r}")
            var = self.vars[name]
            if var.type == "Real":
                self._call("fmi2SetReal", self._fmu.setReal, [var.valueReference], [float(value)])
            elif var.type in ("Integer", "Enumeration"):
                self._call("fmi2SetInteger", self._fmu.setInteger, [var.valueReference],
                           [int(value)])
            elif var.type == "Boolean":
                self._call("fmi2SetBoolean", self._fmu.setBoolean, [var.valueReference],
                           [bool(value)])
            else:
                self._call("fmi2SetString", self._fmu.setString, [var.valueReference],
                           [str(value)])

    # -- the plant interface -----------------------------------------------------------
    def set_parameters(self, values: dict[str, float]) -> None:
        """Parameters applied at every (re)initialization."""
        for name in values:
            if name not in self.vars:
                raise FmuError(f"{self.fmu_path}: has no parameter {name!r}")
        self._params.update(values)
        if self._snapshot is not None:
            self._call("fmi2FreeFMUstate", self._fmu.freeFMUstate, self._snapshot)
            self._snapshot = None

    def initialize(self, start_time: float = 0.0) -> None:
        self.time = float(start_time)
        self._call("fmi2SetupExperiment", self._fmu.setupExperiment, startTime=start_time)
        self._set_values(self._params)
        self._call("fmi2EnterInitializationMode", self._fmu.enterInitializationMode)
        n_log = len(self.log)
        self._call("fmi2ExitInitializationMode", self._fmu.exitInitializationMode)
        refused = [m for m in self.log[n_log:] if m.startswith(("[Error]", "[Fatal]"))]
        if refused:
            # The FMU logs invalid parameters at exitInitializationMode and discards
            # every step after it; stop here, with its messages.
            raise FmuError(f"fmi2ExitInitializationMode at t = {self.time!r} s refused the "
                           "parameters: " + "; ".join(refused))
        if self._can_state:
            if self._snapshot is not None:
                self._call("fmi2FreeFMUstate", self._fmu.freeFMUstate, self._snapshot)
            self._snapshot = self._call("fmi2GetFMUstate", self._fmu.getFMUstate)

    def restart(self, start_time: float = 0.0) -> None:
        """Back to the state right after initialization (same parameters)."""
        if self._snapshot is not None:
            self.time = float(start_time)
            self._call("fmi2SetFMUstate", self._fmu.setFMUstate, self._snapshot)
            return
        self._call("fmi2FreeInstance", self._fmu.fmi2FreeInstance, self._fmu.component)
        self._call("fmi2Instantiate", self._fmu.instantiate, callbacks=self._callbacks,
                   loggingOn=True)
        self.initialize(start_time)

    def set_input(self, u: float) -> None:
        self._fmu.setReal(self._vr_u, [u])

    def do_step(self, t: float, h: float) -> None:
        self.time = t
        self._call("fmi2DoStep", self._fmu.doStep, t, h)

    def get_outputs(self) -> tuple[float, float, float]:
        return tuple(self._fmu.getReal(self._vr_out))

    def close(self) -> None:
        if self._live:
            self._live = False
            try:
                if self._snapshot is not None:
                    self._fmu.freeFMUstate(self._snapshot)
                self._fmu.terminate()
            except Exception:  # noqa: BLE001 - closing a failed instance must not raise
                pass
            try:
                self._fmu.freeInstance()
            except Exception:  # noqa: BLE001
                pass
        if self._owns_dir:
            shutil.rmtree(self.unzip_dir, ignore_errors=True)

    def __enter__(self) -> FmuSlave:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
