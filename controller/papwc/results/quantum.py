"""The table's quantum: the move of one sample at the highest breakaway its parameters allow.

A controller that does not know where in its stiction band the breakaway force of
the next pulse is drawn must fire a one-sample pulse at the top of that band to be sure
the table moves. The *quantum* of a table is the move of that pulse from rest when the
breakaway force is at the top of the band: the smallest move a one-sample pulse that is
sure to break the table away can make. It depends on the table's parameters and the
sample period only, never on what a controller outputs, so the no-runaway bound built
on it (:mod:`papwc.results.pulses`) is one no controller can set.

:func:`table_quantum` computes it from the model layer (:class:`papwc.model.dynamics.Plant`,
or the C plant of a native FrictionPlant.fmu, bit for bit the same):

``band_top``
    The highest breakaway force the parameters allow, N: the top of the stiction band
    ``f_s*(1 + f_s_spread)`` (:mod:`papwc.model.effects.stiction`) times the ripple's
    largest factor ``1 + ripple`` (:mod:`papwc.model.effects.ripple`: the breakaway
    force is ``r(x)*f_s``, Plant._breakaway). With LuGre (``sigma_0 > 0``, which excludes
    random stiction) the bristles hold at most the steady friction at rest ``g(0)``
    (:mod:`papwc.model.effects.lugre`): ``f_s`` with a Stribeck curve, ``f_c`` without,
    times ``1 + ripple``.
``u_break``
    The commanded height of one sample that just breaks the table away at ``band_top``,
    N. Without lag or flexible drive it is ``band_top``. With an actuator lag the applied
    force at the end of the sample is ``u*(1 - exp(-T/tau_u))`` and falls after it, so
    ``u_break = band_top/(1 - exp(-T/tau_u))``. With a flexible drive the force on the
    held table is the coupling's, which goes on ringing after the sample: ``u_break`` is
    found by bisection on the plant (the drive at rest, the table held at ``band_top``;
    with LuGre on its stick-slip twin, the bristles' micrometres of pre-sliding apart).
``move``
    The quantum, m: ``|x|`` at rest after one sample at ``u_break`` (the lowest float
    that breaks the table away) and zero force after it, from rest at ``x = 0`` with the
    ripple's peak there, the breakaway drawn at the top of the band (and kept there at
    later stops), on the table's true parameters otherwise (Stribeck, lag, LuGre, the
    flexible drive). Read when the table is at rest and nothing can move it again: stuck
    with the lag's force and the drive's energy too small to break it away, or with LuGre
    (never stuck) when a sample moved it less than :data:`LUGRE_REST_M`; at most
    :data:`COAST_MAX` s.

On Eq. (1) (Coulomb and viscous friction) without lag the quantum is Eq. (20) with the
stiction at the top of the band: Eq. (3) at ``f_p = band_top``, ``t_p = T``
(:func:`papwc.model.pulse.pulse_displacement`). With a Stribeck curve the friction at rest
equals the breakaway force, so the move grows from zero with the excess over it and the
quantum is a fraction of a nanometre: the bound is then ``1.5*abs(e) + q`` alone.

Computed once per table and period: :func:`table_quantum` keeps the results by the
parameters it depends on (not the seeds, the encoders or the ripple's phase).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from papwc.model.plant import PLANT_DEFAULTS

if TYPE_CHECKING:
    from papwc.master.native_plant import NativePlantLibrary

__all__ = ["COAST_MAX", "LUGRE_REST_M", "QUANTUM_PARAMETERS", "Quantum", "band_top",
           "move_from_rest", "table_quantum"]

#: Longest time the move of the quantum's pulse is followed, s.
COAST_MAX = 2.0
#: With LuGre (a mass that never sticks), the table is at rest once a sample moves it less, m.
LUGRE_REST_M = 1e-12
#: The parameters the quantum depends on (the seeds, encoders and ripple phase do not enter).
QUANTUM_PARAMETERS = ("m", "f_c", "f_s", "c", "v_s", "delta_s", "sigma_0", "sigma_1",
                      "ripple", "ripple_period", "f_s_spread", "tau_u", "m_d", "k_t", "c_t")
#: Doublings of the band top tried for a flexible drive's breaking height.
_DOUBLINGS = 40
#: Results kept by :func:`table_quantum`, by parameters and period (oldest dropped first).
_CACHE_SIZE = 4096
_CACHE: dict[tuple, Quantum] = {}


@dataclass(frozen=True)
class Quantum:
    """The table's quantum (SI units; see the module)."""

    #: Highest breakaway force the parameters allow, N.
    band_top: float
    #: Commanded one-sample height that just breaks the table away at band_top, N.
    u_break: float
    #: Move of that pulse from rest to rest, m.
    move: float


