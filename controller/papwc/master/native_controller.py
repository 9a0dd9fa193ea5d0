"""The C controller of a native PulseController.fmu, stepped in process by the master.

The native FMU's binary exports, beside the fmi2 functions, one table of the controller's
own functions (``papwc_controller_api`` in ``fmu_src/PulseController/controller_api.c``):
``pc_defaults``, ``pc_check``, ``pc_init``, one sample with its outputs, a new maneuver,
``pc_outputs`` and ``pc_state_check`` of ``fmu_src/PulseController/papwc_controller.h``,
with the size and the fields (``name:TYPE`` in order) of ``PcSettings`` and ``PcOutputs``.
:func:`controller_library` loads that table from an extracted FMU when the FMU has a binary
for this platform and its structs are laid out as the model layer's tables say
(:data:`papwc.model.controller_settings.CONTROLLER_SETTINGS`, ``CONTROLLER_SWITCHES``,
``CONTROLLER_OUTPUTS``); otherwise (the pythonfmu build, no binary for this platform, one
built from other tables) it gives None and the master runs the Python controller.

:class:`NativeControllerSlave` is a controller slave of the master with the variables of
:class:`papwc.master.slave.ControllerSlave`: the C controller equals the Python one bit for
bit (tests/unit/test_native_controller.py), so a run gives the same numbers with either; a
sample costs one call into C instead of the Python controller's update.
"""

from __future__ import annotations

import ctypes
import functools
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from papwc.controllers.settings import ControllerSettings
from papwc.master.native_plant import api_table, binary_path, layout_struct
from papwc.master.slave import CONTROLLER_SLAVE_VARIABLES, ControllerInputs
from papwc.model.controller_settings import (
    CONTROLLER_OUTPUTS,
    CONTROLLER_SETTINGS,
    CONTROLLER_SWITCHES,
    KIND_CODES,
)

__all__ = ["API_SYMBOL", "API_VERSION", "CONTROLLER_BUILDS", "NativeControllerError",
           "NativeControllerLibrary", "NativeControllerSlave", "PcOutputs", "PcSettings",
           "controller_library", "controller_slave", "fmu_controller_library"]

#: How the master runs a controller: ``"native"`` (the C controller of PulseController.fmu,
#: for the kinds it implements; the Python controller for the others) or ``"python"``.
CONTROLLER_BUILDS = ("native", "python")

#: The exported function that returns the table of the controller's functions.
API_SYMBOL = "papwc_controller_api"
#: The version of that table this module reads.
API_VERSION = 1

#: Model layer type -> (the C header's type name, ctypes type).
_TYPES = {"Real": ("PC_REAL", ctypes.c_double), "Integer": ("PC_INTEGER", ctypes.c_int32),
          "Boolean": ("PC_BOOLEAN", ctypes.c_int32)}
#: Bytes of a refusal message.
_MSG_LEN = 512

#: ``PcSettings`` of controller_vars.h: the kind's code, one field per other setting, one per
#: switch ``<name>_given``.
PcSettings = layout_struct("PcSettings", [
    ("kind", "PC_INTEGER", ctypes.c_int32),
    *((v.name, *_TYPES[v.type]) for v in CONTROLLER_SETTINGS if v.name != "kind"),
    *((s.name, *_TYPES["Boolean"]) for s in CONTROLLER_SWITCHES),
])
#: ``PcOutputs`` of controller_vars.h: every output but u.
PcOutputs = layout_struct("PcOutputs", [(v.name, *_TYPES[v.type]) for v in CONTROLLER_OUTPUTS
                                        if v.name != "u"])

_P_SETTINGS, _P_OUT = ctypes.POINTER(PcSettings), ctypes.POINTER(PcOutputs)
_P_CTRL = ctypes.c_void_p
_REPORT = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p)
_FORMAT = ctypes.CFUNCTYPE(None, ctypes.c_double, ctypes.c_void_p, ctypes.c_size_t)


def _format_real(value: float, out: int, size: int) -> None:
    """``PcFormat``: a number as the model layer's messages write it (``repr``)."""
    text = repr(value).encode("ascii")[:max(size - 1, 0)] + b"\0"
    ctypes.memmove(out, text, min(len(text), size))


