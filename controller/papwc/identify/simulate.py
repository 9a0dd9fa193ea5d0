"""The moves of a log, each simulated from its rest on a candidate plant.

A *move* (:class:`Move`) is a pulse applied to the table at rest -- the samples ``k0`` to
``kp`` of one force -- and the table's motion after it up to the reading at which the next
force starts (which that force has not touched yet): the log's force and position over
``k0 .. k1 - 1``, with ``k1`` at most :data:`REST_KEEP` samples after the table came to
rest. Starting every move at its measured rest keeps the errors of one move from
accumulating into the next.

:class:`Simulator` replays the moves on a plant of :class:`papwc.model.dynamics.Plant`'s
parameters -- or, bit for bit the same and a hundred times faster, the C plant of the
native FrictionPlant (:func:`papwc.master.native_plant.own_plant_library`) -- each from rest
at its first position with the breakaway force it is given (the plant's state ``f_s_now``:
the draw of random stiction on that stick; the plant's own draws are off), and the lagging
actuator's force as the log's force leaves it there (:func:`lagged_force`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from papwc.identify import IdentifyError
from papwc.identify.log_file import Log
from papwc.identify.motion import Motion
from papwc.model.dynamics import STATE_FIELDS

__all__ = ["REST_KEEP", "Move", "Simulator", "lagged_force", "moves_from_rest",
           "plant_maker", "ripple_factor"]

#: Samples at rest kept at the end of a move (they pin where it stopped).
REST_KEEP = 3
#: The lagging force is taken as gone once below this fraction of the sliding friction (a
#: move's simulation stops once the table is stuck and the force that low).
_FORCE_GONE = 0.25


@dataclass(frozen=True)
class Move:
    """A pulse from rest and the motion after it (see the module).

    Attributes
    ----------
    k0, kp : int
        First and last sample of the pulse (one force).
    k1 : int
        End of the move (exclusive).
    x0 : float
        Position at rest before the pulse, m (the reading at ``k0``).
    """

    k0: int
    kp: int
    k1: int
    x0: float

    @property
    def width(self) -> int:
        """Samples of the pulse."""
        return self.kp - self.k0 + 1


def moves_from_rest(log: Log, motion: Motion) -> list[Move]:
    """Every move of ``log`` that starts from rest and ends at rest (see the module).

    A move seen first in the interval after a pulse (a lagging force that broke the table
    away late in the pulse) starts at that pulse.
    """
    u, moved, rest = log.u, motion.moved, motion.rest
    n = moved.size
    out = []
    for k0 in motion.breakaways:
        k0 = int(k0)
        if u[k0] == 0.0:
            # A lagging force (or a slow start) can break the table away so late in its
            # pulse that the move is seen only in the interval after it: the move starts
            # at that pulse, if the table was at rest before it.
            k = k0 - 1
            while k > 0 and u[k - 1] == u[k] != 0.0:
                k -= 1
            if k < 0 or u[k] == 0.0 or not rest[k]:
                continue
            k0 = k
        kp = k0
        while kp + 1 < n and u[kp + 1] == u[k0]:
            kp += 1
        kn = kp + 1
        while kn < n and u[kn] == 0.0:
            kn += 1
        ks = kp + 1
        while ks < kn and not rest[ks]:
            ks += 1
        # up to the reading at the next force (which that force has not touched yet)
        out.append(Move(k0, kp, min(kn + 1, ks + REST_KEEP), float(log.x[k0])))
    return out


def lagged_force(u: np.ndarray, h: float, tau_u: float) -> np.ndarray:
    """The lagging actuator's force at the end of each interval (its largest there), N."""
    if tau_u <= 0.0:
        return np.asarray(u, dtype=float)
    from scipy.signal import lfilter

    decay = math.exp(-h / tau_u)
    return lfilter([1.0 - decay], [1.0, -decay], np.asarray(u, dtype=float))


def ripple_factor(params: Mapping[str, Any], x: float | np.ndarray) -> float | np.ndarray:
    """The friction ripple's factor ``r(x)`` of ``params`` at ``x`` (m; 1 without ripple)."""
    a = float(params.get("ripple", 0.0))
    if a == 0.0:
        return np.ones_like(x) if isinstance(x, np.ndarray) else 1.0
    arg = 2.0 * math.pi * np.asarray(x) / float(params["ripple_period"]) + float(
        params.get("ripple_phase", 0.0))
    out = 1.0 + a * np.sin(arg)
    return out if isinstance(x, np.ndarray) else float(out)


def plant_maker(library: Any = None) -> Callable[[Mapping[str, Any]], Any]:
    """A maker of plants with :class:`papwc.model.dynamics.Plant`'s interface: the C plant of
    ``library`` (a :class:`papwc.master.native_plant.NativePlantLibrary`) or, without one,
    Plant itself (the same numbers)."""
    if library is not None:
        from papwc.master.native_plant import NativePlant

        return lambda params: NativePlant(library, params)
    from papwc.model.dynamics import Plant

    return Plant


#: The plant's parameters a simulation of the moves takes from a candidate (the others are
#: the defaults: no noise, an ideal encoder, no random stiction, no flexible drive).
SIMULATED = ("m", "f_c", "f_s", "c", "v_s", "delta_s", "tau_u", "ripple", "ripple_period",
             "ripple_phase")