def band_top(params: Mapping[str, Any]) -> float:
    """The highest breakaway force the plant parameters allow, N (see the module)."""
    p = {**PLANT_DEFAULTS, **params}
    return (1.0 + float(p["ripple"])) * _level(p)


def _level(p: Mapping[str, Any]) -> float:
    """The breakaway force at the top of the band before the ripple's factor, N."""
    if p["sigma_0"] > 0.0:
        return float(p["f_s"] if p["v_s"] > 0.0 else p["f_c"])
    return float(p["f_s"]) * (1.0 + float(p["f_s_spread"]))


def table_quantum(params: Mapping[str, Any], T: float,
                  library: NativePlantLibrary | None = None) -> Quantum:
    """The quantum of the plant ``params`` at sample period ``T`` (s), computed once.

    Parameters
    ----------
    params : mapping
        Plant parameters (scenario ``[plant]`` names; missing ones default).
    T : float
        Sample period, s.
    library : NativePlantLibrary, optional
        The C plant of a native FrictionPlant.fmu, stepped instead of Plant (the same
        numbers, faster).
    """
    p = {**PLANT_DEFAULTS, **params}
    key = (float(T), *(float(p[name]) for name in QUANTUM_PARAMETERS))
    found = _CACHE.get(key)
    if found is None:
        found = _compute(p, float(T), library)
        if len(_CACHE) >= _CACHE_SIZE:
            del _CACHE[next(iter(_CACHE))]
        _CACHE[key] = found
    return found


def _maker(library: NativePlantLibrary | None) -> Callable[[Mapping[str, Any]], Any]:
    if library is not None:
        from papwc.master.native_plant import NativePlant

        return lambda values: NativePlant(library, values)
    from papwc.model.dynamics import Plant

    return Plant


