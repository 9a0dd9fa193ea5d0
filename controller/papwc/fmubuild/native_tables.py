"""``plant_vars.h``: the native FrictionPlant's variables, generated from the model layer.

Standard library only. The C plant (``fmu_src/FrictionPlant/plant.c``) and the
FMI glue of the native FMU read every parameter's, input's and output's name,
value reference, type, start value and range from this header, and the plant's
integrator its tolerances and limits, so each is still declared once, in
:mod:`papwc.model.plant` and :mod:`papwc.model.dynamics`:

- ``FP_PARAMETERS(X)``, ``FP_INPUTS(X)``: ``X(name, vr, type, start, min, max,
  min_open, max_open)`` per variable (``type`` ``FP_REAL``, ``FP_INTEGER`` or
  ``FP_BOOLEAN``; no bound: ``-INFINITY``/``INFINITY``);
- ``FP_OUTPUTS(X)``: ``X(name, vr, type)``;
- ``FP_UNITS(X)``: ``X(name, "unit")`` for every variable (for messages);
- ``FpParams`` and ``FpOutputs``: one field per parameter and per output, same name;
- the integrator's tolerances (:data:`papwc.model.dynamics.TOLERANCES`), its
  limits (``MAX_STEPS``, ``MAX_EVENTS``) and the random streams of
  :mod:`papwc.model.effects`;
- the data of the rules between parameters (:data:`papwc.model.plant.PLANT_CONSTRAINTS`):
  ``FP_OFF_OR_AT_LEAST(X)`` and ``FP_INTEGRATED_OFF_OR_AT_LEAST(X)``, ``X(name, low,
  "low", " unit")`` per entry of :data:`~papwc.model.plant.OFF_OR_AT_LEAST` and
  :data:`~papwc.model.plant.INTEGRATED_OFF_OR_AT_LEAST` in their order (``"low"`` as the
  messages write it, ``f"{low:g}"``; the unit as ``Variable.unit_suffix``);
  ``FP_INTEGRATED(X)``, ``X(name)`` per deviation of
  :data:`~papwc.model.plant.INTEGRATED` in its order; the highest mode frequency, damping
  rate and acceleration (``MODE_FREQUENCY_MAX``, ``DAMPING_RATE_MAX``,
  ``ACCELERATION_MAX``), each also as ``..._TEXT``, written as the messages write it
  (``f"{x:g}"``), so no message depends on the C library's ``%g``.

Value references are the index of a variable in
:data:`papwc.model.plant.PLANT_VARIABLES`, as in the model description.
Numbers are written with ``repr``, so the C compiler reads the same doubles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from papwc.model import plant as plant_rules
from papwc.model.dynamics import MAX_EVENTS, MAX_STEPS, TOLERANCES
from papwc.model.effects.encoder import MOTOR_STREAM as MOTOR_NOISE_STREAM
from papwc.model.effects.encoder import STREAM as NOISE_STREAM
from papwc.model.effects.stiction import STREAM as STICTION_STREAM
from papwc.model.plant import PLANT_INPUTS, PLANT_OUTPUTS, PLANT_PARAMETERS, PLANT_VARIABLES
from papwc.model.variables import Variable

__all__ = ["CONTROLLER_HEADER_NAME", "GENERATED_HEADERS", "HEADER_NAME", "NATIVE_KINDS",
           "ControllerTables", "controller_header", "controller_tables", "plant_header",
           "rule_tables", "value_references", "write_controller_header",
           "write_plant_header"]

#: File name of the generated header.
HEADER_NAME = "plant_vars.h"

_C_TYPES = {"Real": ("FP_REAL", "double"), "Integer": ("FP_INTEGER", "int32_t"),
            "Boolean": ("FP_BOOLEAN", "int")}


def value_references() -> dict[str, int]:
    """Value reference of every variable of FrictionPlant: its index in PLANT_VARIABLES."""
    return {var.name: i for i, var in enumerate(PLANT_VARIABLES)}


def _c_number(value: float | int | bool | None, var: Variable, infinity: str) -> str:
    """A start value or bound as a C literal of the variable's type (``repr``: exact)."""
    if value is None:
        return infinity
    if var.type == "Boolean":
        return "1" if value else "0"
    if var.type == "Integer":
        return str(int(value))
    value = float(value)
    if math.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    if math.isnan(value):
        raise ValueError(f"variable {var.name}: NaN cannot be a start value or bound")
    text = repr(value)
    return f"({text})" if text.startswith("-") else text


