"""The C plant (fmu_src/FrictionPlant/plant.c) compiled for the host and loaded with ctypes.

:func:`compiler` finds a C compiler (``PAPWC_TEST_CC``, else the system ``cc``, ``gcc`` or
``clang``, else ``python -m ziglang cc``); :func:`build_plant_library` writes ``plant_vars.h`` with
:func:`papwc.fmubuild.native_tables.write_plant_header` and compiles ``plant.c`` into
a shared library with the flags that keep IEEE double arithmetic as Python does it
(``-O2 -ffp-contract=off``, no ``-ffast-math``); :class:`NativePlant` wraps its API
(``plant.h``) with the structs laid out as there.
"""

from __future__ import annotations

import ctypes
import subprocess
import sys
from pathlib import Path
from typing import Any

from papwc.fmubuild.native_build import host_compiler
from papwc.fmubuild.native_tables import write_plant_header
from papwc.model.plant import PLANT_OUTPUTS, PLANT_PARAMETERS

PROJECT_DIR = Path(__file__).resolve().parent.parent
PLANT_SOURCES = (PROJECT_DIR / "fmu_src" / "FrictionPlant" / "plant.c",)
PLANT_INCLUDE = PROJECT_DIR / "fmu_src" / "FrictionPlant"
#: Flags of every compilation of the plant: C99, optimized, no contraction into FMA.
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared", "-Wall", "-Wextra")

_CTYPES = {"Real": ctypes.c_double, "Integer": ctypes.c_int32, "Boolean": ctypes.c_int}


class FpParams(ctypes.Structure):
    """``FpParams`` of plant_vars.h: one field per parameter, in PLANT_PARAMETERS order."""

    _fields_ = [(v.name, _CTYPES[v.type]) for v in PLANT_PARAMETERS]


class FpOutputs(ctypes.Structure):
    """``FpOutputs`` of plant_vars.h."""

    _fields_ = [(v.name, _CTYPES[v.type]) for v in PLANT_OUTPUTS]


class FpState(ctypes.Structure):
    """``FpState`` of plant.h (the fields of papwc.model.dynamics.STATE_FIELDS)."""

    _fields_ = [("x", ctypes.c_double), ("v", ctypes.c_double), ("z", ctypes.c_double),
                ("x_d", ctypes.c_double), ("v_d", ctypes.c_double), ("f_a", ctypes.c_double),
                ("f_s_now", ctypes.c_double), ("stick_draws", ctypes.c_uint64),
                ("noise_draws", ctypes.c_uint64), ("noise", ctypes.c_double),
                ("h_next", ctypes.c_double)]


def compiler() -> list[str] | None:
    """The command of a C compiler on this machine, or None.

    ``PAPWC_TEST_CC`` (a command, split at spaces) chooses one, e.g.
    ``"python -m ziglang cc -target x86_64-linux-gnu.2.17"``: the toolchain of the FMU;
    else the system ``cc``, ``gcc`` or ``clang``, else zig's
    (:func:`papwc.fmubuild.native_build.host_compiler`).
    """
    return host_compiler("PAPWC_TEST_CC")