def _table(p: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters of the quantum's table: at rest at 0 on the ripple's peak, the breakaway
    force at the top of the band and kept there, no encoder noise."""
    level = _level(p)
    table = {**p, "x0": 0.0, "v0": 0.0, "ripple_phase": 0.5 * math.pi, "f_s_spread": 0.0,
             "noise_std": 0.0, "x_d_noise_std": 0.0, "seed": 0}
    if p["sigma_0"] > 0.0:
        if p["v_s"] > 0.0:
            table["f_s"] = level
    else:
        table["f_s"] = level
    return table


def _compute(p: Mapping[str, Any], T: float, library: NativePlantLibrary | None) -> Quantum:
    top = band_top(p)
    make = _maker(library)
    table = _table(p)
    held = {**table, "sigma_0": 0.0, "sigma_1": 0.0, "f_s": _level(p)}
    tau = float(p["tau_u"])
    if p["m_d"] > 0.0:
        u = _bisect_break(make, held, T, top)
    elif tau > 0.0:
        u = top / -math.expm1(-T / tau)
    else:
        u = top
    u = _lowest_breaking(make, held, T, u)
    return Quantum(top, u, _move(make, table, T, u))


def _breaks(make: Callable, held: Mapping[str, Any], T: float, u: float, samples: int) -> bool:
    """Whether one sample at ``u`` (N), then zero force, moves the held table within
    ``samples`` samples.

    A height whose step the plant refuses counts as not breaking it away: one an ulp above
    the threshold can break the table away at the very end of the sample and leave it
    chattering between stick and slip (more than the plant's events in the next step).
    """
    plant = make(held)
    for k in range(samples):
        if plant.step(u if k == 0 else 0.0, T) is not None:
            return False
        if plant.v != 0.0 or plant.x != 0.0:
            return True
    return False


def _samples_to_break(held: Mapping[str, Any], T: float) -> int:
    """Samples after which a one-sample pulse's force on the held table no longer grows:
    two periods of the held drive's mode and five lag time constants, at least two samples
    and at most :data:`COAST_MAX`."""
    span = 5.0 * float(held["tau_u"])
    if held["m_d"] > 0.0:
        span += 2.0 * 2.0 * math.pi * math.sqrt(held["m_d"] / held["k_t"])
    return max(2, min(math.ceil(span / T) + 2, round(COAST_MAX / T)))


def _bisect_break(make: Callable, held: Mapping[str, Any], T: float, top: float) -> float:
    """The lowest one-sample height (N) that breaks the held table away, by bisection to a
    relative 1e-12 (a flexible drive: its coupling keeps ringing after the sample)."""
    n = _samples_to_break(held, T)
    lo, hi = 0.0, top
    for _ in range(_DOUBLINGS):
        if _breaks(make, held, T, hi, n):
            break
        lo, hi = hi, 2.0 * hi
    else:
        raise ValueError(f"no one-sample height up to 2**{_DOUBLINGS} times the band top "
                         f"({top!r} N) breaks the quantum's table away within "
                         f"{n * T:g} s")
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        if _breaks(make, held, T, mid, n):
            hi = mid
        else:
            lo = mid
    return hi


def _lowest_breaking(make: Callable, held: Mapping[str, Any], T: float, u: float) -> float:
    """The lowest float at or above ``u`` (within a few ulps, found by growing steps) that
    breaks the held table away (``u`` is its threshold computed in closed form or by
    bisection)."""
    n = _samples_to_break(held, T)
    step = math.ulp(u)
    for _ in range(64):
        if _breaks(make, held, T, u, n):
            return u
        u += step
        step *= 2.0
    raise ValueError(f"the quantum's table is not broken away at {u!r} N")


def move_from_rest(table: Mapping[str, Any], T: float, u: float,
                   library: NativePlantLibrary | None = None) -> float:
    """abs(x) at rest after one sample at ``u`` (N), then zero force, from rest at its x0 on
    the plant ``table`` as given (its breakaway force, ripple phase, lag, drive), m.

    At rest as for the quantum (see the module), after at most :data:`COAST_MAX` s.
    """
    p = {**PLANT_DEFAULTS, **table}
    return _move(_maker(library), p, float(T), float(u))


def _move(make: Callable, table: Mapping[str, Any], T: float, u: float) -> float:
    """|x - x0| at rest after one sample at ``u`` (N) from rest (see the module), m."""
    plant = make(table)
    x0 = plant.x
    lugre = table["sigma_0"] > 0.0
    x_before = x0
    for k in range(max(1, round(COAST_MAX / T))):
        why = plant.step(u if k == 0 else 0.0, T)
        if why is not None:
            raise ValueError(f"the quantum's table refused the step after {k * T:g} s of a "
                             f"one-sample pulse of {u!r} N: {why}")
        x = plant.x
        if k > 0 and (abs(x - x_before) <= LUGRE_REST_M if lugre else _held(plant, table)):
            break
        x_before = x
    return abs(plant.x - x0)


def _held(plant: Any, table: Mapping[str, Any]) -> bool:
    """Whether a stick-slip table is stuck and neither the lag's force nor the drive's energy
    can break it away again."""
    if plant.v != 0.0:
        return False
    state = plant.state()
    limit = plant._breakaway(plant.x)
    # a decaying lag force on a rigid table only falls; through a spring it overshoots (< 2x)
    push = abs(state["f_a"]) if table["tau_u"] > 0.0 else 0.0
    if table["m_d"] > 0.0:
        push *= 2.0
        k_t, m_d, c_t = table["k_t"], table["m_d"], table["c_t"]
        energy = (0.5 * k_t * (state["x_d"] - plant.x) ** 2 + 0.5 * m_d * state["v_d"] ** 2)
        push += math.sqrt(2.0 * k_t * energy) + c_t * math.sqrt(2.0 * energy / m_d)
    return push < limit
