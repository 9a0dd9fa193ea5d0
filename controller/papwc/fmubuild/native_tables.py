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
from pathlib import Path

from papwc.model import plant as plant_rules
from papwc.model.dynamics import MAX_EVENTS, MAX_STEPS, TOLERANCES
from papwc.model.effects.encoder import MOTOR_STREAM as MOTOR_NOISE_STREAM
from papwc.model.effects.encoder import STREAM as NOISE_STREAM
from papwc.model.effects.stiction import STREAM as STICTION_STREAM
from papwc.model.plant import PLANT_INPUTS, PLANT_OUTPUTS, PLANT_PARAMETERS, PLANT_VARIABLES
from papwc.model.variables import Variable

__all__ = ["HEADER_NAME", "plant_header", "rule_tables", "value_references",
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
