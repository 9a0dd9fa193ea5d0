"""The C plant of a native FrictionPlant.fmu, called in process with the interface of Plant.

The native FMU's binary exports, beside the fmi2 functions, one table of the plant's own
functions (``papwc_plant_api`` in ``fmu_src/FrictionPlant/fmu_model.c``): ``fp_defaults``,
``fp_check``, ``fp_reset``, ``fp_step``, ``fp_state_check`` and ``fp_outputs`` of
``fmu_src/FrictionPlant/plant.h``, with the size and the fields (``name:TYPE`` in order) of
each struct they take. :func:`plant_library` loads that table from an extracted FMU when
the FMU has a binary for this platform and its structs are laid out as the model layer's
variables say (:data:`papwc.model.plant.PLANT_PARAMETERS`, ``PLANT_OUTPUTS``,
:data:`papwc.model.dynamics.STATE_FIELDS`); otherwise (a pythonfmu FMU, an FMU without a
binary for this platform, one built from other tables) it gives None, and the caller
uses :class:`papwc.model.dynamics.Plant`.

:class:`NativePlant` has the interface of :class:`papwc.model.dynamics.Plant` that the
table's quantum uses (:mod:`papwc.results.quantum`, the runaway bound's floor):
``reset``, ``state``/``set_state``, ``step(u, h)`` returning None or why it is refused,
``x``, ``v``, ``x_meas()``, ``stuck``. The C plant equals ``Plant`` bit for bit
(tests/unit/test_native_physics.py), so the quantum is the same on either; in C a step with
a deviation costs microseconds instead of the model layer's 0.2-1.5 ms.
"""

from __future__ import annotations

import ctypes
import functools
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from papwc.model.dynamics import STATE_FIELDS
from papwc.model.plant import PLANT_DEFAULTS, PLANT_OUTPUTS, PLANT_PARAMETERS

__all__ = ["API_SYMBOL", "API_VERSION", "NativePlant", "NativePlantLibrary",
           "NativePlantError", "api_table", "layout_struct", "own_plant_library",
           "plant_library"]

#: The exported function that returns the table of the plant's functions.
API_SYMBOL = "papwc_plant_api"
#: The version of that table this module reads.
API_VERSION = 1

#: Model layer type -> (the C header's type name, ctypes type).
_TYPES = {"Real": ("FP_REAL", ctypes.c_double), "Integer": ("FP_INTEGER", ctypes.c_int32),
          "Boolean": ("FP_BOOLEAN", ctypes.c_int)}
#: Fields of the state that count random draws (uint64_t); the others are doubles.
_COUNT_FIELDS = ("stick_draws", "noise_draws")
#: Bytes of a refusal message.
_MSG_LEN = 512


def layout_struct(name: str, fields: list[tuple[str, str, Any]]) -> type[ctypes.Structure]:
    """A ctypes struct with ``fields`` (name, C type name, ctypes type), and its layout text
    (``"name:TYPE "`` per field, as a native binary's API table gives it)."""
    cls = type(name, (ctypes.Structure,), {"_fields_": [(n, t) for n, _, t in fields]})
    cls.layout = "".join(f"{n}:{c} " for n, c, _ in fields)
    return cls


#: ``FpParams`` of plant_vars.h: one field per parameter, in the model layer's order.
FpParams = layout_struct("FpParams", [(v.name, *_TYPES[v.type]) for v in PLANT_PARAMETERS])
#: ``FpOutputs`` of plant_vars.h.
FpOutputs = layout_struct("FpOutputs", [(v.name, *_TYPES[v.type]) for v in PLANT_OUTPUTS])
#: ``FpState`` of plant.h: the fields of STATE_FIELDS.
FpState = layout_struct("FpState", [(n, "FP_COUNT", ctypes.c_uint64) if n in _COUNT_FIELDS
                              else (n, "FP_REAL", ctypes.c_double) for n in STATE_FIELDS])

_P_PARAMS, _P_STATE, _P_OUT = (ctypes.POINTER(FpParams), ctypes.POINTER(FpState),
                               ctypes.POINTER(FpOutputs))


class _Api(ctypes.Structure):
    """``PlantApi`` of fmu_model.c."""

    _fields_ = [
        ("version", ctypes.c_int),
        ("params_size", ctypes.c_size_t),
        ("state_size", ctypes.c_size_t),
        ("outputs_size", ctypes.c_size_t),
        ("params", ctypes.c_char_p),
        ("state", ctypes.c_char_p),
        ("outputs", ctypes.c_char_p),
        ("defaults", ctypes.CFUNCTYPE(None, _P_PARAMS)),
        ("check", ctypes.CFUNCTYPE(ctypes.c_int, _P_PARAMS, ctypes.c_char_p, ctypes.c_size_t)),
        ("reset", ctypes.CFUNCTYPE(None, _P_STATE, _P_PARAMS)),
        ("step", ctypes.CFUNCTYPE(ctypes.c_int, _P_STATE, _P_PARAMS, ctypes.c_double,
                                  ctypes.c_double, ctypes.c_char_p, ctypes.c_size_t)),
        ("state_check", ctypes.CFUNCTYPE(ctypes.c_int, _P_STATE, ctypes.c_char_p,
                                         ctypes.c_size_t)),
        ("outputs_of", ctypes.CFUNCTYPE(None, _P_STATE, _P_PARAMS, _P_OUT)),
    ]


