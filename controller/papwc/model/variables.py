"""Metadata of parameters, settings, inputs and outputs: name, unit, default, range.

Standard library only (bundled into the FMUs). A :class:`Variable` says
everything the rest of the project needs to know about one quantity: the FMU
variable declarations, the model description's units and ranges, the SSP
writer, scenario validation and the master's in-process plant all read it, so
adding a parameter is one entry in a table of :mod:`papwc.model.plant`,
:mod:`papwc.model.maneuver` or :mod:`papwc.model.controller_settings`.

Validation messages have one form, ``"<name> = <value> <unit>: must ..."``,
e.g. ``"K_c = 2.5: must satisfy 0 < K_c < 2 (Eq. (6))"``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = [
    "Constraint",
    "Variable",
    "by_name",
    "describe_value",
    "problems",
    "switch_conflicts",
    "switch_variables",
    "switched_values",
]

#: FMI 2.0 types a variable can have.
TYPES = ("Real", "Integer", "Boolean", "String")
#: Causalities (FMI 2.0 names).
CAUSALITIES = ("parameter", "input", "output")


@dataclass(frozen=True)
class Variable:
    """One parameter, setting, input or output.

    Attributes
    ----------
    name : str
        Name in scenario files, FMU model descriptions and results.
    description : str
        One line: what it is (the range is added from ``min``/``max``).
    unit : str
        SI unit as written in the model description (``"1"``: dimensionless;
        ``""`` for Integer, Boolean and String variables).
    default : float, int, bool, str or None
        Default (start) value; ``None`` for an optional setting whose default
        is computed from others (``optional``).
    causality : str
        ``"parameter"``, ``"input"`` or ``"output"``.
    type : str
        ``"Real"``, ``"Integer"``, ``"Boolean"`` or ``"String"``.
    min, max : float or None
        Allowed range of a parameter (inclusive unless ``min_open``/``max_open``).
    min_open, max_open : bool
        Whether the bound itself is excluded.
    nominal : float or None
        Nominal magnitude (model description), where it helps a tool scale.
    inf_ok : bool
        ``+inf`` is allowed (e.g. no bound on the pulse width); in an FMU the
        Boolean :attr:`switch` ``<name>_given`` (false) selects it.
    optional : bool
        ``None`` is allowed and selects a computed default; in an FMU the
        Boolean :attr:`switch` ``<name>_given`` (false) selects it.
    fmi_default : float or None
        Start value in an FMU of a Real whose default (``None`` or ``inf``) its
        switch selects: a value in range that is not read while the switch is
        false (the computed default at the other settings' defaults, or ``max``).
    choices : tuple of str
        Allowed values of a String.
    note : str
        Appended to a range message, e.g. ``"(Eq. (6))"``.
    kinds : tuple of str
        Controller kinds the setting applies to (empty: all).
    attr : str
        Python attribute name where it differs from ``name`` (``lambda`` -> ``lam``).
    initial : str
        FMI ``initial`` of an output (``"exact"`` or ``"calculated"``: its
        value after initialization follows from the parameters).
    feedthrough : bool
        An output that depends on the inputs at the same communication point
        (FMI ``dependencies``); False: ``dependencies=""``.
    variability : str
        FMI variability where the default does not fit (parameters: ``fixed``;
        Real inputs and outputs: ``continuous``; others: ``discrete``), e.g.
        ``"discrete"`` for an output that changes only at communication points.
    """

    name: str
    description: str
    unit: str = "1"
    default: Any = 0.0
    causality: str = "parameter"
    type: str = "Real"
    min: float | None = None
    max: float | None = None
    min_open: bool = False
    max_open: bool = False
    nominal: float | None = None
    inf_ok: bool = False
    optional: bool = False
    fmi_default: float | None = None
    choices: tuple[str, ...] = ()
    note: str = ""
    kinds: tuple[str, ...] = ()
    attr: str = ""
    initial: str = ""
    feedthrough: bool = False
    variability: str = ""

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"variable {self.name}: type {self.type!r} not in {TYPES}")
        if self.causality not in CAUSALITIES:
            raise ValueError(f"variable {self.name}: causality {self.causality!r}")

    @property
    def fmi_variability(self) -> str:
        """FMI 2.0 variability of the variable."""
        if self.variability:
            return self.variability
        if self.causality == "parameter":
            return "fixed"
        return "continuous" if self.type == "Real" else "discrete"

    @property
    def switch(self) -> str:
        """Name of the FMU's Boolean ``<name>_given`` of a Real whose default it cannot
        hold (``None``: computed; ``inf``): true, the Real is read; false (its start), the
        default. Empty for the others."""
        return f"{self.name}_given" if self.optional or self.inf_ok else ""

    @property
    def switched_value(self) -> Any:
        """The value its :attr:`switch` selects: ``None`` (computed) or ``inf``."""
        return None if self.optional else math.inf

    @property
    def fmi_start(self) -> Any:
        """Start value in an FMU: the default, or :attr:`fmi_default` where a switch
        selects the default (``None`` or ``inf``, values a Real in range cannot hold)."""
        return self.fmi_default if self.switch else self.default

    @property
    def fmi_min(self) -> float | None:
        """``min`` in an FMU's model description: the lowest value the FMU accepts (an
        excluded bound moves to the next double, so a host's range check accepts only
        values the FMU accepts)."""
        if self.min is None or not self.min_open or self.type != "Real":
            return self.min
        return math.nextafter(float(self.min), math.inf)

    @property
    def fmi_max(self) -> float | None:
        """``max`` in an FMU's model description: the highest value the FMU accepts."""
        if self.max is None or not self.max_open or self.type != "Real":
            return self.max
        return math.nextafter(float(self.max), -math.inf)

    @property
    def attribute(self) -> str:
        """Python attribute name (``name`` unless it is a keyword)."""
        return self.attr or self.name

    @property
    def unit_suffix(self) -> str:
        """``" <unit>"`` for a value in messages, empty for dimensionless or unit-less."""
        return f" {self.unit}" if self.unit not in ("", "1") else ""

    def range_text(self) -> str:
        """The allowed range in words, e.g. ``"0 < K_c < 2"`` or ``">= 0 m"``."""
        lo, hi = self.min, self.max
        if self.type == "Integer":
            text = "a whole number"
            if lo is not None and hi is not None:
                return (f"{text} {_num(lo)} {'<' if self.min_open else '<='} {self.name} "
                        f"{'<' if self.max_open else '<='} {_num(hi)}")
            if lo is not None:
                text += f" {'>' if self.min_open else '>='} {_num(lo)}"
            if hi is not None:
                text += (" and" if lo is not None else "") + (
                    f" {'<' if self.max_open else '<='} {_num(hi)}")
            return text
        if lo is not None and hi is not None:
            return (
                f"{_num(lo)} {'<' if self.min_open else '<='} {self.name} "
                f"{'<' if self.max_open else '<='} {_num(hi)}{self.unit_suffix}"
            )
        if lo is not None:
            return f"{'>' if self.min_open else '>='} {_num(lo)}{self.unit_suffix}"
        if hi is not None:
            return f"{'<' if self.max_open else '<='} {_num(hi)}{self.unit_suffix}"
        return "any finite number"

    def allowed_text(self) -> str:
        """What values are allowed, in words (choices, true or false, or the range and its note)."""
        if self.choices:
            return ", ".join(repr(c) for c in self.choices)
        if self.type == "Boolean":
            return "true or false"
        if self.type == "String":
            return "a string"
        return f"{self.range_text()} {self.note}".rstrip()

    def check(self, value: Any) -> str | None:
        """What is wrong with ``value`` (the text after ``"must"``), or None if it is allowed."""
        if self.optional and value is None:
            return None
        if self.type == "String":
            if not isinstance(value, str):
                return "be a string"
            if self.choices and value not in self.choices:
                return "be one of " + ", ".join(repr(c) for c in self.choices)
            return None
        if self.type == "Boolean":
            return None if isinstance(value, bool) else "be true or false"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return "be a number"
        if self.type == "Integer" and not (math.isfinite(value) and float(value).is_integer()):
            return f"be {self.range_text()}"
        if math.isnan(value) or (math.isinf(value) and not (self.inf_ok and value > 0)):
            return "be a finite number" + ("" if not self.inf_ok else " or inf")
        if math.isinf(value):
            return None  # +inf where inf_ok: beyond every finite bound by design
        lo, hi = self.min, self.max
        if lo is not None and (value <= lo if self.min_open else value < lo):
            return self._range_message()
        if hi is not None and (value >= hi if self.max_open else value > hi):
            return self._range_message()
        return None

    def _range_message(self) -> str:
        text = self.range_text()
        verb = "satisfy" if self.min is not None and self.max is not None else "be"
        if self.type == "Integer":
            verb = "be"
        return f"{verb} {text}" + (f" {self.note}" if self.note else "")

    def message(self, value: Any, must: str) -> str:
        """``"<name> = <value> <unit>: must <must>"``."""
        return f"{self.name} = {describe_value(value)}{self._value_unit(value)}: must {must}"

    def _value_unit(self, value: Any) -> str:
        return self.unit_suffix if isinstance(value, (int, float)) and not isinstance(
            value, bool) else ""


