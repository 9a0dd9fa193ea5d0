"""The maneuver's settings: the ``[maneuver]`` table of a scenario file.

Standard library only. A maneuver is a rest-to-rest move from x = 0 to ``x_ref``,
sampled at period ``T``, repeated ``iterations`` times with what the controller
learned carried over.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .variables import Constraint, Variable, problems

__all__ = [
    "LOG_SAMPLE_PERIOD",
    "MANEUVER_CONSTRAINTS",
    "MANEUVER_DEFAULTS",
    "MANEUVER_VARIABLES",
    "TIMINGS",
    "maneuver_problems",
]

#: Timing of the force relative to the sample it is computed from (see papwc.master).
TIMINGS: tuple[str, ...] = ("immediate", "delayed")

#: Fields of a ``[maneuver]`` table.
MANEUVER_VARIABLES: tuple[Variable, ...] = (
    Variable("x_ref", "Reference (target) position; the mass starts at rest at 0", "m", 0.01,
             min=-1e3, max=1e3),
    Variable("T", "Sample period", "s", 0.01, min=1e-9, max=1e3),
    Variable("duration", "Duration of one iteration, a whole number of samples T", "s", 2.0,
             min=0.0, min_open=True, max=1e9),
    Variable("iterations", "Repetitions of the maneuver, estimates carried over", "", 10,
             type="Integer", min=1, max=1_000_000),
    Variable("timing", "When the force computed at t_k acts: over [t_k, t_k+1] (immediate) "
             "or one sample later (delayed, as a master stepping both side by side)", "",
             "immediate", type="String", choices=TIMINGS),
    Variable("noise_std", "Standard deviation of measurement noise added to x_meas", "m",
             0.0, min=0.0, max=1.0),
    Variable("noise_seed", "Seed of the measurement noise", "", 0, type="Integer",
             min=-(2**63), max=2**63 - 1),
)

#: The sample period of a measured machine's log that ``papwc identify`` fits, and of the
#: excitation it designs (``--T``): within the range of ``T``, and that of a positioning
#: machine's controller (1 MHz to 10 Hz; the plant's dynamics, m/c = 0.2 s and a breakaway
#: within one sample, must be resolved). A longer one most likely is a time column in
#: milliseconds (a 10 ms period reads 10).
LOG_SAMPLE_PERIOD = Variable("h", "Sample period of a measured log (papwc identify)", "s",
                             0.01, min=1e-6, max=0.1)


def _duration_at_least_T(values: Mapping[str, Any]) -> tuple[str, str] | None:
    duration, T = values["duration"], values["T"]
    if duration < T:
        return "duration", f"duration = {duration!r} s: must be >= T = {T!r} s"
    n = duration / T
    whole = round(n)
    if abs(n - whole) > 1e-6 + 1e-12 * n:
        lower, upper = max(math.floor(n), 1), math.ceil(n)
        return "duration", (f"duration = {duration!r} s: must be a whole number of samples "
                            f"T = {T!r} s (it is {n:.6g} samples; {lower * T:.6g} s or "
                            f"{upper * T:.6g} s would be)")
    return None


#: Rules between maneuver fields.
MANEUVER_CONSTRAINTS: tuple[Constraint, ...] = (
    Constraint(("duration", "T"), _duration_at_least_T),
)

#: Default of every field.
MANEUVER_DEFAULTS: dict[str, Any] = {v.name: v.default for v in MANEUVER_VARIABLES}


def maneuver_problems(values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """Every invalid field of a maneuver as ``(name, message)``."""
    return problems(MANEUVER_VARIABLES, values, MANEUVER_CONSTRAINTS)
