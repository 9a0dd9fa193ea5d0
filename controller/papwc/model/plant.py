"""The friction plant's variables: parameters, input and outputs, with units and ranges.

Standard library only (bundled into FrictionPlant.fmu). FrictionPlant.fmu declares
exactly these variables; the in-process plant, scenario ``[plant]`` tables, the
SSP writer and the model description read them from here.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .variables import Constraint, Variable, by_name, problems

__all__ = [
    "INITIAL_STATE",
    "PLANT_CONSTRAINTS",
    "PLANT_DEFAULTS",
    "PLANT_INPUTS",
    "PLANT_OUTPUTS",
    "PLANT_PARAMETERS",
    "PLANT_VARIABLES",
    "SCENARIO_PLANT_FIELDS",
    "plant_problems",
]

#: Parameters of the plant (FMU parameters; SI units). Scenario files set all but
#: :data:`INITIAL_STATE`.
PLANT_PARAMETERS: tuple[Variable, ...] = (
    Variable("m", "Mass", "kg", 150.0, min=1e-6, max=1e9, nominal=100.0),
    Variable("f_c", "Coulomb (sliding) friction force", "N", 100.0, min=0.0, max=1e9,
             nominal=100.0),
    Variable("f_s", "Stiction (breakaway) force, >= f_c", "N", 130.0, min=0.0, max=1e9,
             nominal=100.0),
    Variable("c", "Viscous damping", "N.s/m", 700.0, min=0.0, max=1e9, nominal=100.0),
    Variable("x0", "Initial position", "m", 0.0, min=-1e6, max=1e6, nominal=1.0),
    Variable("v0", "Initial velocity", "m/s", 0.0, min=-1e6, max=1e6, nominal=1.0),
    Variable(
        "x_resolution", "Encoder resolution of x_meas (0 = ideal encoder)", "m", 0.0, min=0.0,
        max=1.0, nominal=1e-6,
    ),
)

#: Parameters that give the state at the start of a simulation (not scenario fields:
#: a maneuver starts at rest at 0).
INITIAL_STATE = ("x0", "v0")

#: Names of the ``[plant]`` fields of a scenario file.
SCENARIO_PLANT_FIELDS: tuple[str, ...] = tuple(
    v.name for v in PLANT_PARAMETERS if v.name not in INITIAL_STATE
)

#: Default value of every parameter.
PLANT_DEFAULTS: dict[str, Any] = {v.name: v.default for v in PLANT_PARAMETERS}

#: The input: force held constant over each communication step.
PLANT_INPUTS: tuple[Variable, ...] = (
    Variable(
        "u", "Force on the mass, held constant over each communication step", "N", 0.0,
        causality="input", nominal=100.0,
    ),
)

#: The outputs, at the end of the last communication step.
PLANT_OUTPUTS: tuple[Variable, ...] = (
    Variable("x", "Position at the end of the last step", "m", 0.0, causality="output",
             initial="calculated"),
    Variable("v", "Velocity at the end of the last step", "m/s", 0.0, causality="output",
             initial="calculated"),
    Variable(
        "x_meas", "Position read by the encoder: x rounded to x_resolution", "m", 0.0,
        causality="output", initial="calculated",
    ),
    Variable("stuck", "Mass at rest (v exactly 0)", "", True, causality="output",
             type="Boolean", initial="calculated"),
)

#: Every variable of FrictionPlant.fmu, in the order of its value references.
PLANT_VARIABLES: tuple[Variable, ...] = PLANT_PARAMETERS + PLANT_INPUTS + PLANT_OUTPUTS


def _f_s_at_least_f_c(values: Mapping[str, Any]) -> tuple[str, str] | None:
    f_c, f_s = values["f_c"], values["f_s"]
    if f_s < f_c:
        return "f_s", f"f_s = {f_s!r} N: must be >= f_c = {f_c!r} N"
    return None


#: Rules between plant parameters.
PLANT_CONSTRAINTS: tuple[Constraint, ...] = (Constraint(("f_c", "f_s"), _f_s_at_least_f_c),)

_BY_NAME = by_name(PLANT_PARAMETERS)


def plant_problems(values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """Every invalid plant parameter in ``values`` as ``(name, message)``.

    Names not in ``values`` are not checked; a name the plant does not have is
    reported with the list of parameters.
    """
    out = [
        (name, f"{name}: the plant has no such parameter; parameters: "
               + ", ".join(_BY_NAME))
        for name in values if name not in _BY_NAME
    ]
    return out + problems(PLANT_PARAMETERS, values, PLANT_CONSTRAINTS)
