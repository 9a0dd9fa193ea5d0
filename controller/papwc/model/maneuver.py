"""The maneuver's settings: the ``[maneuver]`` table of a scenario file.

Standard library only. A maneuver is a rest-to-rest move from x = 0 to ``x_ref``,
sampled at period ``T``, repeated ``iterations`` times with what the controller
learned carried over.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .variables import Constraint, Variable, problems

__all__ = [
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
    Variable("x_ref", "Reference (target) position; the mass starts at rest at 0", "m", 0.01),
    Variable("T", "Sample period", "s", 0.01, min=0.0, min_open=True),
    Variable("duration", "Duration of one iteration", "s", 2.0, min=0.0, min_open=True),
    Variable("iterations", "Repetitions of the maneuver, estimates carried over", "", 10,
             type="Integer", min=1),
    Variable("timing", "When the force computed at t_k acts: over [t_k, t_k+1] (immediate) "
             "or one sample later (delayed, as a master stepping both side by side)", "",
             "immediate", type="String", choices=TIMINGS),
    Variable("noise_std", "Standard deviation of measurement noise added to x_meas", "m",
             0.0, min=0.0),
    Variable("noise_seed", "Seed of the measurement noise", "", 0, type="Integer"),
)


def _duration_at_least_T(values: Mapping[str, Any]) -> tuple[str, str] | None:
    if values["duration"] < values["T"]:
        return "duration", (f"duration = {values['duration']!r} s: must be >= T = "
                            f"{values['T']!r} s")
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