class NativePlantError(Exception):
    """A binary does not provide the plant as this module reads it."""


def api_table(path: Path, symbol: str, version: int, table: type[ctypes.Structure],
              error: type[Exception], structs: tuple[tuple[str, Any, str, str], ...]
              ) -> tuple[ctypes.CDLL, Any]:
    """Load ``path`` and the table its exported ``symbol()`` returns, checked.

    Parameters
    ----------
    path : Path
        A native binary.
    symbol : str
        The exported function that returns a pointer to the table.
    version : int
        The table's ``version`` field this papwc reads.
    table : ctypes.Structure subclass
        The table's layout.
    error : Exception subclass
        Raised, with what is wrong, if the binary cannot be loaded, lacks the symbol or
        differs in version or in the layout of a struct.
    structs : tuple of (name, ctypes struct, size field, layout field)
        Each struct the table describes: its ``sizeof`` and ``"name:TYPE "`` fields must be
        the struct's (:func:`layout_struct`).

    Returns
    -------
    (ctypes.CDLL, table)
        The library (keep it: it keeps the binary loaded) and the table.
    """
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as exc:
        raise error(f"{path}: cannot be loaded: {exc}") from exc
    try:
        get_api = getattr(lib, symbol)
    except AttributeError as exc:
        raise error(f"{path}: exports no {symbol}") from exc
    get_api.argtypes = []
    get_api.restype = ctypes.POINTER(table)
    api = get_api().contents
    if api.version != version:
        raise error(f"{path}: {symbol} version {api.version}, this papwc reads version "
                    f"{version}")
    for what, cls, size_field, layout_field in structs:
        size = getattr(api, size_field)
        text = (getattr(api, layout_field) or b"").decode("ascii", "replace")
        if size != ctypes.sizeof(cls) or text != cls.layout:
            raise error(f"{path}: its {what} ({size} bytes: {text.strip()}) is not the model "
                        f"layer's ({ctypes.sizeof(cls)} bytes: {cls.layout.strip()}); rebuild "
                        "the FMU (papwc build)")
    return lib, api


class NativePlantLibrary:
    """The plant's functions in a native FrictionPlant binary, checked against the model layer.

    Parameters
    ----------
    path : path
        The binary (``binaries/<platform>/FrictionPlant.so``, ``.dll``, ``.dylib``).

    Raises
    ------
    NativePlantError
        If it cannot be loaded, does not export :data:`API_SYMBOL`, or its version,
        struct sizes or fields differ from this module's.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        lib, api = api_table(self.path, API_SYMBOL, API_VERSION, _Api, NativePlantError, (
            ("FpParams", FpParams, "params_size", "params"),
            ("FpState", FpState, "state_size", "state"),
            ("FpOutputs", FpOutputs, "outputs_size", "outputs")))
        self._lib = lib  # keeps the binary loaded while the table is used
        self.api = api

    def params(self, values: Mapping[str, Any]) -> FpParams:
        """The C parameters: the model layer's defaults with ``values`` over them."""
        p = FpParams()
        merged = {**PLANT_DEFAULTS, **values}
        for var in PLANT_PARAMETERS:
            value = merged[var.name]
            setattr(p, var.name, float(value) if var.type == "Real" else int(value))
        return p


@functools.lru_cache(maxsize=8)
def _load(path: str) -> NativePlantLibrary | None:
    try:
        return NativePlantLibrary(path)
    except NativePlantError:
        return None


def binary_path(unzip_dir: str | os.PathLike) -> Path | None:
    """The binary of an extracted FMU for this platform (fmpy's names), or None."""
    from fmpy import platform, sharedLibraryExtension

    folder = Path(unzip_dir)
    try:
        root = ET.parse(folder / "modelDescription.xml").getroot()
    except (OSError, ET.ParseError):
        return None
    cs = root.find("CoSimulation")
    if cs is None or not cs.get("modelIdentifier"):
        return None
    path = folder / "binaries" / platform / (cs.get("modelIdentifier") + sharedLibraryExtension)
    return path if path.is_file() else None


def plant_library(unzip_dir: str | os.PathLike | None) -> NativePlantLibrary | None:
    """The C plant of an extracted FMU, or None where there is none to use.

    None for no folder, an FMU without a binary for this platform, a binary that does
    not export :data:`API_SYMBOL` (a pythonfmu FMU) or whose structs are not the model
    layer's. A folder is looked at, and a binary loaded, once per process.
    """
    if unzip_dir is None:
        return None
    key = str(unzip_dir)
    if key not in _FOUND:
        path = binary_path(unzip_dir)
        _FOUND[key] = None if path is None else _load(str(path))
    return _FOUND[key]