@dataclass(frozen=True)
class Constraint:
    """A rule between several values; ``check(values)`` returns ``(name, message)`` or None.

    ``names`` are the variables it reads; it is checked only when each of them
    is valid on its own.
    """

    names: tuple[str, ...]
    check: Callable[[Mapping[str, Any]], tuple[str, str] | None]


#: Longest value quoted whole in a message, characters; a longer one is shortened to its
#: start and its length (a 5000-digit number or a megabyte of text in one line helps nobody).
MESSAGE_VALUE_CHARS = 60


def describe_value(value: Any) -> str:
    """A value as written in messages: ``repr`` (whole floats keep their ``.0``); a longer
    text or a larger integer than :data:`MESSAGE_VALUE_CHARS` shortened, e.g.
    ``'7777777777...' (5000 characters)``, ``1234567890123... (4300 digits)``."""
    if isinstance(value, int) and not isinstance(value, bool) and (
            value.bit_length() > 3.33 * MESSAGE_VALUE_CHARS):
        digits = int(math.log10(abs(value))) + 1
        if abs(value) < 10 ** (digits - 1):  # log10 rounded up at a power of ten
            digits -= 1
        head = abs(value) // 10 ** (digits - 20)
        return f"{'-' if value < 0 else ''}{head}... ({digits} digits)"
    text = repr(value)
    if isinstance(value, str) and len(text) > MESSAGE_VALUE_CHARS:
        return f"{value[:MESSAGE_VALUE_CHARS - 20]!r}... ({len(value)} characters)"
    return text