def _build(folder: Path, write_header, sources: tuple[Path, ...], include: Path, name: str,
           command: list[str] | None) -> Path:
    """Write a generated header into ``folder`` (``write_header(folder)``) and compile
    ``sources`` there into the shared library ``name``; its path.

    Raises
    ------
    RuntimeError
        If no compiler is found or the compilation fails (its output in the message).
    """
    command = command or compiler()
    if command is None:
        raise RuntimeError("no C compiler (cc, gcc, clang or the ziglang package)")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_header(folder)
    library = folder / (f"{name}.dll" if sys.platform == "win32" else f"lib{name}.so")
    args = [*command, *CFLAGS, f"-I{folder}", f"-I{include}", "-o", str(library),
            *map(str, sources), "-lm"]
    done = subprocess.run(args, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed:\n{done.stdout}{done.stderr}")
    return library


def build_plant_library(folder: Path, command: list[str] | None = None) -> Path:
    """Write plant_vars.h into ``folder`` and compile plant.c there; the library's path."""
    return _build(folder, lambda f: write_plant_header(Path(f) / "plant_vars.h"), PLANT_SOURCES,
                  PLANT_INCLUDE, "plant", command)


class NativeLibrary:
    """The compiled plant's functions with their argument types."""

    def __init__(self, path: Path) -> None:
        lib = ctypes.CDLL(str(path))
        lib.fp_defaults.argtypes = [ctypes.POINTER(FpParams)]
        lib.fp_defaults.restype = None
        lib.fp_check.argtypes = [ctypes.POINTER(FpParams), ctypes.c_char_p, ctypes.c_size_t]
        lib.fp_check.restype = ctypes.c_int
        lib.fp_reset.argtypes = [ctypes.POINTER(FpState), ctypes.POINTER(FpParams)]
        lib.fp_reset.restype = None
        lib.fp_step.argtypes = [ctypes.POINTER(FpState), ctypes.POINTER(FpParams),
                                ctypes.c_double, ctypes.c_double, ctypes.c_char_p,
                                ctypes.c_size_t]
        lib.fp_step.restype = ctypes.c_int
        lib.fp_state_check.argtypes = [ctypes.POINTER(FpState), ctypes.c_char_p,
                                        ctypes.c_size_t]
        lib.fp_state_check.restype = ctypes.c_int
        lib.fp_outputs.argtypes = [ctypes.POINTER(FpState), ctypes.POINTER(FpParams),
                                   ctypes.POINTER(FpOutputs)]
        lib.fp_outputs.restype = None
        self.lib = lib

    def params(self, values: dict[str, Any] | None = None) -> FpParams:
        """The defaults of fp_defaults with ``values`` set over them."""
        p = FpParams()
        self.lib.fp_defaults(ctypes.byref(p))
        for name, value in (values or {}).items():
            setattr(p, name, value)
        return p

    def check(self, values: dict[str, Any]) -> str | None:
        """fp_check's message for these parameters, or None if they are accepted."""
        buf = ctypes.create_string_buffer(512)
        if self.lib.fp_check(ctypes.byref(self.params(values)), buf, len(buf)) == 0:
            return None
        return buf.value.decode()


    def state_check(self, state: FpState) -> str | None:
        """fp_state_check's message for this state, or None if it can be restored."""
        buf = ctypes.create_string_buffer(256)
        if self.lib.fp_state_check(ctypes.byref(state), buf, len(buf)) == 0:
            return None
        return buf.value.decode()


class NativePlant:
    """A C plant with the interface of :class:`papwc.model.dynamics.Plant` that tests use."""

    def __init__(self, library: NativeLibrary, params: dict[str, Any]) -> None:
        self._lib = library.lib
        self.params = library.params(params)
        self.state = FpState()
        self._msg = ctypes.create_string_buffer(256)
        self.reset()

    def reset(self) -> None:
        self._lib.fp_reset(ctypes.byref(self.state), ctypes.byref(self.params))

    def step(self, u: float, h: float) -> str | None:
        if self._lib.fp_step(ctypes.byref(self.state), ctypes.byref(self.params), u, h,
                             self._msg, len(self._msg)) == 0:
            return None
        return self._msg.value.decode()

    def outputs(self) -> FpOutputs:
        y = FpOutputs()
        self._lib.fp_outputs(ctypes.byref(self.state), ctypes.byref(self.params),
                             ctypes.byref(y))
        return y

    def copy_state(self) -> FpState:
        """A copy of the state struct (bytes copied, as memcpy does)."""
        return FpState.from_buffer_copy(self.state)

    def set_state(self, state: FpState) -> None:
        ctypes.memmove(ctypes.byref(self.state), ctypes.byref(state), ctypes.sizeof(FpState))

    def fields(self) -> dict[str, float | int]:
        """The state as :meth:`papwc.model.dynamics.Plant.state` gives it."""
        return {name: getattr(self.state, name) for name, _ in FpState._fields_}


# --- the controller (fmu_src/PulseController/controller.c) ----------------------------------

CONTROLLER_DIR = PROJECT_DIR / "fmu_src" / "PulseController"
#: The library a drive links and the table papwc's master reads from it.
CONTROLLER_SOURCES = (CONTROLLER_DIR / "controller.c", CONTROLLER_DIR / "controller_api.c")


def build_controller_library(folder: Path, command: list[str] | None = None) -> Path:
    """Write controller_vars.h into ``folder`` and compile controller.c and controller_api.c
    there (the flags of the plant); the library's path."""
    from papwc.fmubuild.native_tables import write_controller_header

    return _build(folder, write_controller_header, CONTROLLER_SOURCES, CONTROLLER_DIR,
                  "controller", command)


_D, _I32, _I64 = ctypes.c_double, ctypes.c_int32, ctypes.c_int64


def _fields(kind: Any, names: str) -> list[tuple[str, Any]]:
    return [(name, kind) for name in names.split()]


class PcConfig(ctypes.Structure):
    """``PcConfig`` of papwc_controller.h."""

    _fields_ = (_fields(_I32, "kind guarded flexible automatic regressor update_covariance "
                              "floor_mode window") + [("T", _D)]
                + _fields(_I64, "n_max max_pulses mode_samples rest_samples hunt_max")
                + _fields(_D, "rest_band tolerance e_band f_p_max f_c_est m_est m_d_est k_p k_d "
                              "K_c floor_raise trust0 lambda_1 lambda_2 b_min b_max delta_inv lam "
                              "a1_min a1_max a2_min a2_max pid_k_p pid_k_d pid_k_i a_max v_max "
                              "w_band q"))


class PcRest(ctypes.Structure):
    """``PcRest`` of papwc_controller.h."""

    _fields_ = ([("sigma2", _D), ("noise_rests", _I64)]
                + _fields(_D, "anchor lo hi sum sum2") + _fields(_I64, "n look")
                + [("ring", _D * 16), ("ring_n", _I64), ("dir", _D)]
                + _fields(_I64, "turns ring_dwell") + [("x_turn", _D)]
                + _fields(_I64, "legs since_force since_turn") + [("band", _D), ("dwell", _I64)])


class PcTrust(ctypes.Structure):
    """``PcTrust`` of papwc_controller.h."""

    _fields_ = [("value", _D), ("ring", _I64), ("d_one", _D)]


class PcSequencer(ctypes.Structure):
    """``PcSequencer`` of papwc_controller.h."""

    _fields_ = (_fields(_I64, "mode pulses first") + _fields(_D, "x_prev v_hat")
                + [("pulse_left", _I64), ("f_pulse", _D), ("n_pulse", _I64), ("x_start", _D)]
                + _fields(_I64, "waited last_n") + _fields(_D, "last_f last_d")
                + _fields(_I64, "outcome outcome_reason stopped") + [("e0", _D)]
                + [("released", _I64), ("pred", _D), ("refusal", _I64), ("stall_x", _D)]
                + _fields(_I64, "stall_n idle_samples") + _fields(_D, "idle_x idle_ref"))


class PcLaw(ctypes.Structure):
    """``PcLaw`` of papwc_controller.h."""

    _fields_ = (_fields(_D, "f_p_floor b_hat F_inv a1 a2 p11 p12 p22 f_p_plan t_p_plan")
                + [("creeps", _D * 4), ("k", _I64)]
                + _fields(_D, "integral x_from x_to x_ref_now side") + [("reversals", _I64)]
                + [("holding", _I64)] + _fields(_D, "u_hold u_last") + [("ring", _D * 16)]
                + [("ring_n", _I64)] + _fields(_D, "h_x0 h_sum")
                + _fields(_I64, "h_n h_look coasting") + [("u_coast", _D)])


def controller_struct() -> type[ctypes.Structure]:
    """``PcController`` of papwc_controller.h (its settings as the master lays them out)."""
    from papwc.master.native_controller import PcSettings

    class PcController(ctypes.Structure):
        _fields_ = [("magic", ctypes.c_uint32), ("size", ctypes.c_uint32),
                    ("settings", PcSettings), ("cfg", PcConfig), ("rest", PcRest),
                    ("trust", PcTrust), ("seq", PcSequencer), ("law", PcLaw)]

    return PcController


#: Names of the law's state (PulseControllerBase.law_state and the kinds') -> PcLaw field.
LAW_FIELDS = {"f_p_floor": "f_p_floor", "b_hat": "b_hat", "F_inv": "F_inv",
              "t_p_plan": "t_p_plan", "A1": "a1", "A2": "a2", "P11": "p11", "P12": "p12",
              "P22": "p22", "f_p_plan": "f_p_plan", "creeps": "creeps", "k": "k",
              "integral": "integral", "x_from": "x_from", "x_to": "x_to",
              "x_ref_now": "x_ref_now", "side": "side", "reversals": "reversals",
              **{name: name for name in ("holding", "u_hold", "u_last", "ring", "ring_n",
                                         "h_x0", "h_sum", "h_n", "h_look", "coasting",
                                         "u_coast")}}


def controller_state(c: ctypes.Structure, names: list[str]) -> dict[str, Any]:
    """The C controller ``c``'s state under the names of the Python controller's ``state()``
    (``sequencer.mode``, ``rest.ring``, ``law.A1``, ...): the idle samples counted in as
    ``state()`` counts them (PulseSequencer.catch_up)."""
    rest = PcRest.from_buffer_copy(c.rest)
    k = c.seq.idle_samples
    if k:
        rest.n += k
        for i in range(min(k, 16)):
            rest.ring[(rest.ring_n + i) % 16] = c.seq.idle_x
        rest.ring_n += k
    parts = {"sequencer": c.seq, "rest": rest, "trust": c.trust, "law": c.law}
    out: dict[str, Any] = {}
    for key in names:
        part, name = key.split(".", 1)
        value = getattr(parts[part], LAW_FIELDS[name] if part == "law" else name)
        out[key] = list(value) if isinstance(value, ctypes.Array) else value
    return out