def _entry(var: Variable, vr: int) -> str:
    kind = _C_TYPES[var.type][0]
    return (f"X({var.name}, {vr}, {kind}, {_c_number(var.fmi_start, var, '0')}, "
            f"{_c_number(var.min, var, '(-INFINITY)')}, {_c_number(var.max, var, 'INFINITY')}, "
            f"{int(var.min_open)}, {int(var.max_open)})")


def _x_macro(name: str, lines: list[str]) -> str:
    body = " \\\n    ".join(lines)
    return f"#define {name}(X) \\\n    {body}\n"


def _real_parameter(name: str, table: str) -> Variable:
    """The Real parameter ``name`` that the rule table ``table`` names (the C reads a double)."""
    var = next((v for v in PLANT_PARAMETERS if v.name == name), None)
    if var is None or var.type != "Real":
        raise ValueError(f"{table} names {name!r}: the C rules read Real plant parameters only")
    return var


def _c_string(text: str) -> str:
    """``text`` as a C string literal (the texts here are plain ASCII)."""
    if not text.isascii() or any(ch in text for ch in '"\\\n'):
        raise ValueError(f"{text!r} cannot be written as a plain C string literal")
    return f'"{text}"'


def _limit(name: str, value: float) -> list[str]:
    """``#define FP_<name>`` (the double) and ``FP_<name>_TEXT`` (as messages write it)."""
    return [f"#define FP_{name} {float(value)!r}",
            f"#define FP_{name}_TEXT {_c_string(format(float(value), 'g'))}"]


def rule_tables() -> str:
    """The part of ``plant_vars.h`` that gives the data of the rules between parameters."""
    def off(table: dict[str, float], label: str) -> list[str]:
        return [f"X({name}, {float(low)!r}, {_c_string(format(float(low), 'g'))}, "
                f"{_c_string(_real_parameter(name, label).unit_suffix)})"
                for name, low in table.items()]

    for name in plant_rules.INTEGRATED:
        _real_parameter(name, "INTEGRATED")
    return "\n".join([
        "/* The rules between parameters (papwc.model.plant.PLANT_CONSTRAINTS).",
        " * X(name, low, \"low\", \" unit\"): 0 (none) or >= low; OFF_OR_AT_LEAST always,",
        " * INTEGRATED_OFF_OR_AT_LEAST when an INTEGRATED deviation is > 0 (the first",
        " * names it). */",
        _x_macro("FP_OFF_OR_AT_LEAST", off(plant_rules.OFF_OR_AT_LEAST, "OFF_OR_AT_LEAST")),
        _x_macro("FP_INTEGRATED_OFF_OR_AT_LEAST",
                 off(plant_rules.INTEGRATED_OFF_OR_AT_LEAST, "INTEGRATED_OFF_OR_AT_LEAST")),
        "/* X(name) */",
        _x_macro("FP_INTEGRATED", [f"X({name})" for name in plant_rules.INTEGRATED]),
        *_limit("MODE_FREQUENCY_MAX", plant_rules.MODE_FREQUENCY_MAX),
        *_limit("DAMPING_RATE_MAX", plant_rules.DAMPING_RATE_MAX),
        *_limit("ACCELERATION_MAX", plant_rules.ACCELERATION_MAX),
    ])


