"""One sample of force on a stuck stick–slip table, for many candidate tables at once.

The ceiling study's learning rows simulate each candidate table with the model layer's plant
(:class:`papwc.model.dynamics.Plant`), a Rosenbrock integrator in plain Python: 0.6-2 s of
processor time a pulse over 99 candidates, far more than the 10 ms a sample gives a
controller. :func:`one_pulse` is the same physics reduced to what one pulse needs,
vectorized over numpy arrays, so that a planner can carry thousands of candidates
(:class:`Candidates`), and :class:`TableEvidence` keeps those the pulses leave possible and
plans the next pulse on them (the study's rows 17-19, :class:`~.ceiling.FastApproach`).

A table stuck at rest with the breakaway force ``f_b`` is given one sample ``u`` (N) through
the actuator lag (``tau_u`` s, Eq. of :mod:`papwc.model.effects.lag`)::

    f_a(t) = u*(1 - exp(-t/tau_u))                      0 <= t < T
    f_a(t) = f_a(T)*exp(-(t - T)/tau_u)                 t >= T

It breaks away where ``f_a`` reaches ``f_b`` (at ``t_0``) and slides along ``u`` by::

    m*dv/dt = f_a(t) - g(v) - c*v,   g(v) = f_c + (f_b - f_c)*exp(-(v/v_s)**delta_s)

(the Stribeck curve of :mod:`papwc.model.effects.stribeck`, scaled by the breakaway drawn at
this stick, as the plant's random stiction does) until ``v`` returns to 0, where it sticks.
Not modelled: ripple (a constant factor over a move of micrometres, folded into ``f_b``), a
new breakaway below the force still applied where it sticks, LuGre's bristles and a flexible
drive. Integration: classical Runge–Kutta, ``STEPS_PULSE`` steps from ``t_0`` to ``T`` (each
table its own step, so the force's kink at ``T`` is a step boundary) and steps of ``T/STEPS_T``
after; the stop is placed within its step as under a constant deceleration.

The reading one sample after a pulse (its *first reading*: the table at the end of the sample
the force was applied in) is what tells the candidates apart: a move at rest alone is
explained on any of them by a breakaway placed just below the pulse's height, but through a
lag the force has barely risen by the first reading. :class:`TableEvidence` keeps the
candidates that explain every one-sample pulse that moved: some breakaway above the
candidate's ``f_c`` moves it as far (within ``CONSISTENT`` and the noise), and at that
breakaway its first reading fits the one read (a chi-square over the pulses, within
``MISFIT_LEFT`` of the least). It plans a one-sample pulse for the lowest breakaway still
possible on each candidate left: the lowest the last ``FRESH_MOVES`` moves imply there,
lowered by their spread over their number (at least ``FRESH_MARGIN``: the exact-model
controller's rule), and no lower than the force each pulse that held on the present stick let
through its lag. The height fired is the lowest any candidate plans for the move: if the table
is among them and breaks away higher, the pulse moves it less.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

__all__ = ["CONSISTENT", "FIELDS", "FRESH_MARGIN", "FRESH_MOVES", "HALVINGS", "HORIZON",
           "MISFIT_LEFT", "STEPS_PULSE", "STEPS_T", "Z_REACH", "Candidates", "TableEvidence",
           "halve_each", "lag_share", "one_pulse"]

#: Steps from the breakaway to the end of the pulse's sample, and steps a sample after it.
STEPS_PULSE = 30
STEPS_T = 50


def lag_share(tau_u: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """``f_a(t)/u`` for a force ``u`` asked from ``t = 0`` (s) through the lag ``tau_u`` (s):
    ``1 - exp(-t/tau_u)``, 1 without lag."""
    lagged = tau_u > 0.0
    return np.where(lagged, -np.expm1(-t / np.where(lagged, tau_u, 1.0)), 1.0)


def halve_each(inside: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """``HALVINGS`` halvings of each bracket ``[lo, hi]``, keeping ``lo`` where ``inside``
    holds and ``hi`` where it does not; the brackets left (the vectorized
    :func:`papwc_studies.ceiling.halve`)."""
    for _ in range(HALVINGS):
        mid = 0.5 * (lo + hi)
        holds = inside(mid)
        lo = np.where(holds, mid, lo)
        hi = np.where(holds, hi, mid)
    return lo, hi


def one_pulse(u: np.ndarray | float, f_b: np.ndarray | float, tau_u: np.ndarray | float,
              v_s: np.ndarray | float, f_c: np.ndarray | float, *, m: float, c: float,
              T: float, horizon: float, delta_s: float = 2.0
              ) -> tuple[np.ndarray, np.ndarray]:
    """The moves of one sample of force on stuck tables (arrays broadcast together).

    Parameters
    ----------
    u : array_like
        The sample's force, N (its sign the direction).
    f_b : array_like
        The breakaway force of the present stick, N, >= ``f_c``.
    tau_u : array_like
        Actuator lag, s, >= 0.
    v_s : array_like
        Stribeck velocity, m/s, > 0.
    f_c : array_like
        Sliding (Coulomb) friction, N, > 0.
    m, c : float
        Mass, kg, and viscous damping, N.s/m.
    T : float
        The sample's length, s.
    horizon : float
        Time from the sample's start to the last reading, s, >= ``T``.
    delta_s : float
        The Stribeck curve's exponent.

    Returns
    -------
    first, final : numpy.ndarray
        The move at ``T`` (the first reading after the sample) and at ``horizon``, m.
    """
    u, f_b, tau_u, v_s, f_c = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (u, f_b, tau_u, v_s, f_c)))
    sign = np.sign(u)
    push = np.abs(u)
    lagged = tau_u > 0.0
    tau = np.where(lagged, tau_u, 1.0)
    rise = lag_share(tau_u, T)  # f_a(T)/u
    moves = push * rise > f_b
    # breakaway time (0 without lag): f_a(t_0) = f_b
    ratio = np.where(moves, f_b / np.where(push > 0.0, push, 1.0), 0.0)
    t_0 = np.where(lagged & moves, -tau * np.log1p(-np.minimum(ratio, 1.0)), 0.0)
    drop = f_b - f_c
    inv_vs = 1.0 / v_s

    def force(t: np.ndarray) -> np.ndarray:
        after = t >= T
        during = push * lag_share(tau_u, np.minimum(t, T))
        decay = np.where(lagged, np.exp(-np.maximum(t - T, 0.0) / tau), 0.0)
        return np.where(after, push * rise * decay, during)

    def accel(t: np.ndarray, v: np.ndarray) -> np.ndarray:
        w = np.maximum(v, 0.0)
        g = f_c + drop * np.exp(-((w * inv_vs) ** delta_s))
        return (force(t) - g - c * w) / m

    x = np.zeros(u.shape)
    v = np.zeros(u.shape)
    live = moves.copy()
    t = t_0.copy()

    def advance(h: np.ndarray) -> None:
        nonlocal x, v, t, live
        k1 = accel(t, v)
        k2 = accel(t + 0.5 * h, v + 0.5 * h * k1)
        k3 = accel(t + 0.5 * h, v + 0.5 * h * k2)
        k4 = accel(t + h, v + h * k3)
        v1 = v + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        x1 = x + h / 6.0 * (v + 2.0 * (v + 0.5 * h * k1) + 2.0 * (v + 0.5 * h * k2)
                            + (v + h * k3))
        stops = live & (v1 <= 0.0) & (t > t_0)
        share = np.where(stops, v / np.where(v - v1 > 0.0, v - v1, 1.0), 1.0)
        # stopping under a constant deceleration: half the speed over the time to stop
        x = np.where(live, np.where(stops, x + 0.5 * share * h * v, x1), x)
        v = np.where(live & ~stops, v1, np.where(live, 0.0, v))
        t = t + np.where(live, h, 0.0)
        live &= ~stops

    h_pulse = (T - t_0) / STEPS_PULSE
    for _ in range(STEPS_PULSE):
        advance(h_pulse)
    first = x.copy()
    t = np.where(moves, np.maximum(t, T), t)
    h = T / STEPS_T
    while live.any() and (t[live] < horizon - 0.5 * h).any():
        advance(np.where(t < horizon - 0.5 * h, h, 0.0))
    return sign * first, sign * x


#: Relative error of the one-pulse model's move and first reading against the table's
#: (a move within it, and ``Z_REACH`` standard deviations of its noise, is explained; half
#: of it is one standard deviation of a first reading's residual).
CONSISTENT = 0.1
Z_REACH = 3.0
#: Misfit (chi-square of the first readings) above the least left at which a candidate is
#: ruled out: 99.7 % for three fields.
MISFIT_LEFT = 14.2
#: The recent moves the lowest breakaway of a fresh stick is taken from, and the least
#: margin below the lowest they imply (relative).
FRESH_MOVES = 12
FRESH_MARGIN = 0.005
#: Time after a pulse's sample over which its move is simulated, s (a move near breakaway
#: ends within a few lags).
HORIZON = 0.05
#: The fields a candidate table is told by (the others are the table's: ``m``, ``c``,
#: ``delta_s``).
FIELDS = ("tau_u", "v_s", "f_c")
#: Halvings of a searched force.
HALVINGS = 18


class Candidates:
    """Stick–slip tables that differ in the fields of :data:`FIELDS`, each over a grid.

    Parameters
    ----------
    grids : mapping
        Values (SI units) of the fields not told, each a sequence from the value under which a
        pulse moves the table farthest to the least far.
    told : mapping
        The table as the planner is told it: ``m``, ``c``, ``delta_s`` (default 2) and each
        field of :data:`FIELDS` not in ``grids``.
    T, horizon : float
        The sample's length and the time from a pulse's start to its last reading, s.

    Attributes
    ----------
    index : numpy.ndarray
        Each candidate's grid indices, shape (candidates, fields of ``grids``).
    alive : numpy.ndarray
        Whether each candidate is still consistent with the pulses (bool).
    """

    def __init__(self, grids: Mapping[str, Sequence[float]], told: Mapping[str, float], *,
                 T: float, horizon: float) -> None:
        self.names = [name for name in FIELDS if name in grids]
        self.shape = tuple(len(grids[name]) for name in self.names)
        count = int(np.prod(self.shape))
        self.index = np.indices(self.shape).reshape(len(self.names), count).T
        self.values = {
            name: (np.asarray(grids[name], dtype=float)[self.index[:, self.names.index(name)]]
                   if name in grids else np.full(count, float(told[name])))
            for name in FIELDS}
        self.m, self.c = float(told["m"]), float(told["c"])
        self.delta_s = float(told.get("delta_s", 2.0))
        self.T, self.horizon = T, horizon
        self.alive = np.ones(count, dtype=bool)

    def __len__(self) -> int:
        return len(self.alive)

    def moves(self, u: np.ndarray | float, f_b: np.ndarray | float, which: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`one_pulse` on the candidates ``which`` (indices): first and final move, m."""
        v = self.values
        return one_pulse(u, f_b, v["tau_u"][which], v["v_s"][which], v["f_c"][which],
                         m=self.m, c=self.c, T=self.T, horizon=self.horizon,
                         delta_s=self.delta_s)

    def implied(self, u: float, d: float, which: np.ndarray) -> np.ndarray:
        """The breakaway (N, between ``f_c`` and ``|u|``) at which one sample ``u`` moves
        each candidate of ``which`` by ``d`` (m): a higher breakaway moves it less."""
        sign = math.copysign(1.0, u)
        lo = self.values["f_c"][which]
        lo, hi = halve_each(lambda f_b: sign * self.moves(u, f_b, which)[1] > sign * d,
                            lo, np.maximum(abs(u), lo))
        return 0.5 * (lo + hi)

    def held(self, u: float, which: np.ndarray) -> np.ndarray:
        """The least breakaway (N) at which one sample ``u`` leaves each candidate of
        ``which`` at rest: the force the lag lets through by the sample's end, at least
        ``f_c``."""
        rise = lag_share(self.values["tau_u"][which], self.T)
        return np.maximum(abs(u) * rise, self.values["f_c"][which])

    def plan(self, e: float, f_b: np.ndarray, which: np.ndarray, f_max: float) -> np.ndarray:
        """The highest one-sample force (N, along ``e``, at most ``f_max``) that moves each
        candidate of ``which`` by at most ``|e|`` (m) with the breakaway at ``f_b`` (N)."""
        sign = math.copysign(1.0, e)
        hi = np.full(len(which), f_max)
        top = self.moves(sign * hi, f_b, which)[1] * sign <= abs(e)
        lo, _ = halve_each(lambda h: sign * self.moves(sign * h, f_b, which)[1] <= abs(e),
                           np.zeros(len(which)), hi)
        return sign * np.where(top, f_max, lo)


