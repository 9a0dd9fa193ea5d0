"""An FMI 2.0 Co-Simulation FMU as a slave of the master (:class:`FmuSlave`).

fmpy reads the model description, extracts the FMU, loads its library and
instantiates it; the calls of every step (``fmi2SetReal``, ``fmi2DoStep``,
``fmi2GetReal``, ...) then go straight to the library's functions with
arguments prepared once (value-reference arrays and value buffers), without
fmpy's per-call wrappers. Any FMU works: FrictionPlant.fmu, PulseController.fmu
or another tool's.
"""

from __future__ import annotations

import itertools
import math
import os
import shutil
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from ctypes import (
    CFUNCTYPE,
    byref,
    c_char_p,
    c_double,
    c_int,
    c_size_t,
    c_uint,
    c_void_p,
    cast,
)
from operator import itemgetter
from pathlib import Path
from typing import Any

from papwc.errors import FmuError

__all__ = ["FmuSlave", "check_fmu"]

#: fmi2Status values.
_STATUS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
#: Log messages kept per instance (the most recent).
_LOG_KEPT = 200

_C_TYPES = {"Real": c_double, "Integer": c_int, "Enumeration": c_int, "Boolean": c_int}


class _Log(deque):
    """The kept log messages of an instance, and how many were ever logged (``count``)."""

    def __init__(self) -> None:
        super().__init__(maxlen=_LOG_KEPT)
        self.count = 0

    def append(self, text: str) -> None:
        self.count += 1
        super().append(text)

    def since(self, count: int) -> list[str]:
        """The messages logged after the ``count``-th (those still kept)."""
        n = min(self.count - count, len(self))
        return list(self)[len(self) - n:] if n > 0 else []


def _refusals(messages: list[str]) -> list[str]:
    return [m for m in messages if m.startswith(("[Error]", "[Fatal]"))]


def _text(value: Any) -> str:
    """A logger argument (bytes, str or NULL) as text."""
    if value is None:
        return ""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return str(value)


#: The log of every open instance, by the componentEnvironment it was instantiated with.
_LOGS: dict[int, deque] = {}
_ENVIRONMENTS = itertools.count(1)
_DISPATCH: list[Any] = []


def log_message(environment: Any, instance_name: Any, status: Any, category: Any,
                message: Any) -> None:
    """The fmi2CallbackLogger of every FmuSlave: append to the log of the instance.

    fmpy's proxy (which formats the message with its arguments) keeps one logger
    for the whole process, so every instance is given this one function and its
    own ``componentEnvironment``, by which the message reaches its log. Any
    argument may be NULL; nothing here raises into the FMU.
    """
    try:
        try:
            code = int(status)
        except (TypeError, ValueError):
            code = -1
        label = _STATUS[code] if 0 <= code < len(_STATUS) else f"status {status!r}"
        text = f"[{label}] {_text(category)}: {_text(message)}"
        log = _LOGS.get(environment if isinstance(environment, int) else 0)
        if log is not None:
            log.append(text)
    except Exception:  # noqa: BLE001 - an exception must not cross into the FMU's C code
        pass


def _dispatcher():
    """The C function pointer of :func:`log_message` (made once)."""
    if not _DISPATCH:
        from fmpy.fmi2 import fmi2CallbackLoggerTYPE

        _DISPATCH.append(fmi2CallbackLoggerTYPE(log_message))
    return _DISPATCH[0]