@functools.lru_cache(maxsize=1)
def own_plant_library() -> NativePlantLibrary | None:
    """The C plant papwc was installed with (``papwc/_native/FrictionPlant/``), where it was
    compiled from FrictionPlant's C sources as they are now, or None (the caller uses
    :class:`papwc.model.dynamics.Plant`, the same numbers). Looked at once per process."""
    from fmpy import platform, sharedLibraryExtension

    from papwc.fmubuild.fmus import FMUS
    from papwc.fmubuild.native_build import prepared_tree
    from papwc.fmubuild.prebuilt import DIGEST_FILE, NATIVE_DIR, sources_digest

    recipe = next((r for r in FMUS if r.name == "FrictionPlant" and r.native), None)
    home = NATIVE_DIR / "FrictionPlant"
    binary = home / platform / ("FrictionPlant" + sharedLibraryExtension)
    if recipe is None or not binary.is_file():
        return None
    try:
        recorded = (home / DIGEST_FILE).read_text(encoding="ascii").strip()
        with prepared_tree(recipe.native_source()) as tree:
            current = sources_digest(tree)
    except (OSError, ValueError):
        return None
    return _load(str(binary)) if recorded == current else None


#: What :func:`plant_library` found in each extracted FMU of this process.
_FOUND: dict[str, NativePlantLibrary | None] = {}


class NativePlant:
    """The C plant with the interface of :class:`papwc.model.dynamics.Plant` (see the module).

    Parameters
    ----------
    library : NativePlantLibrary
        The binary's functions.
    params : mapping
        Plant parameters by name (missing ones default); not checked here, as Plant's
        are not (check them with :func:`papwc.model.plant.plant_problems`).
    """

    def __init__(self, library: NativePlantLibrary, params: Mapping[str, Any]) -> None:
        api = library.api
        self._step = api.step
        self._reset = api.reset
        self._outputs = api.outputs_of
        self._state_check = api.state_check
        self.params = library.params(params)
        self._p = ctypes.byref(self.params)
        self._s_struct = FpState()
        self._s = ctypes.byref(self._s_struct)
        self._msg = ctypes.create_string_buffer(_MSG_LEN)
        merged = {**PLANT_DEFAULTS, **params}
        if float(merged["ripple"]) > 0.0:
            from papwc.model.effects.ripple import Ripple

            self._ripple = Ripple(merged["ripple"], merged["ripple_period"],
                                  merged["ripple_phase"])
        else:
            self._ripple = None
        self.reset()

    def reset(self) -> None:
        """The state at the start (Plant.reset)."""
        ctypes.memset(self._s, 0, ctypes.sizeof(FpState))
        self._reset(self._s, self._p)

    def step(self, u: float, h: float) -> str | None:
        """Advance over ``h`` (s) with the force ``u`` (N) held: None, or why it is refused."""
        if self._step(self._s, self._p, u, h, self._msg, _MSG_LEN) == 0:
            return None
        return self._msg.value.decode("utf-8", "replace")

    def state(self) -> dict[str, float | int]:
        """The full state, as Plant.state gives it."""
        s = self._s_struct
        return {name: getattr(s, name) for name in STATE_FIELDS}

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state of :meth:`state` (or of Plant.state).

        Raises
        ------
        ValueError
            If a field is missing, unknown, not a number, not a count or not finite; the
            state is then left as it was.
        """
        if not isinstance(values, Mapping) or sorted(values) != sorted(STATE_FIELDS):
            raise ValueError(f"a plant state has the fields {', '.join(STATE_FIELDS)}")
        new = FpState()
        for name in STATE_FIELDS:
            value = values[name]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"plant state field {name} = {value!r} is not a number")
            if name in _COUNT_FIELDS and not (isinstance(value, int)
                                              and 0 <= value < 2**64):
                raise ValueError(f"plant state field {name} = {value!r} is not a count")
            setattr(new, name, value)
        if self._state_check(ctypes.byref(new), self._msg, _MSG_LEN) != 0:
            raise ValueError(self._msg.value.decode("utf-8", "replace"))
        ctypes.memmove(ctypes.addressof(self._s_struct), ctypes.addressof(new),
                       ctypes.sizeof(FpState))

    def _out(self) -> FpOutputs:
        y = FpOutputs()
        self._outputs(self._s, self._p, ctypes.byref(y))
        return y

    @property
    def x(self) -> float:
        """Table position, m."""
        return self._s_struct.x

    @property
    def v(self) -> float:
        """Table velocity, m/s (exactly 0.0 while stuck)."""
        return self._s_struct.v

    @property
    def f_s_now(self) -> float:
        """Breakaway force in effect, N."""
        return self._s_struct.f_s_now

    def x_meas(self) -> float:
        """Position read by the encoder, m (Plant.x_meas)."""
        return self._out().x_meas

    @property
    def stuck(self) -> bool:
        """Whether the table is stuck (the output ``stuck``)."""
        return bool(self._out().stuck)

    def _breakaway(self, x: float) -> float:
        """The force the stuck table holds before it breaks away, N (Plant._breakaway)."""
        if self._ripple is not None:
            return self._ripple.factor(x)[0] * self._s_struct.f_s_now
        return self._s_struct.f_s_now