class _Api(ctypes.Structure):
    """``ControllerApi`` of controller_api.c."""

    _fields_ = [
        ("version", ctypes.c_int),
        ("settings_size", ctypes.c_size_t),
        ("outputs_size", ctypes.c_size_t),
        ("controller_size", ctypes.c_size_t),
        ("settings", ctypes.c_char_p),
        ("outputs", ctypes.c_char_p),
        ("defaults", ctypes.CFUNCTYPE(None, _P_SETTINGS)),
        ("check", ctypes.CFUNCTYPE(ctypes.c_int, _P_SETTINGS, ctypes.c_double, _REPORT,
                                   ctypes.c_void_p, _FORMAT)),
        ("init", ctypes.CFUNCTYPE(ctypes.c_int, _P_CTRL, _P_SETTINGS, ctypes.c_double)),
        ("sample", ctypes.CFUNCTYPE(ctypes.c_double, _P_CTRL, ctypes.c_double, ctypes.c_double,
                                    ctypes.c_double, _P_OUT)),
        ("reset", ctypes.CFUNCTYPE(None, _P_CTRL, _P_OUT)),
        ("outputs_of", ctypes.CFUNCTYPE(None, _P_CTRL, _P_OUT)),
        ("state_check", ctypes.CFUNCTYPE(ctypes.c_int, _P_CTRL, ctypes.c_char_p,
                                         ctypes.c_size_t)),
    ]


class NativeControllerError(Exception):
    """A binary does not provide the controller as this module reads it."""


def settings_struct(settings: ControllerSettings) -> PcSettings:
    """The C settings of ``settings``: the kind's code; a setting at a default its Real cannot
    hold (None: computed, inf: no bound) leaves the Real at its FMU start value and its switch
    false, any other value sets the Real and the switch true (as PulseController.fmu's
    parameters, :func:`papwc.model.controller_settings.fmu_parameters`)."""
    s = PcSettings()
    s.kind = KIND_CODES.index(settings.kind) + 1 if settings.kind in KIND_CODES else 0
    for var in CONTROLLER_SETTINGS:
        if var.name == "kind":
            continue
        value = settings.get(var.name)
        if var.switch:
            given = value is not None and value != var.switched_value
            setattr(s, var.switch, int(given))
            value = value if given else var.fmi_start
        setattr(s, var.name, float(value) if var.type == "Real" else int(value))
    return s


