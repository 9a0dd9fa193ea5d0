"""The friction plant's variables: parameters, input and outputs, with units and ranges.

Standard library only (bundled into FrictionPlant.fmu). FrictionPlant.fmu declares
exactly these variables; the in-process plant, scenario ``[plant]`` tables, the
SSP writer and the model description read them from here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .variables import Constraint, Variable, by_name, problems

__all__ = [
    "ACCELERATION_MAX",
    "DAMPING_RATE_MAX",
    "DEVIATION_CONSTRAINTS",
    "DEVIATION_PARAMETERS",
    "INTEGRATED",
    "INTEGRATED_OFF_OR_AT_LEAST",
    "INITIAL_STATE",
    "MODE_FREQUENCY_MAX",
    "OFF_OR_AT_LEAST",
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

#: Deviations of a real machine from Eq. (1), each absent at its default (the plant is then
#: exactly Eq. (1)); equations in fmu_src/FrictionPlant/readme.md and papwc.model.effects.
DEVIATION_PARAMETERS: tuple[Variable, ...] = (
    Variable("v_s", "Stribeck velocity of the sliding friction f_c + (f_s - f_c)*exp(-(|v|/v_s)"
             "^delta_s) (0 = no Stribeck effect)", "m/s", 0.0, min=0.0, max=10.0, nominal=1e-3),
    Variable("delta_s", "Exponent of the Stribeck curve", "1", 2.0, min=1.0, max=10.0,
             nominal=1.0),
    Variable("sigma_0", "LuGre bristle stiffness (0 = stick-slip model without pre-sliding)",
             "N/m", 0.0, min=0.0, max=1e12, nominal=1e7),
    Variable("sigma_1", "LuGre bristle damping", "N.s/m", 0.0, min=0.0, max=1e9, nominal=1e5),
    Variable("ripple", "Relative amplitude a of the friction factor 1 + a*sin(2*pi*x/"
             "ripple_period + ripple_phase) (0 = none)", "1", 0.0, min=0.0, max=1.0,
             max_open=True, nominal=0.1),
    Variable("ripple_period", "Spatial period of the friction ripple", "m", 1e-3, min=1e-4,
             max=1e3, nominal=1e-3),
    Variable("ripple_phase", "Phase of the friction ripple at x = 0", "rad", 0.0,
             min=-2.0 * math.pi, max=2.0 * math.pi, nominal=1.0),
    Variable("f_s_spread", "Relative spread of the breakaway force, redrawn uniformly in "
             "f_s*(1 +- f_s_spread) each time the mass sticks (0 = fixed f_s)", "1", 0.0,
             min=0.0, max=1.0, max_open=True, nominal=0.1),
    Variable("seed", "Seed of the random stiction draws and of the encoder noise", "", 0,
             type="Integer", min=0, max=2**31 - 1),
    Variable("tau_u", "Time constant of the first-order lag between u and the applied force "
             "(0 = none)", "s", 0.0, min=0.0, max=10.0, nominal=1e-3),
    Variable("m_d", "Motor mass driven by u and coupled to the table by k_t and c_t "
             "(0 = rigid drive)", "kg", 0.0, min=0.0, max=1e6, nominal=100.0),
    Variable("k_t", "Stiffness of the motor-table coupling", "N/m", 0.0, min=0.0, max=1e12,
             nominal=1e6),
    Variable("c_t", "Damping of the motor-table coupling", "N.s/m", 0.0, min=0.0, max=1e9,
             nominal=100.0),
    Variable("noise_std", "Standard deviation of the Gaussian encoder noise added to x before "
             "quantization", "m", 0.0, min=0.0, max=1.0, nominal=1e-7),
    Variable("x_d_resolution", "Resolution of the motor encoder x_d_meas (0 = ideal encoder)",
             "m", 0.0, min=0.0, max=1.0, nominal=1e-6),
    Variable("x_d_noise_std", "Standard deviation of the Gaussian motor-encoder noise added to "
             "x_d before quantization (its own random stream)", "m", 0.0, min=0.0, max=1.0,
             nominal=1e-7),
)
PLANT_PARAMETERS = PLANT_PARAMETERS + DEVIATION_PARAMETERS

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
    Variable("x_d", "Motor (drive) position at the end of the last step (x on a rigid drive)",
             "m", 0.0, causality="output", initial="calculated"),
    Variable(
        "x_d_meas", "Motor position read by the motor encoder: x_d plus its noise, rounded to "
        "x_d_resolution", "m", 0.0, causality="output", initial="calculated",
    ),
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


def _lowest_breakaway_at_least_f_c(values: Mapping[str, Any]) -> tuple[str, str] | None:
    f_c, f_s, spread = values["f_c"], values["f_s"], values["f_s_spread"]
    lowest = f_s * (1.0 - spread)
    if spread > 0.0 and lowest < f_c:
        return "f_s_spread", (f"f_s_spread = {spread!r}: the lowest breakaway force "
                              f"f_s*(1 - f_s_spread) = {lowest!r} N must be >= f_c = {f_c!r} N")
    return None


def _lugre_needs_sliding_friction(values: Mapping[str, Any]) -> tuple[str, str] | None:
    if values["sigma_0"] > 0.0 and not values["f_c"] > 0.0:
        return "sigma_0", (f"sigma_0 = {values['sigma_0']!r} N/m: the LuGre model needs "
                           f"f_c > 0 (its bristle equation divides by the sliding friction); "
                           f"f_c = {values['f_c']!r} N")
    return None


def _random_stiction_needs_sticking(values: Mapping[str, Any]) -> tuple[str, str] | None:
    if values["f_s_spread"] > 0.0 and values["sigma_0"] > 0.0:
        return "f_s_spread", (f"f_s_spread = {values['f_s_spread']!r}: random stiction redraws "
                              "the breakaway force each time the mass sticks, and with LuGre "
                              f"(sigma_0 = {values['sigma_0']!r} N/m > 0) it never sticks; "
                              "set f_s_spread or sigma_0 to 0")
    return None


def _flexible_drive_needs_a_spring(values: Mapping[str, Any]) -> tuple[str, str] | None:
    if values["m_d"] > 0.0 and not values["k_t"] > 0.0:
        return "k_t", (f"k_t = {values['k_t']!r} N/m: a flexible drive (m_d = "
                       f"{values['m_d']!r} kg > 0) needs a coupling stiffness k_t > 0")
    return None


#: Highest frequency of the LuGre pre-sliding mode and of the flexible mode, Hz: the
#: integrator resolves them, and a stiffer spring is a rigid one at the 10 ms of a step.
#: (At 1e4 Hz a 10 ms step of a flexible drive took 11500 integrator steps, over a second;
#: the shipped scenarios' modes are at most 200 Hz.)
MODE_FREQUENCY_MAX = 1e3


def _presliding_mode_resolvable(values: Mapping[str, Any]) -> tuple[str, str] | None:
    sigma_0, m = values["sigma_0"], values["m"]
    if sigma_0 > 0.0:
        f = math.sqrt(sigma_0 / m) / (2.0 * math.pi)
        if f > MODE_FREQUENCY_MAX:
            return "sigma_0", (f"sigma_0 = {sigma_0!r} N/m: the pre-sliding mode "
                               f"sqrt(sigma_0/m)/(2*pi) = {f:.6g} Hz (m = {m!r} kg) must be "
                               f"<= {MODE_FREQUENCY_MAX:g} Hz")
    return None


def _flexible_mode_resolvable(values: Mapping[str, Any]) -> tuple[str, str] | None:
    m, m_d, k_t = values["m"], values["m_d"], values["k_t"]
    if m_d > 0.0 and k_t > 0.0:
        f = math.sqrt(k_t * (1.0 / m + 1.0 / m_d)) / (2.0 * math.pi)
        if f > MODE_FREQUENCY_MAX:
            return "k_t", (f"k_t = {k_t!r} N/m: the flexible mode sqrt(k_t*(1/m + 1/m_d))/(2*pi) "
                           f"= {f:.6g} Hz (m = {m!r} kg, m_d = {m_d!r} kg) must be <= "
                           f"{MODE_FREQUENCY_MAX:g} Hz; a stiffer drive is rigid: m_d = 0")
    return None


#: Smallest value other than 0 of a parameter whose 0 means "none": below it the effect is
#: nil at the plant's steps while its arithmetic overflows or takes unbounded time
#: (x_resolution = 5e-324 overflowed x/x_resolution; tau_u = 5e-324 and v_s = 1e-12 with
#: delta_s = 10 made the integrator's step fall below 1e-18 s).
OFF_OR_AT_LEAST: dict[str, float] = {
    "x_resolution": 1e-12,  # m: a picometre encoder
    "v_s": 1e-6,  # m/s
    "tau_u": 1e-6,  # s
    "sigma_0": 1.0,  # N/m
    "sigma_1": 1e-6,  # N.s/m
    "ripple": 1e-6,  # 1
    "f_s_spread": 1e-9,  # 1
    "m_d": 1e-3,  # kg
    "noise_std": 1e-12,  # m
    "x_d_resolution": 1e-12,  # m
    "x_d_noise_std": 1e-12,  # m
    "c_t": 1e-6,  # N.s/m
}
#: The same for the friction and damping of Eq. (1) when the plant is integrated (with a
#: deviation of :data:`INTEGRATED`): a tiny friction force made the mass stop and break
#: away thousands of times in one step (Eq. (1) alone has a closed form, cheap for any).
INTEGRATED_OFF_OR_AT_LEAST: dict[str, float] = {"f_c": 1e-6, "f_s": 1e-6, "c": 1e-6}


def _off_or_at_least(name: str, low: float, integrated: bool = False) -> Constraint:
    unit = _BY_NAME_ALL[name].unit_suffix

    def check(values: Mapping[str, Any]) -> tuple[str, str] | None:
        value = values[name]
        which = _integrated(values) if integrated else ""
        if value != 0.0 and abs(value) < low and (which or not integrated):
            when = f" when the plant is integrated ({which} = {values[which]!r} > 0)" if (
                which) else ""
            return name, (f"{name} = {value!r}{unit}: must be 0 (none) or >= {low:g}{unit}"
                          f"{when} (a smaller one has no effect at the plant's steps, and "
                          "makes them overflow or take unbounded time)")
        return None

    return Constraint((name, *INTEGRATED) if integrated else (name,), check)


_BY_NAME_ALL = by_name(PLANT_PARAMETERS)

#: Deviations that have no closed form: with any of them the plant's state is integrated
#: (see papwc.model.dynamics), at a cost that the two rules below bound.
INTEGRATED = ("v_s", "sigma_0", "ripple", "tau_u", "m_d")

#: Largest viscous damping rate of the mass, c/m, 1/s (a time constant of 0.1 ms), with an
#: integrated deviation: beyond it the mass stopped and broke away again thousands of times
#: in one step.
DAMPING_RATE_MAX = 1e4
#: Largest acceleration the breakaway force gives the mass, f_s/m, m/s^2 (1000 g), with an
#: integrated deviation: beyond it a step of a tiny mass under a large force took seconds or
#: was refused.
ACCELERATION_MAX = 1e4


def _integrated(values: Mapping[str, Any]) -> str:
    """The first integrated deviation present ("" if none)."""
    return next((name for name in INTEGRATED if values[name] > 0.0), "")


def _damping_bounded(values: Mapping[str, Any]) -> tuple[str, str] | None:
    m, c, which = values["m"], values["c"], _integrated(values)
    if which and c / m > DAMPING_RATE_MAX:
        return "c", (f"c = {c!r} N.s/m: the damping rate c/m = {c / m:.6g} 1/s (m = {m!r} kg) "
                     f"must be <= {DAMPING_RATE_MAX:g} 1/s when the plant is integrated "
                     f"({which} = {values[which]!r} > 0)")
    m_d, c_t = values["m_d"], values["c_t"]
    if m_d > 0.0 and c_t * (1.0 / m + 1.0 / m_d) > DAMPING_RATE_MAX:
        rate = c_t * (1.0 / m + 1.0 / m_d)
        return "c_t", (f"c_t = {c_t!r} N.s/m: the coupling's damping rate c_t*(1/m + 1/m_d) = "
                       f"{rate:.6g} 1/s (m = {m!r} kg, m_d = {m_d!r} kg) must be <= "
                       f"{DAMPING_RATE_MAX:g} 1/s")
    return None


def _acceleration_bounded(values: Mapping[str, Any]) -> tuple[str, str] | None:
    m, f_s, which = values["m"], values["f_s"], _integrated(values)
    if which and f_s / m > ACCELERATION_MAX:
        return "m", (f"m = {m!r} kg: the breakaway force gives the mass f_s/m = "
                     f"{f_s / m:.6g} m/s^2 (f_s = {f_s!r} N); must be <= "
                     f"{ACCELERATION_MAX:g} m/s^2 when the plant is integrated ({which} = "
                     f"{values[which]!r} > 0)")
    return None


#: Rules between the deviation parameters and the others.
DEVIATION_CONSTRAINTS: tuple[Constraint, ...] = (
    *(_off_or_at_least(name, low) for name, low in OFF_OR_AT_LEAST.items()),
    *(_off_or_at_least(name, low, integrated=True)
      for name, low in INTEGRATED_OFF_OR_AT_LEAST.items()),
    Constraint(("m", "f_s", *INTEGRATED), _acceleration_bounded),
    Constraint(("m", "c", "c_t", *INTEGRATED), _damping_bounded),
    Constraint(("f_c", "f_s", "f_s_spread"), _lowest_breakaway_at_least_f_c),
    Constraint(("f_c", "sigma_0"), _lugre_needs_sliding_friction),
    Constraint(("f_s_spread", "sigma_0"), _random_stiction_needs_sticking),
    Constraint(("m_d", "k_t"), _flexible_drive_needs_a_spring),
    Constraint(("m", "sigma_0"), _presliding_mode_resolvable),
    Constraint(("m", "m_d", "k_t"), _flexible_mode_resolvable),
)
PLANT_CONSTRAINTS = PLANT_CONSTRAINTS + DEVIATION_CONSTRAINTS

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