class TableEvidence:
    """Candidate tables consistent with the one-sample pulses, and the pulse they allow.

    Parameters
    ----------
    grids : mapping
        The fields of :data:`FIELDS` learned and their grids (SI units, each from the value
        under which a pulse moves the table farthest).
    told : mapping
        The rest of every candidate: ``m`` (kg), ``c`` (N.s/m), and the fields not learned.
    T : float
        Sample period, s.

    Attributes
    ----------
    tables : Candidates
        The candidates and which are left (``tables.alive``).
    implied : list of numpy.ndarray
        The breakaway (N) each of the last ``FRESH_MOVES`` moves implies on every candidate.
    misfit : numpy.ndarray
        Each candidate's chi-square of the first readings of the moves (:meth:`observe_move`).
    held : list of float
        Heights (N) of the one-sample pulses that held since the table last moved.
    failed : bool
        A move no candidate explained: the table is none of them, and they plan nothing.
    """

    def __init__(self, grids: Mapping[str, tuple[float, ...]], told: Mapping[str, float],
                 T: float) -> None:
        self.tables = Candidates(grids, told, T=T, horizon=T + HORIZON)
        self.implied: list[np.ndarray] = []
        self.misfit = np.zeros(len(self.tables))
        self.held: list[float] = []
        self.failed = False

    def ready(self) -> bool:
        """Whether it plans: a move has been seen, and some candidate explains every one."""
        return bool(self.implied) and not self.failed

    def observe_held(self, f_p: float) -> None:
        """A one-sample pulse of ``f_p`` (N) left the table at rest."""
        self.held.append(abs(f_p))

    def observe_move(self, f_p: float, first: float, d: float, sigma_first: float,
                     sigma_d: float) -> None:
        """A one-sample pulse of ``f_p`` (N) moved the table ``d`` > 0 (m, along the pulse),
        ``first`` (m) at its first reading; ``sigma_first`` and ``sigma_d`` (m) are the
        standard deviations of the noise on them.

        A candidate under which even a breakaway at its ``f_c`` moves the table less than
        ``d`` (within ``CONSISTENT`` and ``Z_REACH`` standard deviations) is ruled out. Each
        other adds to its misfit (``misfit``, a chi-square) the first reading's residual at
        the breakaway that explains ``d``, over its standard deviation: the noise, the
        noise of ``d`` carried into it, and half ``CONSISTENT`` of it (the model's error);
        those whose misfit exceeds the least left by more than ``MISFIT_LEFT`` are ruled
        out.
        """
        self.held = []
        tables = self.tables
        every = np.arange(len(tables))
        u = abs(f_p)
        reach = tables.moves(u, tables.values["f_c"], every)[1]
        keep = reach >= d * (1.0 - CONSISTENT) - Z_REACH * sigma_d
        implied = tables.implied(u, d, every)
        self.implied = (self.implied + [implied])[-FRESH_MOVES:]
        at_first = tables.moves(u, implied, every)[0]
        var = (sigma_first**2 + (at_first / d * sigma_d) ** 2
               + (0.5 * CONSISTENT * np.maximum(np.abs(at_first), abs(first))) ** 2)
        self.misfit = self.misfit + (at_first - first) ** 2 / np.maximum(var, 1e-300)
        left = tables.alive & keep
        if not left.any():
            self.failed = True
            return
        best = self.misfit[left].min()
        tables.alive = left & (self.misfit <= best + MISFIT_LEFT)

    def lowest(self, ends: np.ndarray) -> np.ndarray:
        """The lowest breakaway still possible (N) on each candidate of ``ends``."""
        tables = self.tables
        out = tables.values["f_c"][ends]
        if self.implied:
            seen = np.stack([b[ends] for b in self.implied])
            low = seen.min(axis=0)
            gap = np.maximum((seen.max(axis=0) - low) / len(seen), FRESH_MARGIN * low)
            out = np.maximum(low - gap, out)
        for f_p in self.held:
            out = np.maximum(out, tables.held(f_p, ends))
        return out

    def plan(self, goal: float, f_max: float) -> tuple[float, float]:
        """The height (N, > 0) of one sample that moves the table at most ``goal`` (m) on
        every candidate left at its lowest breakaway, and the lowest of those breakaways
        (N)."""
        ends = np.flatnonzero(self.tables.alive)
        low = self.lowest(ends)
        heights = self.tables.plan(goal, low, ends, f_max)
        return float(heights.min()), float(low.min())