def _num(x: float) -> str:
    """A bound as written in messages: ``0``, ``2``, ``1e-06``, ``0.5``, ``1e+09``."""
    if isinstance(x, int) and not isinstance(x, bool) and abs(x) < 10**7:
        return str(x)
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if float(x).is_integer() and abs(x) < 1e5:
        return str(int(x))
    short = f"{float(x):g}"
    if float(short) == x:
        return short
    return str(x) if isinstance(x, int) else repr(float(x))


def switch_variables(variables: Iterable[Variable]) -> tuple[Variable, ...]:
    """The FMU's Boolean switches ``<name>_given`` of ``variables`` (one per variable with
    a :attr:`~Variable.switch`).

    A switch is false by default: the Real is then not read, and the setting takes
    its computed default (``None``) or no bound (``inf``); true, the Real is read.
    Every value a host's range check accepts for the Real is thus one the FMU
    accepts (a sentinel outside the range, as -1 for "computed", would let a host
    accept -0.5 too). Only a switch that is true need be set, so a host that
    cannot set a Boolean false (fmpy's SSP runner sets every Boolean it is given
    true) still runs a file that binds them.
    """
    out = []
    for var in variables:
        if not var.switch:
            continue
        default = ("it is computed (its default)" if var.optional
                   else "it is inf (no bound, its default)")
        out.append(Variable(var.switch, f"True: the parameter {var.name} is used; false: "
                            f"{default} and the parameter {var.name} is not read", "", False,
                            type="Boolean", kinds=var.kinds))
    return tuple(out)


def switched_values(variables: Iterable[Variable], values: Mapping[str, Any]) -> dict[str, Any]:
    """``values`` of an FMU's parameters as the model layer reads them.

    A variable whose switch is false takes its default (``None`` or ``inf``); the
    switches themselves are left out. Names not in ``variables`` are kept as they
    are.
    """
    variables = list(variables)
    switches = {v.switch for v in variables if v.switch}
    out = {name: value for name, value in values.items() if name not in switches}
    for var in variables:
        if var.switch and not values.get(var.switch) and var.name in out:
            out[var.name] = var.switched_value
    return out


def switch_conflicts(variables: Iterable[Variable],
                     values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(name, message)`` for each Real set away from its start while its switch is false.

    The Real is not read then, so a value set on it would be ignored: it is refused
    instead, with what to do.
    """
    out = []
    for var in variables:
        if not var.switch or values.get(var.switch) or var.name not in values:
            continue
        value = values[var.name]
        if value == var.fmi_start or value == var.switched_value:
            continue
        what = "computed" if var.optional else "inf (no bound)"
        out.append((var.name, f"{var.name} = {describe_value(value)}{var._value_unit(value)} "
                    f"is not read while {var.switch} = false ({var.name} is {what}): set "
                    f"{var.switch} = true to use it, or leave {var.name} at its start value "
                    f"{describe_value(var.fmi_start)}"))
    return out


def by_name(variables: Iterable[Variable]) -> dict[str, Variable]:
    """A table of variables indexed by name."""
    return {v.name: v for v in variables}


def problems(
    variables: Iterable[Variable],
    values: Mapping[str, Any],
    constraints: Iterable[Constraint] = (),
) -> list[tuple[str, str]]:
    """Every invalid value as ``(name, message)``; empty when all are allowed.

    Parameters
    ----------
    variables : iterable of Variable
        The table the values belong to; only names present in ``values`` are
        checked.
    values : mapping
        Name -> value.
    constraints : iterable of Constraint
        Rules between values, checked for values that are valid on their own.
    """
    out: list[tuple[str, str]] = []
    bad: set[str] = set()
    for var in variables:
        if var.name not in values:
            continue
        value = values[var.name]
        must = var.check(value)
        if must is not None:
            out.append((var.name, var.message(value, must)))
            bad.add(var.name)
    for rule in constraints:
        if all(n in values and n not in bad for n in rule.names):
            found = rule.check(values)
            if found is not None:
                out.append(found)
    return out