class FmuSlave:
    """One instance of an FMI 2.0 Co-Simulation FMU.

    The FMU is extracted once (into a temporary folder whose path has only
    ASCII letters and digits) and its library stays loaded; :meth:`restart`
    re-creates the state right after initialization (from an FMU state taken
    then, when the FMU can get and set its state, else by a new instance).
    Every state the slave takes is freed (when the start values change, on
    :meth:`close`).

    Every FMI call that returns Discard, Error or Fatal raises
    :class:`~papwc.errors.FmuError` naming the time, the call and the FMU's
    last log messages.

    Parameters
    ----------
    fmu_path : path
        The ``.fmu`` file.
    name : str
        Instance name passed to fmi2Instantiate.
    unzip_dir : path, optional
        An already extracted copy to use (it is not deleted).
    restart_input : str, optional
        An Integer input whose change starts a new run of the FMU with what it
        has learned (PulseController.fmu's ``maneuver``): :meth:`restart`
        increments it instead of restoring the initial state. The FMU's communication
        points then go on from where the last run ended (FMI 2.0: each step starts where the
        last ended; a native FMU refuses another point): the master's time plus the
        length of the runs before.
    """

    #: Instances that returned fmi2Fatal, kept so that nothing frees them.
    _keep_dead: list[Any] = []

    def __init__(
        self,
        fmu_path: str | os.PathLike,
        name: str = "plant",
        unzip_dir: str | os.PathLike | None = None,
        restart_input: str | None = None,
        where: str | None = None,
    ) -> None:
        from papwc.master import archive

        self.name = name
        self.fmu_path = Path(fmu_path)
        #: What opens every message about the file (the path, or an SSP's component).
        self.where = where or f"FMU {str(self.fmu_path)!r}"
        self.values: list[Any] = []
        self.log: _Log = _Log()
        self.time = 0.0
        self._fmu = None
        self._snapshot = None
        self._start: dict[str, Any] = {}
        self._watched: list[str] = []
        self._owns_dir = False
        self._fatal = False
        self.restart_input = restart_input
        self._restarts = 0
        #: The FMU's communication point is the master's t plus this (s): the runs before
        #: a restart by ``restart_input``; the end of the last step, in the FMU's time.
        self._t_shift = 0.0
        self._t_end = 0.0
        # Everything that opens the file goes through papwc.master.archive: a
        # failure is one FmuError naming the file, and the unpacked copy is removed.
        if unzip_dir is None:
            if not self.fmu_path.is_file():
                raise FmuError(f"FMU file {str(self.fmu_path)!r} does not exist")
            unzip_dir = archive.unpack(self.fmu_path, self.where)
            self._owns_dir = True
        self.unzip_dir = str(unzip_dir)
        try:
            self.md = archive.read_model_description(self.unzip_dir, self.where)
            self.vars = {v.name: v for v in self.md.modelVariables}
            if restart_input is not None and (
                    restart_input not in self.vars
                    or self.vars[restart_input].causality != "input"
                    or self.vars[restart_input].type != "Integer"):
                raise FmuError(f"{self.where}: has no Integer input {restart_input!r}")
            self._can_state = bool(self.md.coSimulation.canGetAndSetFMUstate)
            #: Whether initialization has been entered since the instance was made or reset:
            #: a new initialization then starts with fmi2Reset (a native FMU) or with a new
            #: instance (a pythonfmu FMU, which has no reset of its own).
            self._entered = False
            self._resets = not (self.md.generationTool or "").startswith("PythonFMU")
            self._refresh: Callable[[], None] = lambda: None
            #: What a Real input was last set to, by name: [value, sign of value] or [NaN]
            #: (not known); a setter of that input alone sends a value only if it differs.
            self._held: dict[str, list[float]] = {}
            self._load()
            self._instantiate()
        except BaseException:
            self.close()
            raise

    # -- the FMI library -------------------------------------------------------------------
    def _load(self) -> None:
        """Load the library, make the callbacks, bind the functions called at every step."""
        from fmpy.fmi1 import calloc, free
        from fmpy.fmi2 import (
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
        )
        from fmpy.logging import addLoggerProxy

        self._environment = next(_ENVIRONMENTS)
        _LOGS[self._environment] = self.log
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = _dispatcher()
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        callbacks.componentEnvironment = self._environment
        addLoggerProxy(byref(callbacks))
        # The FMU keeps a pointer to this structure until fmi2FreeInstance.
        self._callbacks = callbacks
        self._logger = log_message
        from papwc.master.archive import load_library

        self._fmu = load_library(self.md, self.unzip_dir, self.name, self.where)
        #: The instance (fmi2Component); the step functions hold this object, so a
        #: new instance only changes its value.
        self._c = c_void_p(None)
        # The functions called at every step, as bare function pointers: no argtypes,
        # so ctypes passes the prepared ctypes objects without converting them
        # (fmpy's own function objects keep their argtypes).
        dll = self._fmu.dll
        bare = CFUNCTYPE(c_int)
        self._fn: dict[str, Any] = {}
        for kind in ("Real", "Integer", "Boolean"):
            for verb in ("Get", "Set"):
                address = cast(getattr(dll, f"fmi2{verb}{kind}"), c_void_p).value
                self._fn[f"{verb}{kind}"] = bare(address)
        self._fn["DoStep"] = bare(cast(dll.fmi2DoStep, c_void_p).value)
        self._do_step = self._fn["DoStep"]
        self._h = c_double(0.0)
        self._t = c_double(0.0)  # the communication point, passed by value

    def _instantiate(self) -> None:
        self._call("fmi2Instantiate", lambda: self._fmu.instantiate(
            callbacks=self._callbacks, loggingOn=True))
        self._c.value = self._fmu.component
        self._entered = False

    def _call(self, name: str, fn: Callable[[], Any]) -> Any:
        from fmpy.fmi1 import FMICallException

        try:
            return fn()
        except FMICallException as exc:
            raise FmuError(self._failure(name, _STATUS[exc.status]
                                         if 0 <= exc.status < 5 else exc.status)) from exc
        except Exception as exc:  # fmpy raises plain Exceptions
            log = "; ".join(list(self.log)[-5:])  # the FMU's reason (fmi2Instantiate: a GUID)
            raise FmuError(f"{self.where}: {name} failed: {exc}"
                           + (f"; FMU log: {log}" if log else " (the FMU logged nothing)")
                           ) from exc

    def _failure(self, name: str, status: Any) -> str:
        if status == "Fatal":
            # FMI 2.0: after fmi2Fatal no function of the instance may be called, not
            # even fmi2FreeInstance (pythonfmu 0.7.0 has then released the Python
            # instance; freeing it again would release it twice).
            self._fatal = True
        log = "; ".join(list(self.log)[-5:]) or "(the FMU logged nothing)"
        return (f"{self.name}: {name} at t = {self.time!r} s returned {status}; "
                f"FMU log: {log}")

    def _check(self, name: str, status: int) -> None:
        if status > 1:
            raise FmuError(self._failure(name, _STATUS[status] if status < 5 else status))

    # -- the slave interface ---------------------------------------------------------------
    def variables(self) -> Mapping[str, str]:
        """Causality of every variable of the FMU."""
        return {name: v.causality for name, v in self.vars.items()}

    @property
    def reusable(self) -> bool:
        """Whether a new simulation may take this instance (``fmi2Reset`` brings it back to
        its start; not after an fmi2Fatal, nor for a pythonfmu FMU, which has no reset)."""
        return self._fmu is not None and self._resets and not getattr(self, "_fatal", False)

    def replace_start_values(self, values: Mapping[str, Any]) -> None:
        """Forget the start values set so far; set ``values`` (see :meth:`set_start_values`)."""
        self._start.clear()
        self.set_start_values(values)

    def set_start_values(self, values: Mapping[str, Any]) -> None:
        """Parameters and input start values, applied at every (re)initialization."""
        for name in values:
            if name not in self.vars:
                raise FmuError(f"{self.where}: has no variable {name!r}")
        self._start.update(values)
        self._free_snapshot()

    def _held_cell(self, name: str) -> list[float]:
        return self._held.setdefault(name, [math.nan])

    def _forget_inputs(self) -> None:
        """The inputs' values are no longer known (a new instance, a restored state)."""
        for held in self._held.values():
            held[:] = [math.nan]

    def _set_now(self, values: Mapping[str, Any]) -> None:
        """Set ``values`` now; FmuError if the FMU logs an Error or Fatal while doing it.

        (pythonfmu's FMUs return fmi2OK for a refused set; the refusal is in their log.)
        """
        before = self.log.count
        self._set_values(values)
        refused = _refusals(self.log.since(before))
        if refused:
            names = ", ".join(values)
            raise FmuError(f"{self.name}: setting {names} at t = {self.time!r} s was refused: "
                           + "; ".join(refused))

    def _set_values(self, values: Mapping[str, Any]) -> None:
        self._forget_inputs()
        for name, value in values.items():
            var = self.vars[name]
            vr = (c_uint * 1)(var.valueReference)
            if var.type == "String":
                buf = (c_char_p * 1)(str(value).encode("utf-8"))
                self._call("fmi2SetString", lambda vr=vr, buf=buf: self._fmu.fmi2SetString(
                    self._fmu.component, vr, 1, buf))
                continue
            ctype = _C_TYPES[var.type]
            buf = (ctype * 1)(float(value) if ctype is c_double else int(value))
            fn = self._fn["Set" + ("Integer" if var.type == "Enumeration" else var.type)]
            self._check(f"fmi2Set{var.type}({name})", fn(self._c, vr, c_size_t(1), buf))

    def watch(self, names: Sequence[str]) -> list[int]:
        """Read ``names`` into :attr:`values` after each step; return their indexes."""
        for name in names:
            if name not in self.vars:
                raise FmuError(f"{self.where}: has no variable {name!r}")
            if self.vars[name].type not in _C_TYPES:
                raise FmuError(f"{self.where}: variable {name!r} of type "
                               f"{self.vars[name].type} cannot be watched")
            if name not in self._watched:
                self._watched.append(name)
        self._prepare_reads()
        return [self._watched.index(n) for n in names]

    def _prepare_reads(self) -> None:
        groups: dict[str, list[int]] = {}
        for i, name in enumerate(self._watched):
            t = self.vars[name].type
            groups.setdefault("Integer" if t == "Enumeration" else t, []).append(i)
        reads = []
        for kind, positions in groups.items():
            n = len(positions)
            vr = (c_uint * n)(*(self.vars[self._watched[i]].valueReference for i in positions))
            buf = (_C_TYPES[kind] * n)()
            reads.append((self._fn["Get" + kind], vr, c_size_t(n), buf, positions, kind))
        comp, check = self._c, self._check
        if len(reads) == 1 and reads[0][5] == "Real":
            get, vr, n, buf, _, _ = reads[0]

            def refresh() -> None:
                status = get(comp, vr, n, buf)
                if status > 1:
                    check("fmi2GetReal", status)
                self.values = buf[:]
        elif all(kind != "Boolean" for *_, kind in reads):
            # Reals and Integers: each buffer read whole, then put in the watched order by one
            # itemgetter (a controller's outputs: u and the estimates, the counts and codes)
            order = [i for *_, positions, _ in reads for i in positions]
            where = [0] * len(order)
            for j, i in enumerate(order):
                where[i] = j
            arrange = itemgetter(*where) if len(where) > 1 else (lambda v: (v[0],))

            def refresh() -> None:
                read: list[Any] = []
                for get, vr, n, buf, _, kind in reads:
                    status = get(comp, vr, n, buf)
                    if status > 1:
                        check(f"fmi2Get{kind}", status)
                    read += buf[:]
                self.values = list(arrange(read))
        else:
            size = len(self._watched)

            def refresh() -> None:
                values: list[Any] = [None] * size
                for get, vr, n, buf, positions, kind in reads:
                    status = get(comp, vr, n, buf)
                    if status > 1:
                        check(f"fmi2Get{kind}", status)
                    for i, value in zip(positions, buf, strict=True):
                        values[i] = bool(value) if kind == "Boolean" else value
                self.values = values

        self._refresh = refresh

    def input_setter(self, names: Sequence[str]) -> Callable[..., None]:
        """A function ``set(*values)`` that sets the inputs ``names`` (Real, Integer, Boolean)."""
        kinds = set()
        for name in names:
            if name not in self.vars:
                raise FmuError(f"{self.where}: has no variable {name!r}")
            if self.vars[name].causality != "input":
                raise FmuError(f"{self.where}: variable {name!r} is not an input")
            kinds.add(self.vars[name].type)
        comp, check = self._c, self._check
        # Watched inputs show the value last set (watch them before asking for the setter).
        shown = [(j, self._watched.index(name)) for j, name in enumerate(names)
                 if name in self._watched]
        if kinds == {"Real"}:
            n = len(names)
            vr = (c_uint * n)(*(self.vars[name].valueReference for name in names))
            buf = (c_double * n)()
            n_c = c_size_t(n)
            set_real = self._fn["SetReal"]
            if n == 1 and len(shown) <= 1:
                index = shown[0][1] if shown else None
                held = self._held_cell(names[0])

                def set_one(value: Any) -> None:
                    if value == held[0] and (value != 0.0
                                             or math.copysign(1.0, value) == held[1]):
                        return  # the input holds it: FMI keeps an input until it is set
                    buf[0] = value
                    status = set_real(comp, vr, n_c, buf)
                    if status > 1:
                        check("fmi2SetReal", status)
                    held[:] = value, math.copysign(1.0, value)
                    if index is not None:
                        self.values[index] = value

                return set_one

            cells = [self._held_cell(name) for name in names]

            def set_reals(*values: Any) -> None:
                for held in cells:  # (each setter of one of them sends anew)
                    held[:] = [math.nan]
                buf[:] = values
                status = set_real(comp, vr, n_c, buf)
                if status > 1:
                    check("fmi2SetReal", status)
                for j, i in shown:
                    self.values[i] = values[j]

            return set_reals

        def set_any(*values: Any) -> None:
            self._set_now(dict(zip(names, values, strict=True)))
            for j, i in shown:
                self.values[i] = values[j]

        return set_any

    def initialize(self, start_time: float = 0.0) -> None:
        """setupExperiment, the start values, enter and exit initialization mode.

        Raises
        ------
        FmuError
            If a call fails, or if the FMU logged an Error or Fatal message at
            exitInitializationMode (FrictionPlant.fmu and PulseController.fmu
            refuse invalid parameters that way).
        """
        self.time = float(start_time)
        self._t_shift, self._t_end = 0.0, self.time
        self._forget_inputs()
        if self._entered:
            # FMI 2.0 initializes an instance once: a native FMU is reset; a pythonfmu FMU,
            # which has no reset (an initialized one only logs that it refuses parameters),
            # is replaced by a new instance that takes the start values.
            self._free_snapshot()
            if self._resets:
                self._call("fmi2Reset", self._fmu.reset)
            else:
                self._call("fmi2FreeInstance",
                           lambda: self._fmu.fmi2FreeInstance(self._fmu.component))
                self._instantiate()
        self._entered = True
        self._call("fmi2SetupExperiment", lambda: self._fmu.setupExperiment(
            startTime=start_time))
        self._set_now(self._start)
        self._call("fmi2EnterInitializationMode", self._fmu.enterInitializationMode)
        before = self.log.count
        try:
            self._call("fmi2ExitInitializationMode", self._fmu.exitInitializationMode)
            failed = None
        except FmuError as exc:  # a native FMU refuses the parameters with fmi2Error
            failed = exc
        refused = _refusals(self.log.since(before))
        if failed is not None and not refused:
            raise failed
        if refused:
            raise FmuError(f"{self.name}: fmi2ExitInitializationMode at t = {self.time!r} s "
                           "refused the parameters: " + "; ".join(refused))
        self._restarts = 0
        if self._can_state and self.restart_input is None:
            self._free_snapshot()
            self._snapshot = self._call("fmi2GetFMUstate", self._fmu.getFMUstate)
        self._refresh()

    def restart(self, start_time: float = 0.0) -> None:
        """Back to the state right after initialization (same start values).

        With ``restart_input``, that input is incremented instead: the FMU starts
        anew keeping what it has learned.
        """
        self._forget_inputs()
        if self.restart_input is not None:
            self.time = float(start_time)
            self._t_shift = self._t_end - self.time
            self._restarts += 1
            base = int(self._start.get(self.restart_input, 0))
            self._set_now({self.restart_input: base + self._restarts})
            self._refresh()
            return
        if self._snapshot is not None:
            self.time = float(start_time)
            self._t_shift, self._t_end = 0.0, self.time
            before = self.log.count
            self._call("fmi2SetFMUstate", lambda: self._fmu.setFMUstate(self._snapshot))
            refused = _refusals(self.log.since(before))
            if refused:
                raise FmuError(f"{self.name}: fmi2SetFMUstate at t = {self.time!r} s was "
                               "refused: " + "; ".join(refused))
            self._refresh()
            return
        self.initialize(start_time)

    def do_step(self, t: float, h: float) -> None:
        """fmi2DoStep from ``t`` over ``h`` (s), then read the watched variables."""
        self.time = t
        step_size = self._h
        if step_size.value != h:
            step_size.value = h
        t_c = self._t
        t_c.value = t + self._t_shift
        status = self._do_step(self._c, t_c, step_size, 1)
        if status > 1:
            self._check("fmi2DoStep", status)
        self._t_end = t_c.value + h
        self._refresh()

    def _free_snapshot(self) -> None:
        if self._snapshot is not None and self._fmu is not None:
            snapshot, self._snapshot = self._snapshot, None
            self._call("fmi2FreeFMUstate", lambda: self._fmu.freeFMUstate(snapshot))

    def close(self) -> None:
        """Free the state taken, terminate, free the instance, remove the extracted copy.

        After an fmi2Fatal nothing is called: the instance is left as it is.
        """
        fmu, self._fmu = self._fmu, None
        if fmu is not None and getattr(self, "_fatal", False):
            self._keep_dead.append(fmu)
        elif fmu is not None:
            try:
                if self._snapshot is not None:
                    fmu.freeFMUstate(self._snapshot)
                    self._snapshot = None
                fmu.terminate()
            except Exception:  # noqa: BLE001 - closing a failed instance must not raise
                pass
            try:
                fmu.freeInstance()
            except Exception:  # noqa: BLE001
                pass
        _LOGS.pop(getattr(self, "_environment", None), None)
        if self._owns_dir:
            shutil.rmtree(self.unzip_dir, ignore_errors=True)
            self._owns_dir = False

    def __enter__(self) -> FmuSlave:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_fmu(fmu_path: str | os.PathLike, where: str | None = None) -> Any:
    """Open ``fmu_path`` as the master would (unpack, read, load, instantiate), then close it.

    Returns its model description. A command given an FMU calls this before
    any work starts, so that an FMU that cannot be used is refused once, in one
    line (:class:`~papwc.errors.FmuError`), with nothing left unpacked.
    """
    with FmuSlave(fmu_path, name="check", where=where) as slave:
        return slave.md