class Simulator:
    """Simulates moves of a log on candidate plants (see the module).

    Parameters
    ----------
    log : Log
        The log.
    moves : sequence of Move
        The moves to simulate.
    maker : callable
        :func:`plant_maker`'s result.
    breakaway : sequence of float, optional
        Per move, the breakaway force it starts from (N, the ripple's factor included:
        the force that would just break the table away there); default: the candidate's
        ``f_s`` times the ripple's factor (or :attr:`draws`, where set).
    """

    def __init__(self, log: Log, moves: Sequence[Move], maker: Callable,
                 breakaway: Sequence[float] | None = None) -> None:
        if not moves:
            raise IdentifyError(f"{log.source}: no move from rest to rest to fit")
        self.log = log
        self.moves = list(moves)
        self.maker = maker
        self.breakaway = None if breakaway is None else [float(f) for f in breakaway]
        #: Per move, the stiction's draw it breaks away from (N, without the ripple's
        #: factor), in place of ``breakaway`` and the candidate's ``f_s`` (None: those).
        self.draws: np.ndarray | None = None
        self._u = [float(f) for f in log.u]
        self.index = np.concatenate([np.arange(mv.k0, mv.k1) for mv in self.moves])
        self.measured = log.x[self.index]
        self._sizes = np.array([mv.k1 - mv.k0 for mv in self.moves])
        #: Where each move's samples start in :attr:`index`.
        self.starts = np.concatenate([[0], np.cumsum(self._sizes)[:-1]]).astype(int)
        #: Samples less one per move (its offset is estimated): the residual's size.
        self.n = int(self.index.size - len(self.moves))

    def subset(self, moves: Sequence[Move]) -> Simulator:
        """A simulator of some of the moves (each keeping its breakaway force and draw)."""
        keep = [i for i, mv in enumerate(self.moves) if any(mv is m for m in moves)]
        out = Simulator(self.log, [self.moves[i] for i in keep], self.maker,
                        None if self.breakaway is None else [self.breakaway[i] for i in keep])
        if self.draws is not None:
            out.draws = self.draws[keep]
        return out

    def project(self, r: np.ndarray) -> np.ndarray:
        """``r`` less its mean over each move: each move's offset estimated by least squares.

        The rest a move starts from is known only through the encoder; an error in it
        would shift all of the move's samples alike (correlated errors). Removing each
        move's mean residual fits that offset, so the residual left is the move's shape.
        """
        means = np.add.reduceat(r, self.starts) / self._sizes
        return r - np.repeat(means, self._sizes)

    def _plant(self, params: Mapping[str, Any]) -> tuple[Any, dict[str, Any], np.ndarray]:
        p = {name: params[name] for name in SIMULATED if name in params}
        p["f_s"] = max(float(p.get("f_s", p["f_c"])), float(p["f_c"]))
        plant = self.maker(p)
        state: dict[str, Any] = dict.fromkeys(STATE_FIELDS, 0.0)
        state["stick_draws"] = state["noise_draws"] = 0
        force = lagged_force(self.log.u, self.log.h, float(p.get("tau_u", 0.0)))
        return plant, {"params": p, "state": state}, force

    def _start(self, plant: Any, ctx: dict[str, Any], force: np.ndarray, i: int) -> None:
        p, state = ctx["params"], ctx["state"]
        mv = self.moves[i]
        if self.draws is not None:
            f_now = self.draws[i]
        elif self.breakaway is not None:
            f_now = self.breakaway[i] / ripple_factor(p, mv.x0)
        else:
            f_now = p["f_s"]
        state.update(x=mv.x0, x_d=mv.x0, f_a=float(force[mv.k0 - 1]) if mv.k0 else 0.0,
                     f_s_now=max(float(f_now), p["f_c"]))
        plant.set_state(state)

    def positions(self, params: Mapping[str, Any]) -> np.ndarray:
        """Simulated positions at :attr:`index` (m)."""
        plant, ctx, force = self._plant(params)
        u, h = self._u, self.log.h
        gone = _FORCE_GONE * ctx["params"]["f_c"]
        out = np.empty(self.index.size)
        i = 0
        for j, mv in enumerate(self.moves):
            self._start(plant, ctx, force, j)
            out[i] = mv.x0
            i += 1
            still = False
            for k in range(mv.k0, mv.k1 - 1):
                if not still:
                    reason = plant.step(u[k], h)
                    if reason is not None:
                        raise IdentifyError(f"{self.log.source}: the plant refused to simulate "
                                            f"row {k + 1}: {reason}")
                    still = k > mv.kp and plant.v == 0.0 and abs(force[k]) < gone
                out[i] = plant.x
                i += 1
        return out

    def trajectories(self, params: Mapping[str, Any], sub: int
                     ) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """Per move: position (m) and velocity (m/s) at ``sub`` points per sample interval,
        from ``k0`` to ``k1 - 1``, and the breakaway force it started from (N, without the
        ripple's factor)."""
        plant, ctx, force = self._plant(params)
        u, h = self._u, self.log.h / sub
        out = []
        for j, mv in enumerate(self.moves):
            self._start(plant, ctx, force, j)
            count = (mv.k1 - mv.k0 - 1) * sub
            xs, vs = np.empty(count + 1), np.empty(count + 1)
            xs[0], vs[0] = mv.x0, 0.0
            for j in range(count):
                plant.step(u[mv.k0 + j // sub], h)
                xs[j + 1], vs[j + 1] = plant.x, plant.v
            out.append((xs, vs, float(ctx["state"]["f_s_now"])))
        return out
