"""Pulses read off a trace, and the bound no pulse may exceed (no runaway).

A pulse starts at the sample where the controller's ``pulses`` count rises. Its
displacement is the change of the true position ``x`` from that sample to the
next rest the controller acted on: the start of the next pulse, the first
sample of coarse feedback after it, or else the end of the iteration. The error
before it is ``x_ref - x`` at its start.

Its bound is ``bound_m = max(1.5*abs(e) + q, quantum_m)``: ``q`` the encoder's count
(``x_resolution``) and ``quantum_m`` the table's quantum (:mod:`papwc.results.quantum`),
the move of one sample at the highest breakaway force the table's parameters allow
(``band_top_N``), from rest. Both depend on the table and the error only: nothing a
controller outputs enters the bound, so no controller can set its own. A pulse
*runs away* when its displacement exceeds the bound (``ratio = abs(d)/bound_m > 1``).

Which runaway the spec forbids outright depends on the error and on the pulse
(:func:`pulse_class`; the physics in docs/_incoming/43-the-bound.md): a one-sample pulse
near the breakaway force moves anything from zero to tens of micrometres depending on where
in its band the stiction was drawn, so a hard bound holds for it only from
:data:`FAR_M` of error; a *planned* pulse (two samples or more, or one sample above
``u_break_N``, the commanded height that breaks the table away at ``band_top_N``) has no
such excuse at any error from :data:`NEAR_M`.

:func:`pulse_ratio` gives, per iteration, the largest ratio of a pulse's
displacement to that bound (> 1: a runaway pulse).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from papwc.controllers import Mode
from papwc.master.trace import Trace
from papwc.model.plant import PLANT_DEFAULTS
from papwc.results.quantum import table_quantum

if TYPE_CHECKING:
    from papwc.master.native_plant import NativePlantLibrary

__all__ = ["FAR_M", "NEAR_M", "ROW_COLUMNS", "RUNAWAY_FACTOR", "Pulse", "PulseBound",
           "pulse_class", "pulse_ratio", "pulses_of"]

#: Factor on abs(e) of the bound.
RUNAWAY_FACTOR = 1.5
#: Error from which every pulse, of any width, must stay within its bound, m.
FAR_M = 5e-5
#: Error from which a planned pulse must stay within its bound, m (below: the last micrometre).
NEAR_M = 1e-6
#: Keys of :meth:`PulseBound.rows`, in order (SI units; see there).
ROW_COLUMNS = ("pulse", "t_s", "samples", "amplitude_N", "e_m", "d_m", "band_top_N",
               "u_break_N", "quantum_m", "bound_m", "ratio")


@dataclass(frozen=True)
class Pulse:
    """One pulse of a trace (SI units)."""

    #: Row of the trace where it starts.
    k: int
    #: Signed largest force of the pulse, N.
    amplitude: float
    #: Error x_ref - x at its start, m.
    e: float
    #: Displacement to the next rest, m.
    d: float
    #: Row of the trace where the displacement is read (the next rest).
    end: int
    #: Samples of non-zero force from its start (its width).
    samples: int


def pulses_of(trace: Trace) -> list[Pulse]:
    """The pulses of one iteration, in order."""
    cols = trace.columns
    n = len(trace)
    if n == 0:
        return []
    count, mode, x, u = cols["pulses"], cols["mode"], cols["x"], cols["u"]
    starts = [k for k in range(n) if count[k] > (count[k - 1] if k else 0)]
    out = []
    for i, k0 in enumerate(starts):
        k1 = starts[i + 1] if i + 1 < len(starts) else n - 1
        end = k1
        for k in range(k0 + 1, k1):
            if mode[k] == Mode.COARSE:
                end = k
                break
        forces = [f for f in u[k0:max(end, k0 + 1)] if f == f and f != 0.0]
        amp = max(forces, key=abs) if forces else 0.0
        width = 0
        while k0 + width < n and u[k0 + width] == u[k0 + width] and u[k0 + width] != 0.0:
            width += 1
        out.append(Pulse(k0, amp, trace.x_ref - x[k0], x[end] - x[k0], end, width))
    return out


class PulseBound:
    """The bound of the pulses of every trace on one table (see the module).

    Parameters
    ----------
    plant : mapping
        The run's plant parameters (scenario ``[plant]`` names; missing ones default).
    T : float
        Sample period, s.
    library : NativePlantLibrary, optional
        The C plant of the run's native FMU (:func:`papwc.master.native_plant.plant_library`):
        the quantum is computed on it instead of the model layer's Plant (the same numbers).
    """

    def __init__(self, plant: Mapping[str, Any], T: float,
                 library: NativePlantLibrary | None = None) -> None:
        p = {**PLANT_DEFAULTS, **plant}
        self.q = float(p["x_resolution"])
        self.T = float(T)
        self.quantum = table_quantum(p, self.T, library)

    def bound(self, e: float) -> float:
        """``max(1.5*abs(e) + q, quantum_m)`` for a pulse fired at the error ``e`` (m), m."""
        return max(RUNAWAY_FACTOR * abs(e) + self.q, self.quantum.move)

    def ratios(self, traces: Sequence[Trace]) -> list[float]:
        """Largest ratio of a pulse's displacement to its bound, per trace (0 without pulses)."""
        return [max((_divide(abs(p.d), self.bound(p.e)) for p in pulses_of(trace)),
                    default=0.0) for trace in traces]

    def rows(self, trace: Trace) -> list[dict[str, Any]]:
        """One row per pulse of a trace: where it starts, its width, height, error, bound, ratio.

        Keys (SI units): ``pulse`` (1, 2, ... in the iteration), ``t_s`` (its
        start), ``samples`` (of non-zero force from its start), ``amplitude_N``
        (signed largest force), ``e_m`` (error before it), ``d_m`` (signed
        displacement to the next rest), the table's ``band_top_N``, ``u_break_N`` and
        ``quantum_m`` (:class:`papwc.results.quantum.Quantum`), ``bound_m`` (the larger of
        ``1.5*abs(e) + q`` and ``quantum_m``) and ``ratio`` (``abs(d_m)/bound_m``; above 1
        the pulse ran away).
        """
        quantum = self.quantum
        out = []
        for i, p in enumerate(pulses_of(trace), 1):
            bound = self.bound(p.e)
            out.append(dict(zip(ROW_COLUMNS, (
                i, p.k * trace.T, p.samples, p.amplitude, p.e, p.d, quantum.band_top,
                quantum.u_break, quantum.move, bound, _divide(abs(p.d), bound)), strict=True)))
        return out