def plant_header() -> str:
    """The text of ``plant_vars.h``."""
    vrs = value_references()
    for var in PLANT_VARIABLES:
        if var.type not in _C_TYPES:
            raise ValueError(f"variable {var.name}: type {var.type} has no C form here")
    out = [
        "/* plant_vars.h: FrictionPlant's variables, generated by",
        " * papwc.fmubuild.native_tables from papwc.model.plant and papwc.model.dynamics.",
        " * Do not edit: change the model layer and build again. */",
        "#ifndef FP_PLANT_VARS_H",
        "#define FP_PLANT_VARS_H",
        "",
        "#include <math.h>",
        "#include <stdint.h>",
        "",
        "#define FP_REAL 0",
        "#define FP_INTEGER 1",
        "#define FP_BOOLEAN 2",
        "",
        "/* X(name, vr, type, start, min, max, min_open, max_open) */",
        _x_macro("FP_PARAMETERS", [_entry(v, vrs[v.name]) for v in PLANT_PARAMETERS]),
        _x_macro("FP_INPUTS", [_entry(v, vrs[v.name]) for v in PLANT_INPUTS]),
        "/* X(name, vr, type) */",
        _x_macro("FP_OUTPUTS", [f"X({v.name}, {vrs[v.name]}, {_C_TYPES[v.type][0]})"
                                for v in PLANT_OUTPUTS]),
        "/* X(name, unit) */",
        _x_macro("FP_UNITS", [f'X({v.name}, "{v.unit}")' for v in PLANT_VARIABLES]),
        f"#define FP_N_VARIABLES {len(PLANT_VARIABLES)}",
        f"#define FP_N_PARAMETERS {len(PLANT_PARAMETERS)}",
        f"#define FP_N_INPUTS {len(PLANT_INPUTS)}",
        f"#define FP_N_OUTPUTS {len(PLANT_OUTPUTS)}",
        "",
        "typedef struct {",
        *(f"    {_C_TYPES[v.type][1]} {v.name};" for v in PLANT_PARAMETERS),
        "} FpParams;",
        "",
        "typedef struct {",
        *(f"    {_C_TYPES[v.type][1]} {v.name};" for v in PLANT_OUTPUTS),
        "} FpOutputs;",
        "",
        "/* The integrator's local error tolerances (absolute, relative) per state component",
        " * (papwc.model.dynamics.TOLERANCES; forces in units of max(f_s, f_c, 1 N)). */",
    ]
    for name, (atol, rtol) in TOLERANCES.items():
        out.append(f"#define FP_ATOL_{name.upper()} {atol!r}")
        out.append(f"#define FP_RTOL_{name.upper()} {rtol!r}")
    out += [
        f"#define FP_MAX_STEPS {int(MAX_STEPS)}",
        f"#define FP_MAX_EVENTS {int(MAX_EVENTS)}",
        f"#define FP_STREAM_STICTION {int(STICTION_STREAM)}",
        f"#define FP_STREAM_NOISE {int(NOISE_STREAM)}",
        f"#define FP_STREAM_MOTOR_NOISE {int(MOTOR_NOISE_STREAM)}",
        "",
        rule_tables(),
        "",
        "#endif",
        "",
    ]
    return "\n".join(out)


def write_plant_header(path: Path | str) -> None:
    """Write ``plant_vars.h`` to ``path`` (a file, or a folder to write it into)."""
    path = Path(path)
    if path.is_dir():
        path = path / HEADER_NAME
    path.write_text(plant_header(), encoding="utf-8")


# --- the controller ---------------------------------------------------------------------------
#
# ``controller_vars.h``: PulseController's variables and the constants of the controllers'
# parts, generated from the model layer and the Python controllers (their specification):
#
# - ``PC_SETTINGS(X)``: ``X(name, vr, type, start, min, max, min_open, max_open, inf_ok,
#   " unit", "what is allowed")`` per setting of CONTROLLER_SETTINGS but ``kind`` (the
#   String, value reference ``PC_VR_KIND``); ``PC_FMU_PARAMETERS(X)`` the same for ``T``,
#   ``kind_code`` and ``x_ref_offset``;
# - ``PC_SWITCHES(X)``: ``X(name, vr, setting, optional)`` per Boolean ``<setting>_given``
#   (optional 1: false selects the computed default; 0: false selects inf);
# - ``PC_INPUTS(X)``, ``PC_OUTPUTS(X)``: ``X(name, vr, type, start)``;
# - ``PC_KINDS(X)``: ``X(code, name, native)`` per entry of KIND_CODES, ``PC_KIND_<NAME>``;
# - the mode, outcome and reason codes, the constants of rest detection, trust region,
#   sequencer, PAPWC and PID, and ``PcSettings`` / ``PcOutputs``.

#: The controller kinds the C controller (fmu_src/PulseController/controller.c) implements:
#: the native PulseController.fmu offers these; the others are in the pythonfmu build.
NATIVE_KINDS: tuple[str, ...] = ("pwc", "papwc", "pid")

#: File name of the generated header of the controller.
CONTROLLER_HEADER_NAME = "controller_vars.h"

_PC_TYPES = {"Real": ("PC_REAL", "double"), "Integer": ("PC_INTEGER", "int32_t"),
             "Boolean": ("PC_BOOLEAN", "int32_t")}