class NativeControllerLibrary:
    """The controller's functions in a native PulseController binary, checked against the
    model layer.

    Parameters
    ----------
    path : path
        The binary (``binaries/<platform>/PulseController.so``, ``.dll``, ``.dylib``), or a
        library built from ``controller.c`` and ``controller_api.c``.

    Raises
    ------
    NativeControllerError
        If it cannot be loaded, does not export :data:`API_SYMBOL`, or its version or the
        layout of its structs differ from this module's.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        lib, api = api_table(self.path, API_SYMBOL, API_VERSION, _Api, NativeControllerError, (
            ("PcSettings", PcSettings, "settings_size", "settings"),
            ("PcOutputs", PcOutputs, "outputs_size", "outputs")))
        self._lib = lib  # keeps the binary loaded while the table is used
        self.api = api
        self.controller_size = int(api.controller_size)

    def problems(self, settings: ControllerSettings, T: float) -> list[str]:
        """What ``pc_check`` refuses of ``settings`` at sample period ``T`` (s), one message
        each, numbers written as ``repr`` writes them (empty: valid)."""
        found: list[str] = []

        def report(context: Any, message: bytes) -> None:
            found.append(message.decode("utf-8", "replace"))

        self.api.check(ctypes.byref(settings_struct(settings)), float(T), _REPORT(report),
                       None, _FORMAT(_format_real))
        return found

    def new(self, settings: ControllerSettings, T: float) -> ctypes.Array:
        """A new controller (``pc_init``) of ``settings`` at sample period ``T`` (s): a buffer
        holding the ``PcController`` struct.

        Raises
        ------
        ValueError
            If ``pc_check`` refuses the settings (its messages).
        """
        buffer = (ctypes.c_uint64 * ((self.controller_size + 7) // 8))()
        if self.api.init(ctypes.addressof(buffer), ctypes.byref(settings_struct(settings)),
                         float(T)) != 0:
            raise ValueError("the C controller refuses the settings: "
                             + "; ".join(self.problems(settings, T)))
        return buffer

    def state_problem(self, buffer: ctypes.Array) -> str | None:
        """``pc_state_check``'s message for a controller's bytes, or None if a run can go
        on from them."""
        msg = ctypes.create_string_buffer(_MSG_LEN)
        if self.api.state_check(ctypes.addressof(buffer), msg, _MSG_LEN) == 0:
            return None
        return msg.value.decode("utf-8", "replace")


@functools.lru_cache(maxsize=8)
def _load(path: str) -> NativeControllerLibrary | None:
    try:
        return NativeControllerLibrary(path)
    except NativeControllerError:
        return None


def controller_library(unzip_dir: str | os.PathLike | None) -> NativeControllerLibrary | None:
    """The C controller of an extracted FMU, or None where there is none to use (no folder,
    no binary for this platform, a binary without :data:`API_SYMBOL` or with other tables).
    A binary is loaded once per process."""
    if unzip_dir is None:
        return None
    path = binary_path(unzip_dir)
    return None if path is None else _load(str(path))


#: The C controller of each PulseController.fmu file of this process, by path: extracted once
#: into a temporary folder removed at exit.
_BY_FMU: dict[str, NativeControllerLibrary | None] = {}


def fmu_controller_library(fmu: str | os.PathLike | None) -> NativeControllerLibrary | None:
    """The C controller of the PulseController.fmu at ``fmu``, or None where it gives none
    (no file, no binary for this platform, another layout). The FMU is extracted once per
    process."""
    if fmu is None:
        return None
    key = str(fmu)
    if key not in _BY_FMU:
        if not Path(fmu).is_file():
            return None
        import atexit
        import shutil
        import tempfile

        from fmpy import extract

        folder = tempfile.mkdtemp(prefix="papwc_controller_")
        atexit.register(shutil.rmtree, folder, True)
        try:
            extract(str(fmu), unzipdir=folder)
        except Exception:  # noqa: BLE001 - not an archive: the Python controller runs instead
            _BY_FMU[key] = None
        else:
            _BY_FMU[key] = controller_library(folder)
    return _BY_FMU[key]


def controller_slave(settings: ControllerSettings, T: float,
                     library: NativeControllerLibrary | None = None,
                     name: str = "controller"):
    """The master's controller slave of ``settings`` at period ``T`` (s): the C controller of
    ``library`` for a kind it implements, else the Python controller
    (:class:`papwc.master.slave.ControllerSlave`). Both give the same numbers."""
    from papwc.controllers import make_controller
    from papwc.master.slave import ControllerSlave

    if library is not None and settings.kind in _native_kinds():
        return NativeControllerSlave(library, settings, T, name)
    return ControllerSlave(make_controller(settings, T), name)


def _native_kinds() -> tuple[str, ...]:
    """The kinds of the C controller (its header's PC_KINDS, from the model layer)."""
    from papwc.fmubuild.native_tables import NATIVE_KINDS

    return NATIVE_KINDS


class NativeControllerSlave(ControllerInputs):
    """The C controller as a slave: the variables and behaviour of
    :class:`papwc.master.slave.ControllerSlave` around the Python controller of the same
    settings.

    ``do_step(t, h)`` samples the inputs ``x_meas`` and ``x_ref`` (m) present at ``t`` and
    sets ``u`` (N), the force to hold over the next sample, and the outputs;
    ``restart`` starts a new maneuver keeping what was learned.

    Parameters
    ----------
    library : NativeControllerLibrary
        The binary's functions.
    settings : ControllerSettings
        Valid settings of a kind the C controller implements.
    T : float
        Sample period, s.
    name : str
        Instance name.
    """

    reads_x_d_meas = False

    def __init__(self, library: NativeControllerLibrary, settings: ControllerSettings,
                 T: float, name: str = "controller") -> None:
        self.name = name
        self.library = library
        self.settings = settings
        self._c = library.new(settings, T)
        self._p = ctypes.addressof(self._c)
        self._sample = library.api.sample
        self.y = PcOutputs()
        self._y = ctypes.byref(self.y)
        library.api.outputs_of(self._p, self._y)
        self._init_inputs()

    def variables(self) -> Mapping[str, str]:
        """Causality of every variable."""
        return dict(CONTROLLER_SLAVE_VARIABLES)

    def _path(self, name: str) -> str:
        if name in ("x_meas", "x_ref", "x_d_meas", "u"):
            return name
        return f"y.{name}"

    def restart(self, start_time: float = 0.0) -> None:
        """A new maneuver from rest, keeping what the controller learned."""
        self.library.api.reset(self._p, self._y)
        self.initialize(start_time)

    def do_step(self, t: float, h: float) -> None:
        """Sample at ``t`` (the step size is the controller's T) and refresh :attr:`values`."""
        self.u = self._sample(self._p, t, self.x_meas, self.x_ref, self._y)
        self.values = list(self._read(self))