def _divide(d: float, bound: float) -> float:
    """d/bound, with 0/0 = 0 and d/0 = inf."""
    return d / bound if bound > 0.0 else (math.inf if d > 0.0 else 0.0)


def pulse_class(e: float, samples: int, amplitude: float, u_break: float) -> str:
    """Which part of the spec judges a pulse beyond its bound (see the module).

    Parameters
    ----------
    e : float
        Error before the pulse, m.
    samples : int
        Its width, samples.
    amplitude : float
        Its signed largest force, N.
    u_break : float
        The table's commanded one-sample height that breaks it away at the band top, N.

    Returns
    -------
    str
        ``"far"`` (abs(e) >= :data:`FAR_M`: hard, any width), ``"planned"`` (abs(e) >=
        :data:`NEAR_M`, two samples or more or one above ``u_break``: hard), ``"mid"``
        (a one-sample pulse at most ``u_break`` at :data:`NEAR_M` <= abs(e) < :data:`FAR_M`:
        a share) or ``"near"`` (abs(e) < :data:`NEAR_M`: a share).
    """
    if abs(e) >= FAR_M:
        return "far"
    if not abs(e) >= NEAR_M:
        return "near"
    if samples >= 2 or abs(amplitude) > u_break:
        return "planned"
    return "mid"


def pulse_ratio(traces: Sequence[Trace], plant: Mapping[str, Any], T: float,
                library: NativePlantLibrary | None = None) -> list[float]:
    """Per trace, the largest ratio of a pulse's displacement to its bound (see the module).

    ``library``: the C plant of the run's native FMU, on which the quantum is computed (see
    :class:`PulseBound`).
    """
    return PulseBound(plant, T, library).ratios(traces)