@dataclass(frozen=True)
class ControllerTables:
    """Everything ``controller_vars.h`` is made of (read by :func:`controller_tables`).

    Attributes
    ----------
    variables : tuple of Variable
        Every variable of PulseController.fmu in value-reference order.
    settings : tuple of Variable
        The settings but ``kind`` (fields of ``PcSettings``).
    fmu_parameters : tuple of Variable
        The FMU's own parameters (``T``, ``kind_code``, ``x_ref_offset``).
    switches : tuple of (Variable, Variable)
        Each Boolean ``<name>_given`` and the setting it switches.
    inputs, outputs : tuple of Variable
        Inputs and outputs of the FMU.
    kinds : tuple of str
        KIND_CODES (kind ``n`` has code ``n + 1``).
    native_kinds : tuple of str
        The kinds the C controller implements.
    default_kind : str
        The kind of a new FMU (the String's start value).
    outcomes, reasons : tuple of str
        OUTCOMES and OUTCOME_REASONS.
    modes : dict of str to int
        Mode codes by name.
    constants : dict of str to float or int
        The constants of the controllers' parts, by their Python names.
    texts : dict of str to str
        Numbers as the messages write them (``:g``).
    """

    variables: tuple[Variable, ...]
    settings: tuple[Variable, ...]
    fmu_parameters: tuple[Variable, ...]
    switches: tuple[tuple[Variable, Variable], ...]
    inputs: tuple[Variable, ...]
    outputs: tuple[Variable, ...]
    kinds: tuple[str, ...]
    native_kinds: tuple[str, ...]
    default_kind: str
    outcomes: tuple[str, ...]
    reasons: tuple[str, ...]
    modes: dict[str, int]
    constants: dict[str, float | int]
    texts: dict[str, str]


def controller_tables() -> ControllerTables:
    """The tables and constants ``controller_vars.h`` is generated from, read in one place.

    From :mod:`papwc.model.controller_settings` (variables, kinds, outcomes, reasons, the
    rules' constants) and from the Python controllers, the specification of the C one:
    :mod:`papwc.controllers.rest`, ``trust``, ``sequencer``, ``base``, ``papwc``, ``pid``.
    """
    from papwc.controllers import base, pid, rest, sequencer, trust
    from papwc.controllers import papwc as papwc_law
    from papwc.controllers.interface import Mode
    from papwc.model import controller_settings as cs

    variables = cs.PULSE_CONTROLLER_VARIABLES
    by_name = {v.name: v for v in variables}
    settings = tuple(v for v in cs.CONTROLLER_SETTINGS if v.name != "kind")
    constants: dict[str, float | int] = {
        "MODE_PERIODS": cs.MODE_PERIODS, "DWELL_MAX": cs.DWELL_MAX,
        "F_MODE_MAX_T": cs.F_MODE_MAX_T, "STEP_RTOL": cs.STEP_RTOL,
        **{name: getattr(rest, name) for name in (
            "NOISE_WINDOW", "NOISE_DRIFT", "BAND_SIGMAS", "NOISE_DWELL", "NOISE_MEMORY",
            "RING_LEG", "RING_PERIODS", "RING_DWELL_MAX")},
        **{name: getattr(trust, name) for name in (
            "TRUST_GROWTH", "TRUST_GOOD", "TRUST_MIN", "TRUST_RING", "TRUST_FLEXIBLE")},
        **{name: getattr(sequencer, name) for name in (
            "X_LIMIT", "Z_DECIDE", "Z_ACT", "RUNAWAY_FACTOR", "RING_MARGIN",
            "E_BAND_FLEXIBLE", "STALL_BAND", "STALL_SAMPLES", "PRECISION_MIN")},
        **{name: getattr(papwc_law, name) for name in (
            "FAR_LESS", "FLOOR_RAISE", "FLOOR_RAISE_LEARN", "FLOOR_LEARN")},
        "REGRESSOR_PLANNED": papwc_law.REGRESSOR_PLANNED,
        "CUT_BY_ONE_UP_TO": base.CUT_BY_ONE_UP_TO,
        **{name: getattr(pid, name) for name in (
            "BANDWIDTH", "ZETA", "MODE_BANDWIDTH", "INTEGRAL", "SLOPE_NORM", "IN_POSITION_T",
            "IN_POSITION_T_MARGIN")},
    }
    texts = {"MODE_PERIODS": format(cs.MODE_PERIODS, "g"),
             "F_MODE_MAX_T": format(cs.F_MODE_MAX_T, "g")}
    return ControllerTables(
        variables=variables,
        settings=settings,
        fmu_parameters=(cs.SAMPLE_PERIOD, cs.KIND_CODE, cs.REFERENCE_OFFSET),
        switches=tuple((s, by_name[s.name.removesuffix("_given")])
                       for s in cs.CONTROLLER_SWITCHES),
        inputs=cs.CONTROLLER_INPUTS,
        outputs=cs.CONTROLLER_OUTPUTS,
        kinds=cs.KIND_CODES,
        native_kinds=NATIVE_KINDS,
        default_kind=by_name["kind"].default,
        outcomes=cs.OUTCOMES,
        reasons=cs.OUTCOME_REASONS,
        modes={name.upper(): code for code, name in Mode.NAMES.items()},
        constants=constants,
        texts=texts,
    )


