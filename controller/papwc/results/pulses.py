"""Pulses read off a trace, and the bound no pulse may exceed (no runaway).

A pulse starts at the sample where the controller's ``pulses`` count rises. Its
displacement is the change of the true position ``x`` from that sample to the
next rest the controller acted on: the start of the next pulse, the first
sample of coarse feedback after it, or else the end of the iteration. The error
before it is ``x_ref - x`` at its start.

A pulse *runs away* when its displacement exceeds both ``1.5*|e| + q`` (``q``
the encoder's count) and the smallest pulse the controller can make: one sample
at its lowest amplitude -- the controller's output ``f_low`` when the pulse
starts (PWC: f_p_max, so d_min of Eq. (19); PAPWC: its amplitude floor; exact:
its ``f_floor``), or the pulse's own height if lower -- displaced on the plant
of the run itself, in the state the plant was in at the pulse's start (the
model layer's :class:`papwc.model.dynamics.Plant` replayed with the trace's
forces), over the same samples, so that a deviation which makes every pulse
longer (or a drive still ringing from the last one) does not count against the
controller. The height is at least the breakaway force in effect then (random
stiction draws it anew at every stop; ripple makes it depend on x). A run on a native
FrictionPlant.fmu is replayed on that FMU's own C plant, called in process
(:mod:`papwc.master.native_plant`; bit for bit the model layer's, in microseconds a step
instead of milliseconds with a deviation).

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

if TYPE_CHECKING:
    from papwc.master.native_plant import NativePlantLibrary

__all__ = ["ROW_COLUMNS", "Pulse", "PulseBound", "pulse_ratio", "pulses_of"]

#: Factor on abs(e) of the bound.
RUNAWAY_FACTOR = 1.5
#: Keys of :meth:`PulseBound.rows`, in order (SI units; see there).
ROW_COLUMNS = ("pulse", "t_s", "samples", "amplitude_N", "e_m", "d_m", "smallest_m", "bound_m",
               "ratio")
#: Longest coast simulated for the smallest pulse, s.
_COAST_MAX = 2.0


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
    """The smallest pulse a controller can make on the plant of a run, by simulation.

    The plant of the run (:class:`papwc.model.dynamics.Plant` with the run's
    parameters) is replayed with the forces of the trace, so that at every
    pulse its full state is known (a flexible drive still ringing, the
    breakaway force drawn, the lag's force); from that state the smallest pulse
    -- one sample at the lowest amplitude -- is simulated over the same samples
    as the pulse's span.

    Parameters
    ----------
    plant : mapping
        The run's plant parameters (scenario ``[plant]`` names; missing ones default).
    T : float
        Sample period, s.
    library : NativePlantLibrary, optional
        The C plant of the run's native FMU (:func:`papwc.master.native_plant.plant_library`):
        the replay steps it instead of the model layer's Plant (the same numbers).
    """

    def __init__(self, plant: Mapping[str, Any], T: float,
                 library: NativePlantLibrary | None = None) -> None:
        p = {**PLANT_DEFAULTS, **plant}
        self.q = float(p["x_resolution"])
        self.T = float(T)
        self.params = dict(p)
        self.library = library

    def _plant(self):
        if self.library is not None:
            from papwc.master.native_plant import NativePlant

            return NativePlant(self.library, self.params)
        from papwc.model.dynamics import Plant

        return Plant(self.params)

    def ratios(self, traces: Sequence[Trace]) -> list[float]:
        """Largest ratio of a pulse's displacement to its bound, per trace (0 without pulses).

        ``traces`` are iterations of one controller, each from the plant's
        initial state. The smallest pulse is simulated only for a pulse beyond
        ``1.5*|e| + q`` that could raise the largest ratio.
        """
        out = []
        for trace in traces:
            worst = 0.0
            check = _Check(self, trace)
            for p in pulses_of(trace):
                ratio = check.cheap_ratio(p)
                if ratio > 1.0 and ratio > worst:
                    ratio = check.ratio(p)
                worst = max(worst, ratio)
            out.append(worst)
        return out

    def rows(self, trace: Trace) -> list[dict[str, Any]]:
        """One row per pulse of a trace: where it starts, its width, height, error, bound, ratio.

        Keys (SI units): ``pulse`` (1, 2, ... in the iteration), ``t_s`` (its
        start), ``samples`` (of non-zero force from its start), ``amplitude_N``
        (signed largest force), ``e_m`` (error before it), ``d_m`` (signed
        displacement to the next rest), ``smallest_m`` (the smallest pulse from
        the plant's state then, see the class), ``bound_m`` (the larger of
        ``1.5*|e| + q`` and ``smallest_m``) and ``ratio`` (``|d_m|/bound_m``;
        above 1 the pulse ran away).
        """
        check = _Check(self, trace)
        out = []
        for i, p in enumerate(pulses_of(trace), 1):
            small = check.smallest(p)
            bound = max(check.cheap_bound(p), small)
            out.append(dict(zip(ROW_COLUMNS, (
                i, p.k * trace.T, p.samples, p.amplitude, p.e, p.d, small, bound,
                _divide(abs(p.d), bound)), strict=True)))
        return out


def _divide(d: float, bound: float) -> float:
    """d/bound, with 0/0 = 0 and d/0 = inf."""
    return d / bound if bound > 0.0 else (math.inf if d > 0.0 else 0.0)


class _Check:
    """The bound of the pulses of one trace; the plant is replayed only when needed."""

    def __init__(self, bound: PulseBound, trace: Trace) -> None:
        self.bound = bound
        self.trace = trace
        self.lows = trace.columns.get("f_low")
        self.replay: _Replay | None = None

    def cheap_bound(self, p: Pulse) -> float:
        """1.5*abs(e) + q, m."""
        return RUNAWAY_FACTOR * abs(p.e) + self.bound.q

    def cheap_ratio(self, p: Pulse) -> float:
        """abs(d) / (1.5*abs(e) + q)."""
        return _divide(abs(p.d), self.cheap_bound(p))

    def smallest(self, p: Pulse) -> float:
        """Absolute displacement of the smallest pulse from the state at p's start (0: none)."""
        height = abs(p.amplitude)
        f_low = height if self.lows is None else min(abs(self.lows[p.k]), height)
        if not f_low > 0.0:
            return 0.0
        if self.replay is None:
            self.replay = _Replay(self.bound._plant, self.trace)
        return self.replay.smallest(p.k, p.end, math.copysign(f_low, p.amplitude))

    def ratio(self, p: Pulse) -> float:
        """abs(d) / max(1.5*abs(e) + q, the smallest pulse)."""
        return _divide(abs(p.d), max(self.cheap_bound(p), self.smallest(p)))


class _Replay:
    """The run's plant driven with a trace's forces, state kept per row on demand."""

    def __init__(self, make_plant, trace: Trace) -> None:
        self.make_plant = make_plant
        self.plant = make_plant()
        self.u = trace.columns["u"]
        self.T = trace.T
        self.k = 0

    def state_at(self, k: int) -> dict:
        """The plant's state at row k (rows are replayed forward only)."""
        plant = self.plant
        while self.k < k:
            u = self.u[self.k]
            if plant.step(u if u == u else 0.0, self.T) is not None:
                raise ValueError("the replay of the trace was refused by the plant")
            self.k += 1
        return plant.state()

    def smallest(self, k0: int, end: int, f: float) -> float:
        """Absolute displacement of one sample at f (N) from row k0's state, read at row ``end``.

        The height is at least the breakaway force in effect there (random
        stiction draws it anew at every stop; ripple makes it depend on x).
        """
        state = self.state_at(k0)
        probe = self.make_plant()
        probe.set_state(state)
        x0 = probe.x
        T = self.T
        f_move = math.copysign(max(abs(f), probe._breakaway(x0) * (1.0 + 1e-9)), f)
        if probe.step(f_move, T) is not None:
            return math.inf
        for _ in range(max(end - k0 - 1, 0)):
            if probe.step(0.0, T) is not None:
                return math.inf
        return abs(probe.x - x0)


def pulse_ratio(traces: Sequence[Trace], plant: Mapping[str, Any], T: float,
                library: NativePlantLibrary | None = None) -> list[float]:
    """Per trace, the largest ratio of a pulse's displacement to its bound (see the module).

    ``library``: the C plant of the run's native FMU, replayed instead of Plant (see
    :class:`PulseBound`).
    """
    return PulseBound(plant, T, library).ratios(traces)