def _pc_number(value: float | int | bool | None, var: Variable, infinity: str) -> str:
    return _c_number(value, var, infinity)


def _pc_entry(var: Variable, vr: int) -> str:
    """``X(name, vr, type, start, min, max, min_open, max_open, inf_ok, unit, allowed)``."""
    kind = _PC_TYPES[var.type][0]
    if var.type == "Boolean":
        lo = hi = "0"
        words = ""
    else:
        lo = _pc_number(var.min, var, "(-INFINITY)")
        hi = _pc_number(var.max, var, "INFINITY")
        words = var._range_message()
    return (f"X({var.name}, {vr}, {kind}, {_pc_number(var.fmi_start, var, '0')}, {lo}, {hi}, "
            f"{int(var.min_open)}, {int(var.max_open)}, {int(var.inf_ok)}, "
            f"{_c_string(var.unit_suffix)}, {_c_string(words)})")


def _c_constant(name: str, value: float | int) -> str:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"constant {name} = {value!r}: not a number")
    if isinstance(value, int):
        return f"#define PC_{name} {value}"
    return f"#define PC_{name} {float(value)!r}"


def controller_header(tables: ControllerTables | None = None) -> str:
    """The text of ``controller_vars.h`` (from :func:`controller_tables`)."""
    t = tables if tables is not None else controller_tables()
    vrs = {v.name: i for i, v in enumerate(t.variables)}
    for var in (*t.settings, *t.fmu_parameters, *t.inputs, *t.outputs):
        if var.type not in _PC_TYPES:
            raise ValueError(f"variable {var.name}: type {var.type} has no C form here")
    if vrs.get("kind") is None or t.variables[vrs["kind"]].type != "String":
        raise ValueError("the controller's kind must be the String variable 'kind'")
    trust0 = next(v for v in t.settings if v.name == "trust0")
    if not trust0.kinds or set(trust0.kinds) & set(t.native_kinds):
        raise ValueError("controller.c starts the trust region at 1 (trust0 read by none of "
                         f"{t.native_kinds}); trust0 is now read by {trust0.kinds or 'all'}")
    unknown = [k for k in t.native_kinds if k not in t.kinds]
    if unknown or t.default_kind not in t.native_kinds:
        raise ValueError(f"native kinds {t.native_kinds} (default {t.default_kind!r}) must be "
                         f"kinds of KIND_CODES {t.kinds}")
    kinds = [f"X({n}, {k}, {int(k in t.native_kinds)})" for n, k in enumerate(t.kinds, 1)]
    out_fields = [v for v in t.outputs if v.name != "u"]
    out = [
        "/* controller_vars.h: PulseController's variables and the constants of the",
        " * controllers' parts, generated by papwc.fmubuild.native_tables from",
        " * papwc.model.controller_settings and papwc.controllers (rest, trust, sequencer,",
        " * papwc, pid). Do not edit: change the Python and build again. */",
        "#ifndef PC_CONTROLLER_VARS_H",
        "#define PC_CONTROLLER_VARS_H",
        "",
        "#include <math.h>",
        "#include <stdint.h>",
        "",
        "#define PC_REAL 0",
        "#define PC_INTEGER 1",
        "#define PC_BOOLEAN 2",
        "",
        "/* X(name, vr, type, start, min, max, min_open, max_open, inf_ok, \" unit\", \"allowed\")",
        " * per setting but kind; a Boolean has no range (0, 0) and no words. */",
        _x_macro("PC_SETTINGS", [_pc_entry(v, vrs[v.name]) for v in t.settings]),
        _x_macro("PC_FMU_PARAMETERS", [_pc_entry(v, vrs[v.name]) for v in t.fmu_parameters]),
        "/* X(name, vr, setting, optional, start, \" unit\"): false selects the computed",
        " * default (optional 1) or inf (0) and the setting (start: its start value) is not",
        " * read. */",
        _x_macro("PC_SWITCHES", [f"X({s.name}, {vrs[s.name]}, {of.name}, {int(of.optional)}, "
                                 f"{_pc_number(of.fmi_start, of, '0')}, "
                                 f"{_c_string(of.unit_suffix)})" for s, of in t.switches]),
        "/* X(name, vr, type, start) */",
        _x_macro("PC_INPUTS", [f"X({v.name}, {vrs[v.name]}, {_PC_TYPES[v.type][0]}, "
                               f"{_pc_number(v.fmi_start, v, '0')})" for v in t.inputs]),
        _x_macro("PC_OUTPUTS", [f"X({v.name}, {vrs[v.name]}, {_PC_TYPES[v.type][0]}, "
                                f"{_pc_number(v.fmi_start, v, '0')})" for v in t.outputs]),
        "/* The fields of PcOutputs: every output but u. */",
        _x_macro("PC_OUTPUT_FIELDS", [f"X({v.name}, {vrs[v.name]}, {_PC_TYPES[v.type][0]}, "
                                      f"{_pc_number(v.fmi_start, v, '0')})" for v in out_fields]),
        f"#define PC_VR_KIND {vrs['kind']}",
        *(f"#define PC_VR_{v.name.upper()} {vrs[v.name]}" for v in (*t.inputs, *t.outputs)),
        f"#define PC_N_VARIABLES {len(t.variables)}",
        "",
        "/* X(code, name, native): the kinds by kind_code; native: the C controller has it. */",
        _x_macro("PC_KINDS", kinds),
        *(f"#define PC_KIND_{k.upper()} {n}" for n, k in enumerate(t.kinds, 1)),
        f"#define PC_N_KINDS {len(t.kinds)}",
        f"#define PC_KIND_DEFAULT PC_KIND_{t.default_kind.upper()}",
        "",
        *(f"#define PC_MODE_{name} {code}" for name, code in t.modes.items()),
        *(f"#define PC_OUTCOME_{name.upper()} {n}" for n, name in enumerate(t.outcomes)),
        *(f"#define PC_REASON_{(name or 'none').upper()} {n}"
          for n, name in enumerate(t.reasons)),
        f"#define PC_N_REASONS {len(t.reasons)}",
        "",
        "/* Constants of the controllers' parts (the Python modules' names). */",
        *(_c_constant(name, value) for name, value in t.constants.items()),
        *(f"#define PC_{name}_TEXT {_c_string(text)}" for name, text in t.texts.items()),
        "",
        "/* The settings of one controller: kind (a PC_KIND_ code), one field per setting",
        " * (SI units, named as in a scenario file), one per switch <setting>_given. */",
        "typedef struct {",
        "    int32_t kind;",
        *(f"    {_PC_TYPES[v.type][1]} {v.name};" for v in t.settings),
        *(f"    int32_t {s.name};" for s, _ in t.switches),
        "} PcSettings;",
        "",
        "/* The outputs of a controller but u (what pc_update returns). */",
        "typedef struct {",
        *(f"    {_PC_TYPES[v.type][1]} {v.name};" for v in out_fields),
        "} PcOutputs;",
        "",
        "#endif",
        "",
    ]
    return "\n".join(out)


def write_controller_header(path: Path | str) -> Path:
    """Write ``controller_vars.h`` to ``path`` (a file, or a folder to write it into)."""
    path = Path(path)
    if path.is_dir():
        path = path / CONTROLLER_HEADER_NAME
    path.write_text(controller_header(), encoding="utf-8")
    return path


#: The headers each native FMU is built with, generated here: model name -> file name ->
#: function that writes its text.
GENERATED_HEADERS = {
    "FrictionPlant": {HEADER_NAME: plant_header},
    "PulseController": {CONTROLLER_HEADER_NAME: controller_header},
}
