"""Fitting the friction plant to a log: regression start, output error, deviations, band.

1. **Start** (:func:`regression`). While the table slides in one direction ``s`` over two
   sample intervals with the force held over each, Eq. (1) gives exactly (``a =
   exp(-c*h/m)``, ``dx_k = x_{k+1} - x_k``)::

       dx_{k+1} = a*dx_k + p_1*u_k + p_2*u_{k+1} - (p_1 + p_2)*s*f_c,
       p_2 = h^2*phi2(z)/m,  z = c*h/m,

   (``phi2`` of :mod:`papwc.model.stickslip`), linear in ``a``, ``p_1``, ``p_2`` and
   ``(p_1 + p_2)*f_c``: least squares over every such triple of sliding intervals gives
   ``m``, ``c`` and ``f_c``.
   Where the table is not Eq. (1)'s (a lag, a ripple) least squares can leave ``a``
   outside (0, 1); the regression is then made over the triples whose force is held over
   both intervals, with ``a`` the best of a grid within (0, 1).
2. **Output error** (:func:`output_error`): the *sliding* moves of the log -- pulses from
   rest above :data:`SLIDE_OVER` times every force the table held, so that where in its band
   the stick's breakaway was drawn matters little -- are simulated from their rests
   (:class:`papwc.identify.simulate.Simulator`, every move's offset estimated) with the
   logged force replayed, and ``scipy.optimize.least_squares`` minimizes the squared
   differences of simulated and measured positions. On Eq. (1) where a move breaks away does
   not matter (it starts at once); with the Stribeck curve or a lag it does, and ``f_s`` is
   fitted.
3. **Intervals**: 95 % intervals from the Jacobian at the optimum, ``cov = s^2 (J^T J)^-1``,
   with ``s^2`` the residual variance (at least :data:`SIGMA_FLOOR` squared, the
   integrator's accuracy) and Student's t; widened by :data:`RELATIVE_FLOOR` of the value
   (the optimizer's tolerance).
4. **Deviations** (:func:`identify`): the friction ripple's wavelength is searched over a
   grid (:func:`papwc.identify.ripple.search`); then every deviation of :data:`DEVIATIONS`
   tried (the Stribeck curve, the actuator lag, the friction ripple) is fitted at once, in
   stages from the ripple's best peak and the best of a grid of the others' starts
   (:func:`_fit_full`: fitted one at a time on top of each other, a lag and the Stribeck
   curve each stood in for the other in a local optimum); each is then tested against the
   model without it (every other parameter free): it is kept when the F-test of the nested
   models rejects "no improvement" at :data:`ALPHA` and its parameters' intervals exclude
   0, the least significant dropped first until all kept are. The deviations are chosen on at
   most :data:`SELECT_MOVES` of the sliding moves.
5. **Breakaways and the band** (:func:`breakaways`, :mod:`papwc.identify.band`): every
   one-sample pulse from rest just above a force its stick held (:data:`BRACKET_MAX`)
   breaks the stick away near its breakaway force; on a plant whose move depends on where it
   broke away (Stribeck, a lag) that force is the one at which the fitted plant moves as far
   as the table did (bisection), else the middle of the bracket. Divided by the fitted
   ripple's factor there, these are draws of random stiction.
6. **Each move at its own draw** (where the model depends on the breakaway): the sliding
   moves cannot tell a Stribeck curve from where in the band their sticks' draws lie (a
   lower curve at a higher draw moves them alike), and a single ``f_s`` for all of them
   biases the curve where the draws spread. So the model chosen is fitted once more with
   each sliding move breaking away at its own draw, fitted too (a sparse Jacobian), the
   draws held to one population by a prior (:data:`PRIOR_WIDTH` times their spread wide)
   whose centre is placed so that the lowest draw of the sliding moves is the lowest of the
   breakaways near the band (those sample its low end; the teeth's later breakaways, after
   moves too small to see redrew the stick, lie low in it): up to :data:`BAND_ROUNDS`
   rounds, with the breakaways found again on each model, until the centre settles. The
   band is made of all the draws, placed by the breakaways near it; ``f_s`` is its middle,
   ``f_s_spread`` its half-width.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from papwc.identify import IdentifyError
from papwc.identify.band import MIN_DRAWS, Band, band_of, sticks_needed
from papwc.identify.log_file import Log, LogError
from papwc.identify.motion import Bracket, Motion, analyse, breakaway_bracket
from papwc.identify.simulate import (
    Move,
    Simulator,
    lagged_force,
    moves_from_rest,
    plant_maker,
    ripple_factor,
)
from papwc.model.plant import PLANT_PARAMETERS
from papwc.model.stickslip import _phi1, _phi2, quantize

__all__ = [
    "ALPHA",
    "DEVIATIONS",
    "RELATIVE_FLOOR",
    "SIGMA_FLOOR",
    "SLIDE_OVER",
    "Breakaway",
    "Estimate",
    "Identification",
    "Trial",
    "breakaways",
    "check_log",
    "identify",
    "output_error",
    "regression",
    "replay",
]

#: Significance level of the F-test that adds a deviation.
ALPHA = 0.01
#: The deviations' parameters whose 95 % interval must exclude 0 too: the ripple's amplitude,
#: on which the moves depend about linearly. The Stribeck velocity and the lag's time
#: constant are scales whose effect vanishes as they go to 0, so an interval from the
#: Jacobian (linear in them) says little there; the F-test decides for them (measured: a
#: Stribeck curve at p = 6e-11 with such an interval reaching 0 dropped, v_s -100 % and the
#: band 30 N off on 13 of 30 tables).
LINEAR = ("ripple",)
#: Smallest standard deviation of a residual, m: the accuracy of the plant's integrator
#: (papwc.model.dynamics.TOLERANCES), below which an improvement is not one.
SIGMA_FLOOR = 1e-11
#: Unit of the residuals the optimizer sees, m (its gradient test is absolute).
RESIDUAL_UNIT = 1e-6
#: Relative width added to every interval: the optimizer's tolerance.
RELATIVE_FLOOR = 1e-6
#: A move from rest is a sliding one when its pulse's force exceeds this many times the
#: largest force the table held at rest (where its stick broke away then matters little).
SLIDE_OVER = 1.2

#: Most evaluations and the tolerance of the least squares of a trial (each evaluation
#: simulates the moves).
TRIAL_EVALUATIONS = 20
TRIAL_TOLERANCE = 1e-6
#: The same for the final fit, every parameter free.
REFIT_EVALUATIONS = 40
FINAL_TOLERANCE = 1e-8
#: Bisection steps of a breakaway force (:func:`breakaways`).
BREAKAWAY_STEPS = 40
#: A move's draw of random stiction is fitted within this factor of its start.
DRAW_RANGE = 2.0
#: Most sliding moves the deviations are chosen on (:func:`identify`).
SELECT_MOVES = 100
#: Most rounds of the fit with each sliding move at its own draw and the band
#: (:func:`identify`) ...
BAND_ROUNDS = 5
#: ... until the band's centre moves less than this (relative).
BAND_SETTLED = 0.002
#: Smallest spread of the draws' prior, N (a band of one force), and its width in standard
#: deviations of the draws.
DRAW_SPREAD_MIN = 0.5
PRIOR_WIDTH = 3.0
#: The sliding moves' draws count for the band.
BAND_FROM_SLIDING = True
#: A breakaway counts for the band when its pulse is at most this much (relative) above
#: the largest force its stick held: a move from far above its breakaway says little of
#: where that was.
BRACKET_MAX = 0.05
#: Peaks of the wavelength search that start the ripple's trial.
RIPPLE_STARTS = 3
#: A ripple trial's wavelength stays within this factor of the peak it starts from.
RIPPLE_WINDOW = 1.25

_UNITS = {v.name: v.unit for v in PLANT_PARAMETERS}


@dataclass(frozen=True)
class Deviation:
    """A deviation the fit can add: its parameters, their starting values and bounds."""

    name: str
    parameters: tuple[str, ...]
    starts: tuple[tuple[float, ...], ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    what: str

    @property
    def own(self) -> tuple[str, ...]:
        """Its parameters with their own starts and bounds (``f_s``, which the Stribeck curve
        and the lag share, starts from Eq. (1)'s ``f_c``, :data:`F_S_STARTS`)."""
        return self.parameters[:len(self.lower)]


#: The deviations tried, in order (the ripple's starts come from the wavelength search).
DEVIATIONS: tuple[Deviation, ...] = (
    Deviation("stribeck", ("v_s", "f_s"), ((1e-4,), (3e-4,), (1e-3,), (3e-3,)), (1e-6,),
              (10.0,), "Stribeck curve (v_s, and f_s, its top; delta_s held at 2)"),
    Deviation("lag", ("tau_u", "f_s"), ((0.0,), (5e-4,), (2e-3,), (5e-3,)), (1e-6,), (1.0,),
              "actuator lag (tau_u, and f_s, where the lagging force breaks the table away)"),
    Deviation("ripple", ("ripple", "ripple_period", "ripple_phase"), (),
              (1e-6, 1e-4, -2.0 * math.pi), (0.9, 1e3, 2.0 * math.pi),
              "friction ripple (ripple, ripple_period searched, ripple_phase)"),
)
#: Starts of ``f_s`` as multiples of Eq. (1)'s ``f_c`` where a deviation fits it.
F_S_STARTS = (1.1, 1.3, 1.5)


#: Deviations not tried, and why (for the report).
NOT_TRIED: tuple[tuple[str, str], ...] = (
    ("flexible drive", "motor mass and coupling: not fitted (needs the motor position and "
                       "a model of the drive's start state)"),
    ("LuGre", "pre-sliding: below the encoder's resolution in a stick-slip log"),
)


@dataclass
class Estimate:
    """One identified parameter: value, 95 % interval, unit and how it was found."""

    name: str
    value: float
    low: float
    high: float
    unit: str
    method: str


@dataclass
class Trial:
    """One fit of the output error: the model, its residual and the test that judged it."""

    label: str
    names: tuple[str, ...]
    values: dict[str, float]
    rss: float
    n: int
    seconds: float
    jac: np.ndarray | None = None
    p_value: float = math.nan
    f_stat: float = math.nan
    chosen: bool = False
    why: str = ""
    #: The optimizer met its tolerance (else it stopped at its evaluation limit).
    converged: bool = True
    #: Each move's draw of random stiction, fitted with the model (N; None: not fitted).
    draws: np.ndarray | None = None

    @property
    def n_params(self) -> int:
        """Parameters fitted: the model's and the moves' draws."""
        return len(self.names) + (0 if self.draws is None else self.draws.size)


@dataclass(frozen=True)
class Breakaway:
    """One stick broken away from rest: its pulse, where, and at which force.

    Attributes
    ----------
    k : int
        The pulse's sample.
    x : float
        Position at rest, m.
    force : float
        The force at which it broke away, N (the ripple's factor there included).
    low, high : float
        The bracket: the largest force the stick held (0: none), the force that moved it, N.
    draw : float
        ``force`` over the fitted ripple's factor at ``x``: the stiction's draw, N.
    """

    k: int
    x: float
    force: float
    low: float
    high: float
    draw: float


@dataclass
class Identification:
    """The result of :func:`identify`."""

    log: Log
    motion: Motion
    bracket: Bracket
    start: dict[str, float]
    plant: dict[str, Any]
    estimates: list[Estimate]
    trials: list[Trial]
    chosen: list[str]
    replay_x: np.ndarray
    replay_rms: float
    replay_bound: float
    residual_rms: float
    seconds: float
    regression_rows: int
    notes: list[str] = field(default_factory=list)
    #: The stiction band (None: too few breakaways from rest).
    band: Band | None = None
    #: The breakaways the band is made of.
    breakaways: list[Breakaway] = field(default_factory=list)
    #: Moves from rest fitted (sliding) and breakaways from rest seen.
    sliding_moves: int = 0
    #: The wavelength search's peaks (when the ripple was tried).
    ripple_peaks: list = field(default_factory=list)
    #: Processor time of the identification, s.
    cpu_seconds: float = 0.0


# -- the start ----------------------------------------------------------------------------------


def sliding_triples(motion: Motion) -> np.ndarray:
    """Samples ``k`` whose intervals ``k``, ``k+1``, ``k+2`` all moved in one direction."""
    moved, s = motion.moved, np.sign(motion.dx)
    k = np.arange(moved.size - 2)
    ok = (moved[k] & moved[k + 1] & moved[k + 2] & (s[k] == s[k + 1]) & (s[k + 1] == s[k + 2]))
    return k[ok]


def regression(log: Log, motion: Motion) -> tuple[dict[str, float], int]:
    """``m``, ``f_c``, ``c`` from the sliding triples (see the module); and their number.

    Raises
    ------
    LogError
        If the log holds fewer than 8 triples (too short to contain a move) or they
        do not determine the three parameters.
    """
    k = sliding_triples(motion)
    if k.size < 8:
        raise LogError(f"{log.source}, column {log.columns.position!r}: too short to contain a "
                       f"move: {k.size} run(s) of 3 sample intervals sliding in one direction, "
                       "at least 8 are needed (pulses of several samples; see papwc identify "
                       "--design)")
    dx, u, h = motion.dx, log.u, log.h
    steady = k[u[k] == u[k + 1]]
    if steady.size >= 8 and np.unique(np.abs(u[steady])).size >= 2:
        # The force held over both intervals: a lagging actuator's transient, which the
        # regression does not model, is least there. Then dx_{k+1} = a*dx_k + P*(u - s*f_c)
        # with P = p_1 + p_2 = h^2*(phi1^2 + phi2*(1 - a))/m.
        sign = np.sign(dx[steady])
        sol, *_ = np.linalg.lstsq(np.column_stack([dx[steady], u[steady], -sign]),
                                  dx[steady + 1], rcond=None)
        a, p, q = (float(v) for v in sol)
        if not 0.0 < a < 1.0:
            # A plant unlike Eq. (1) (a long lag, a ripple) can pull a out of (0, 1): the
            # best a within it instead (a grid of c*h/m), P and P*f_c by least squares.
            a, p, q = _steady_within(dx[steady], dx[steady + 1], u[steady], sign)
        if 0.0 < a < 1.0 and p > 0.0:
            z = -math.log(a)
            m = h * h * (_phi1(z) ** 2 + _phi2(z) * (1.0 - a)) / p
            return {"m": m, "f_c": max(q / p, 0.0), "c": z * m / h}, int(steady.size)
    s = np.sign(dx[k])
    a_matrix = np.column_stack([dx[k], u[k], u[k + 1], -s])
    sol, *_ = np.linalg.lstsq(a_matrix, dx[k + 1], rcond=None)
    a, p1, p2, q = (float(v) for v in sol)
    if not (0.0 < a < 1.0 and p2 > 0.0 and p1 + p2 > 0.0):
        raise LogError(f"{log.source}: the sliding samples do not determine m and c (regression "
                       f"a = {a:.6g}, p_2 = {p2:.6g}); the log needs pulses of several samples "
                       "at several heights")
    z = -math.log(a)
    m = h * h * _phi2(z) / p2
    c = z * m / h
    f_c = max(q / (p1 + p2), 0.0)
    return {"m": m, "f_c": f_c, "c": c}, int(k.size)


def _steady_within(dx: np.ndarray, dx_next: np.ndarray, u: np.ndarray, sign: np.ndarray
                   ) -> tuple[float, float, float]:
    """``a``, ``P``, ``P*f_c`` of the steady regression with ``a`` within (0, 1): the best
    of a grid of ``z = -log(a)`` from 1e-6 to 5."""
    best = (math.inf, 0.0, 0.0, 0.0)
    design_matrix = np.column_stack([u, -sign])
    for z in np.geomspace(1e-6, 5.0, 200):
        a = math.exp(-z)
        sol, *_ = np.linalg.lstsq(design_matrix, dx_next - a * dx, rcond=None)
        rss = float(np.sum((design_matrix @ sol - (dx_next - a * dx)) ** 2))
        if rss < best[0]:
            best = (rss, a, float(sol[0]), float(sol[1]))
    return best[1], best[2], best[3]


# -- output error ------------------------------------------------------------------------------


def _parameter(name: str) -> Any:
    return next(v for v in PLANT_PARAMETERS if v.name == name)


def output_error(sim: Simulator, fixed: Mapping[str, Any], names: Sequence[str],
                 start: Mapping[str, float], lower: Mapping[str, float] | None = None,
                 upper: Mapping[str, float] | None = None, label: str = "",
                 max_nfev: int = 200, tolerance: float = 1e-12,
                 draws: np.ndarray | None = None,
                 prior: tuple[float, float, float] | None = None) -> Trial:
    """Least squares on the positions of ``sim`` over the parameters ``names``.

    ``fixed`` holds the other plant parameters; the bounds of a parameter not in ``lower``
    and ``upper`` are the model layer's. With ``draws`` (N, one per move of ``sim``), each
    move's draw of random stiction is fitted too, from those values, within a factor
    :data:`DRAW_RANGE` of them (each touches its own move only: the Jacobian's columns of
    the draws are found together, one evaluation for all). With ``prior`` ``(centre, spread,
    noise)`` (N, N, m) the draws are held to the stiction band's: each adds the residual
    ``(draw - centre)/spread`` in units of the position's ``noise`` (the draws of a band are
    one population, so the moves cannot trade a Stribeck curve for draws off the band).
    """
    from scipy.optimize import least_squares

    lower, upper = dict(lower or {}), dict(upper or {})
    scale = np.array([max(abs(start[n]), 1e-12) for n in names])
    lo = np.array([lower.get(n, max(_parameter(n).min or 0.0, 0.0)) for n in names]) / scale
    hi = np.array([upper.get(n, _parameter(n).max or np.inf) for n in names]) / scale
    theta0 = np.clip(np.array([start[n] for n in names]) / scale, lo, hi)
    g = len(names)
    sparsity = None
    if draws is not None:
        d_scale = np.maximum(np.asarray(draws, dtype=float), 1e-9)
        scale = np.concatenate([scale, d_scale])
        lo = np.concatenate([lo, np.full(d_scale.size, 1.0 / DRAW_RANGE)])
        hi = np.concatenate([hi, np.full(d_scale.size, DRAW_RANGE)])
        theta0 = np.concatenate([theta0, np.ones(d_scale.size)])
        from scipy.sparse import lil_matrix

        rows = sim.index.size + (d_scale.size if prior is not None else 0)
        sparsity = lil_matrix((rows, g + d_scale.size), dtype=np.int8)
        sparsity[:sim.index.size, :g] = 1
        for i, (first, size) in enumerate(zip(sim.starts, sim._sizes, strict=True)):
            sparsity[first:first + size, g + i] = 1
            if prior is not None:
                sparsity[sim.index.size + i, g + i] = 1

    def params_of(theta: np.ndarray) -> dict[str, Any]:
        return {**fixed, **{n: float(t * s) for n, t, s in zip(names, theta[:g], scale[:g],
                                                                strict=True)}}

    def residual(theta: np.ndarray) -> np.ndarray:
        if draws is not None:
            sim.draws = theta[g:] * scale[g:]
        r = sim.project(sim.positions(params_of(theta)) - sim.measured) / RESIDUAL_UNIT
        if prior is None:
            return r
        centre, spread, noise = prior
        return np.concatenate([r, (sim.draws - centre) / spread * (noise / RESIDUAL_UNIT)])

    began = time.perf_counter()
    kept = sim.draws
    try:
        res = least_squares(residual, theta0, bounds=(lo, hi), method="trf", x_scale=1.0,
                            ftol=tolerance, xtol=tolerance, gtol=1e-14, max_nfev=max_nfev,
                            diff_step=1e-6, jac_sparsity=sparsity,
                            tr_solver=None if sparsity is None else "lsmr")
    finally:
        sim.draws = kept
    values = params_of(res.x)
    fun = res.fun[:sim.index.size]
    rss = float(np.sum(fun**2)) * RESIDUAL_UNIT**2
    jac = res.jac.toarray() if hasattr(res.jac, "toarray") else np.asarray(res.jac)
    jac = jac * RESIDUAL_UNIT / scale[np.newaxis, :]
    fitted = None if draws is None else res.x[g:] * scale[g:]
    return Trial(label, tuple(names), values, rss, sim.n, time.perf_counter() - began, jac,
                 converged=res.status != 0, draws=fitted)


def intervals(trial: Trial, n_params: int | None = None) -> dict[str, tuple[float, float]]:
    """95 % intervals of a trial's free parameters (see the module; with the moves' draws
    fitted, of the model's parameters with the draws free)."""
    from scipy.stats import t as student

    dof = max(trial.n - (trial.n_params if n_params is None else n_params), 1)
    sigma2 = max(trial.rss / dof, SIGMA_FLOOR**2)
    jtj = trial.jac.T @ trial.jac
    cov = sigma2 * np.linalg.pinv(jtj)
    quantile = float(student.ppf(0.975, dof))
    out = {}
    for i, name in enumerate(trial.names):
        value = trial.values[name]
        half = quantile * math.sqrt(max(cov[i, i], 0.0)) + RELATIVE_FLOOR * abs(value)
        out[name] = (value - half, value + half)
    return out


def f_test(base: Trial, bigger: Trial, extra: int, n_bigger: int) -> tuple[float, float]:
    """F statistic and p-value of ``bigger`` (``n_bigger`` parameters) against ``base``,
    nested in it with ``extra`` parameters fewer."""
    from scipy.stats import f as fisher

    dof = max(bigger.n - n_bigger, 1)
    sigma2 = max(bigger.rss / dof, SIGMA_FLOOR**2)
    stat = max(base.rss - bigger.rss, 0.0) / extra / sigma2
    return stat, float(fisher.sf(stat, extra, dof))


def replay(log: Log, params: Mapping[str, Any], moved: np.ndarray | None = None,
           maker: Callable | None = None) -> np.ndarray:
    """The whole log simulated from its first rest with the force replayed (x_meas, m).

    The encoder's count is applied, its noise is not (the machine's noise is not known), nor
    random stiction (the table breaks away at ``f_s`` times the ripple's factor: where the
    machine's draws fell is not known). The start is the mean of the positions before the
    first interval that ``moved``. ``maker``: :func:`papwc.identify.simulate.plant_maker`'s
    result (default: :class:`papwc.model.dynamics.Plant`).
    """
    first = int(np.argmax(moved)) if moved is not None and moved.any() else 0
    x0 = float(np.mean(log.x[:min(first, 50) + 1]))  # the first rest, averaged
    p = {**params, "noise_std": 0.0, "f_s_spread": 0.0, "x0": x0, "v0": 0.0}
    plant = (maker or plant_maker())(p)
    out = np.empty(log.x.size)
    out[0] = quantize(plant.x, p.get("x_resolution", 0.0))
    for k in range(log.x.size - 1):
        reason = plant.step(float(log.u[k]), log.h)
        if reason is not None:
            raise IdentifyError(f"{log.source}: the identified plant refused to replay row "
                                f"{k + 1}: {reason}")
        out[k + 1] = plant.x_meas()
    return out


# -- breakaways and the band --------------------------------------------------------------------


def held_forces(log: Log, motion: Motion, force: np.ndarray) -> np.ndarray:
    """Per sample, the largest ``|force|`` the table held at rest since it last moved, N."""
    held = np.zeros(motion.moved.size)
    top = 0.0
    for k in range(motion.moved.size):
        held[k] = top
        if motion.moved[k]:
            top = 0.0
        elif motion.rest[k]:
            top = max(top, abs(float(force[k])))
    return held


def _depends_on_breakaway(params: Mapping[str, Any]) -> bool:
    """Whether a move from rest depends on the force at which the table broke away."""
    return float(params.get("v_s", 0.0)) > 0.0 or float(params.get("tau_u", 0.0)) > 0.0


def breakaways(log: Log, motion: Motion, moves: Sequence[Move], params: Mapping[str, Any],
               maker: Callable) -> list[Breakaway]:
    """The force at which each one-sample move from rest broke its stick away (see the
    module), on the plant ``params``."""
    force = lagged_force(log.u, log.h, float(params.get("tau_u", 0.0)))
    held = held_forces(log, motion, force)
    depends = _depends_on_breakaway(params)
    out = []
    for mv in moves:
        high = abs(float(force[mv.k0]))
        low = float(held[mv.k0])
        if mv.width != 1 or not 0.0 < low < high <= low * (1.0 + BRACKET_MAX):
            continue  # not a pulse just above one the stick held: far from its breakaway
        factor = float(ripple_factor(params, mv.x0))
        if depends:
            point = _implied(log, mv, params, maker, factor * float(params["f_c"]), high)
            if point is None:
                continue
        else:
            point = 0.5 * (low + high)
        out.append(Breakaway(mv.k0, mv.x0, point, low, high, point / factor))
    return out


def _implied(log: Log, mv: Move, params: Mapping[str, Any], maker: Callable, low: float,
             high: float) -> float | None:
    """The breakaway force (N, in ``[low, high]``) at which the plant moves as far as the
    table did over ``mv``, by bisection; None if the table moved back or not at all."""
    sim = Simulator(log, [mv], maker, [high])
    sign = math.copysign(1.0, float(log.u[mv.k0]))
    moved = sign * (float(log.x[mv.k1 - 1]) - mv.x0)
    if not moved > 0.0 or not high > low:
        return None

    def move(f_b: float) -> float:
        sim.breakaway = [f_b]
        return sign * (float(sim.positions(params)[-1]) - mv.x0)

    if move(low) <= moved:
        return low
    lo, hi = low, high
    for _ in range(BREAKAWAY_STEPS):
        mid = 0.5 * (lo + hi)
        if move(mid) > moved:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _band(found: Sequence[Breakaway], depends: bool) -> Band | None:
    """The band of the breakaways ``found``; placed by those near the band (the sliding
    moves' draws, ``low`` 0, are placed by them)."""
    near = [b for b in found if b.low > 0.0]
    if len(near) < MIN_DRAWS:
        return None
    brackets = None
    if not depends:
        brackets = [(b.low / (b.force / b.draw), b.high / (b.force / b.draw)) for b in near]
    return band_of([b.draw for b in found], brackets, sticks=len(near))


# -- the whole identification ---------------------------------------------------------------


def check_log(log: Log) -> None:
    """Refuse a log without motion, without a breakaway or too short (:class:`LogError`)."""
    regression(log, analyse(log))


def _sliding(log: Log, moves: Sequence[Move], motion: Motion) -> tuple[list[Move], list[Move]]:
    """The sliding moves (see the module) and the others."""
    at_rest = motion.held
    top = float(np.max(np.abs(log.u[at_rest]))) if at_rest.size else 0.0
    sliding = [mv for mv in moves if abs(float(log.u[mv.k0])) > SLIDE_OVER * top]
    others = [mv for mv in moves if abs(float(log.u[mv.k0])) <= SLIDE_OVER * top]
    return sliding, others


def identify(log: Log, deviations: Sequence[str] = ("stribeck", "lag", "ripple"),
             progress: Callable[[str], None] | None = None, library: Any = "installed"
             ) -> Identification:
    """Identify the plant of ``log`` (see the module's description).

    Parameters
    ----------
    log : Log
        A checked log (:func:`papwc.identify.log_file.read_log`).
    deviations : sequence of str
        The deviations to try beyond Eq. (1): ``"stribeck"``, ``"lag"``, ``"ripple"``, or
        none.
    progress : callable, optional
        Called with a line of text at each stage (``papwc identify`` prints them).
    library : NativePlantLibrary, None or "installed"
        The C plant the moves are simulated on (the same numbers as
        :class:`papwc.model.dynamics.Plant`, faster); ``"installed"``: the one papwc was
        installed with where it is current
        (:func:`papwc.master.native_plant.own_plant_library`); None: Plant.

    Returns
    -------
    Identification
        The identified ``plant`` parameters, each ``estimates`` entry with its 95 %
        interval, the models tried, the stiction band, the replay of the log and its
        residual.

    Raises
    ------
    LogError
        If the log holds no motion, no breakaway, or too few sliding samples or moves.

    Examples
    --------
    The default excitation applied to Table 1's plant (m = 150 kg, f_c = 100 N,
    f_s = 130 N, c = 700 N.s/m), read through an ideal encoder, identified with Eq. (1):

    >>> from papwc.identify.excitation import apply_to_plant, design
    >>> u = design(h=0.01, f_p_max=300.0, travel=0.05, duration=60.0)
    >>> log = apply_to_plant(u, 0.01, {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0})
    >>> found = identify(log, deviations=())
    >>> {name: round(found.plant[name], 6) for name in ("m", "f_c", "c")}
    {'m': 150.0, 'f_c': 100.0, 'c': 700.0}
    >>> abs(found.plant["f_s"] - 130.0) <= 0.001 * 130.0, found.chosen, found.band.spread
    (True, [], 0.0)
    """
    from papwc.progress import doing

    if isinstance(library, str):
        from papwc.master.native_plant import own_plant_library

        library = own_plant_library()
    maker = plant_maker(library)
    say = progress or (lambda text: None)
    began, cpu_began = time.perf_counter(), time.process_time()
    doing("finding the moves and rests in the log")
    motion = analyse(log)
    start, rows = regression(log, motion)
    say(f"regression on {rows} sliding triples: m = {start['m']:.6g} kg, f_c = "
        f"{start['f_c']:.6g} N, c = {start['c']:.6g} N.s/m")
    bracket = breakaway_bracket(motion, log.u)
    if bracket.low_k < 0:
        bracket = Bracket(min(start["f_c"], bracket.high), bracket.high, -1, bracket.high_k)
    moves = moves_from_rest(log, motion)
    sliding, others = _sliding(log, moves, motion)
    if len(sliding) < 2:
        raise LogError(f"{log.source}: {len(sliding)} move(s) from rest to rest by a pulse above "
                       f"{SLIDE_OVER:g} times the largest force the table held; at least 2 are "
                       "needed (pulses of several samples and heights, each followed by a "
                       "rest; see papwc identify --design)")
    say(f"{len(moves)} moves from rest to rest: {len(sliding)} sliding, {len(others)} near "
        f"the breakaway")
    sim = Simulator(log, sliding, maker)
    # Eq. (1)'s sliding moves start at once whatever the breakaway (at f_c here); where the
    # Stribeck curve or the lag makes it matter, f_s is fitted.
    f_s = start["f_c"]
    base_names = ("m", "f_c", "c")
    doing("output error, Eq. (1): fitting m, f_c, c")
    base = output_error(sim, {"f_s": f_s}, base_names, start, label="Eq. (1): m, f_c, c",
                        max_nfev=REFIT_EVALUATIONS, tolerance=FINAL_TOLERANCE)
    say(f"output error, Eq. (1): rss = {base.rss:.4g} m^2 in {base.seconds:.3g} s")
    trials = [base]
    notes: list[str] = []
    tried = [d for d in DEVIATIONS if d.name in deviations]
    peaks: list = []
    if any(d.name == "ripple" for d in tried):
        from papwc.identify.ripple import search

        doing("searching the friction ripple's wavelength")
        peaks = search(sim, base.values, RIPPLE_STARTS)
        say("ripple wavelengths searched; best: " + ", ".join(
            f"{p.wavelength * 1e3:.4g} mm ({p.share:.2%} of the residual)" for p in peaks))
    current = base
    # The deviations are chosen on at most SELECT_MOVES of the sliding moves (evenly
    # spread), the model chosen fitted on all.
    step = max(1, math.ceil(len(sim.moves) / SELECT_MOVES))
    choose = sim if step == 1 else sim.subset(sim.moves[::step])
    if choose is not sim:
        notes.append(f"the deviations were chosen on {len(choose.moves)} of the "
                     f"{len(sim.moves)} sliding moves (evenly spread); the model chosen is "
                     "fitted on all")
    if tried:
        doing("fitting every deviation tried at once: " + ", ".join(d.name for d in tried))
        current = _fit_full(choose, base, tried, peaks)
        trials.append(current)
        say(f"fitted with {', '.join(d.name for d in tried)}: rss = {current.rss:.4g} m^2 in "
            f"{current.seconds:.3g} s")
    kept = list(tried)
    while kept:
        # Each deviation kept is tested against the model without it (nested, every other
        # parameter free); the least significant is dropped unless every one holds.
        results = []
        for dev in kept:
            doing(f"testing {dev.name}: the model without it")
            reduced = _without(choose, current, dev, [d for d in kept if d is not dev])
            extra = current.n_params - reduced.n_params
            f_stat, p_value = f_test(reduced, current, extra, current.n_params)
            ci = intervals(current)
            tested = [p for p in dev.own if p in LINEAR]
            ok = p_value < ALPHA and all(ci[p][0] > 0.0 for p in tested)
            if ok:
                why = (f"F = {f_stat:.4g}, p = {p_value:.3g} < {ALPHA}: lowers the residual "
                       "beyond the noise")
            elif p_value >= ALPHA:
                why = (f"F = {f_stat:.4g}, p = {p_value:.3g} >= {ALPHA}: no improvement beyond "
                       "the noise")
            else:
                why = (f"F = {f_stat:.4g}, p = {p_value:.3g}, but a 95 % interval of its "
                       "parameters includes 0")
            reduced.label = f"without {dev.what}"
            reduced.f_stat, reduced.p_value = f_stat, p_value
            reduced.why = f"{dev.name}: {why}"
            say(f"tested {dev.name}: {why} ({reduced.seconds:.3g} s)")
            trials.append(reduced)
            results.append((dev, reduced, ok))
        weak = [(dev, reduced) for dev, reduced, ok in results if not ok]
        if not weak:
            break
        dev, reduced = max(weak, key=lambda pair: pair[1].p_value)
        kept = [d for d in kept if d is not dev]
        current = reduced
    chosen = [d.name for d in tried if d in kept]
    current.chosen = True
    found = breakaways(log, motion, others, current.values, maker)
    band = _band(found, _depends_on_breakaway(current.values))
    if choose is not sim and not (_depends_on_breakaway(current.values) and band is not None):
        doing("fitting the model chosen on every sliding move")
        current = _with_draws(sim, current.values, current.names,
                              current.label + " (every sliding move)", REFIT_EVALUATIONS)
        current.chosen = True
        current.why = "the model chosen, fitted on every sliding move"
        trials.append(current)
        found = breakaways(log, motion, others, current.values, maker)
        band = _band(found, _depends_on_breakaway(current.values))
    if _depends_on_breakaway(current.values) and band is not None:
        # The model chosen once more, each sliding move breaking away at its own draw of
        # random stiction, the draws held to the band the breakaways near it give (the
        # sliding moves alone cannot tell a Stribeck curve from where their draws lie),
        # then the band again on that model.
        # The prior holds the draws' mean (to about its width over the square root of their
        # number), not each draw: it is wider than the band (PRIOR_WIDTH times its standard
        # deviation), so that it does not pull the draws together.
        centre, spread = band.f_s, band.spread * band.f_s / math.sqrt(3.0)
        noise = max(motion.noise, motion.resolution, SIGMA_FLOOR)
        for _ in range(BAND_ROUNDS):
            before = centre
            doing("refitting the model chosen, each move at its own draw of the band")
            current = _with_draws(sim, {**current.values, "f_s": centre}, current.names,
                                  current.label.split(" (")[0] + " (each move at its own draw)",
                                  REFIT_EVALUATIONS, per_move=True,
                                  prior=(centre, max(PRIOR_WIDTH * spread, DRAW_SPREAD_MIN),
                                         noise))
            found = breakaways(log, motion, others, current.values, maker)
            # The sliding moves' draws are one random sample of the band (the walk's sticks
            # are drawn as any), but where they lie trades against the Stribeck curve; the
            # breakaways near the band place its low end (the lowest of them lies near it):
            # the draws are moved so that their lowest is theirs.
            draws = current.draws
            if found:
                centre = float(np.mean(draws)) + min(b.draw for b in found) - float(np.min(draws))
            spread = float(np.std(draws))
            if abs(centre - before) <= BAND_SETTLED * centre:
                break
        current.chosen = True
        current.why = ("the model chosen, each sliding move breaking away at its own draw of "
                       "the stiction band")
        trials.append(current)
        say(f"refitted, each move at its own draw: rss = {current.rss:.4g} m^2 in "
            f"{current.seconds:.3g} s")
    if current.draws is not None and BAND_FROM_SLIDING:
        found += [Breakaway(mv.k0, mv.x0, draw * float(ripple_factor(current.values, mv.x0)),
                            0.0, abs(float(log.u[mv.k0])), float(draw))
                  for mv, draw in zip(sim.moves, current.draws, strict=True)]
    band = _band(found, _depends_on_breakaway(current.values))
    final = current
    if not final.converged:
        notes.append(f"the final fit ({final.label}) stopped at its limit of "
                     f"{REFIT_EVALUATIONS} evaluations before its tolerance: its intervals are "
                     "those of a converged fit and may be too narrow")
    final.chosen = True
    if not final.why:
        final.why = "the model chosen"
    ci = intervals(final)
    estimates = []
    for name in final.names:
        low, high = ci[name]
        if name == "f_s" and band is not None:
            continue  # the band's middle is the breakaway's estimate (the fit's is in report.md)
        if name == "ripple_phase":
            estimates.append(Estimate(name, final.values[name], low, high, _UNITS[name],
                                      "output error"))
            continue
        estimates.append(Estimate(name, final.values[name], max(low, 0.0), high, _UNITS[name],
                                  "output error"))
    plant = {name: final.values[name] for name in final.names}
    plant["f_s"] = (float(np.mean(final.draws)) if final.draws is not None
                    else final.values.get("f_s", final.values["f_c"]))
    if band is not None:
        plant["f_s"] = band.f_s
        estimates.append(Estimate("f_s", band.f_s, band.f_s_low, band.f_s_high, "N",
                                  f"stiction band: the middle of {band.sticks} breakaways"))
        if not band.single:
            plant["f_s_spread"] = band.spread
            estimates.append(Estimate("f_s_spread", band.spread, band.spread_low,
                                      band.spread_high, "1",
                                      f"stiction band: its half-width over {band.sticks} "
                                      "breakaways"))
    elif final.draws is None:
        plant["f_s"] = max(bracket.middle, plant["f_c"])
        estimates.append(Estimate("f_s", plant["f_s"], bracket.low, bracket.high, "N",
                                  "rests: largest force held, smallest that moved"))
    if band is None:
        notes.append(f"{len(found)} breakaway(s) from rest by a one-sample pulse: too few for "
                     f"the stiction band (it needs {sticks_needed()}; papwc identify --design "
                     "gives them)")
    if plant["f_s"] * (1.0 - plant.get("f_s_spread", 0.0)) < plant["f_c"]:
        # the model layer's rule: no breakaway below the sliding friction
        plant["f_s_spread"] = max(1.0 - plant["f_c"] / plant["f_s"], 0.0)
        plant["f_c"] = min(plant["f_c"], plant["f_s"])
    if "v_s" in plant:
        plant["delta_s"] = 2.0
    if "ripple_phase" in plant:
        plant["ripple_phase"] = math.remainder(plant["ripple_phase"], 2.0 * math.pi)
    order = ["m", "f_c", "f_s", "f_s_spread", "c", "v_s", "tau_u", "ripple", "ripple_period",
             "ripple_phase"]
    estimates.sort(key=lambda e: order.index(e.name) if e.name in order else len(order))
    plant["x_resolution"] = motion.resolution
    plant["noise_std"] = motion.noise
    estimates.append(Estimate("x_resolution", motion.resolution, motion.resolution,
                              motion.resolution, "m", "encoder: smallest step of the position"))
    estimates.append(Estimate("noise_std", motion.noise, math.nan, math.nan, "m",
                              "encoder: scatter of the position at rest"))
    doing("replaying the log on the identified plant")
    replay_x = replay(log, plant, motion.moved, maker)
    replay_rms = float(np.sqrt(np.mean((replay_x - log.x) ** 2)))
    bound = max(3.0 * motion.resolution, 2.0 * motion.noise, 1e-9)
    residual_rms = math.sqrt(final.rss / max(final.n, 1))
    return Identification(log, motion, bracket, start, plant, estimates, trials, chosen,
                          replay_x, replay_rms, bound, residual_rms,
                          time.perf_counter() - began, rows, notes, band, found, len(sliding),
                          peaks, time.process_time() - cpu_began)


def _bounds(names: Sequence[str], values: Mapping[str, float]
            ) -> tuple[dict[str, float], dict[str, float]]:
    """Bounds of a model's free deviation parameters (the ripple's period near its own)."""
    lower, upper = {}, {}
    for dev in DEVIATIONS:
        for name, low, high in zip(dev.own, dev.lower, dev.upper, strict=True):
            if name in names:
                lower[name], upper[name] = low, high
    if "f_s" in names:
        # at least the sliding friction (a box: f_c is free too, and the simulation holds
        # the breakaway at f_c at least)
        lower["f_s"] = values["f_c"] * (1.0 if "f_c" not in names else 0.9)
        upper["f_s"] = 1e9
    if "ripple_period" in names:
        period = values["ripple_period"]
        lower["ripple_period"] = max(period / RIPPLE_WINDOW, 1e-4)
        upper["ripple_period"] = period * RIPPLE_WINDOW
    return lower, upper


#: Starts of the fit with every deviation ranked by their residual (the grid of the
#: deviations' starts) that are fitted, each for this many evaluations at most.
FULL_STARTS = 8
START_EVALUATIONS = 30


def _fit_full(sim: Simulator, base: Trial, tried: Sequence[Deviation], peaks: Sequence
              ) -> Trial:
    """Eq. (1) with every deviation of ``tried``, every parameter free.

    In stages, each from the one before: Eq. (1) with the ripple from the wavelength search's
    best peak (where the ripple is tried); then the grid of the other deviations' starts
    (and ``f_s``'s, :data:`F_S_STARTS`) ranked by the residual on every other move, the best
    :data:`FULL_STARTS` fitted there for :data:`START_EVALUATIONS` evaluations, and the best
    of those fitted on every move.
    """
    start = dict(base.values)
    names = tuple(base.names)
    ripple = next((d for d in tried if d.name == "ripple"), None)
    if ripple is not None:
        first = [(p.amplitude, p.wavelength, p.phase) for p in peaks
                 if 0.0 < p.amplitude < ripple.upper[0]][:1] or [(0.01, 1e-3, 0.0)]
        start.update(zip(ripple.own, first[0], strict=True))
        names = _names(names, [ripple])
        lower, upper = _bounds(names, start)
        fixed = {k: v for k, v in start.items() if k not in names}
        start = output_error(sim, fixed, names, start, lower=lower, upper=upper,
                             max_nfev=START_EVALUATIONS, tolerance=TRIAL_TOLERANCE).values
    rest = [d for d in tried if d is not ripple]
    if not rest:
        stage = start
    else:
        half = sim.subset(sim.moves[::2]) if len(sim.moves) >= 8 else sim
        grids = [[dict(zip(dev.own, values, strict=True)) for values in dev.starts]
                 for dev in rest]
        grids.append([{"f_s": factor * start["f_c"]} for factor in F_S_STARTS])
        ranked = []
        for combination in itertools.product(*grids):
            p = dict(start)
            for part in combination:
                p.update({k: (v if v > 0.0 else 1e-4) for k, v in part.items()})
            ranked.append((float(np.sum(half.project(half.positions(p) - half.measured) ** 2)),
                           p))
        ranked.sort(key=lambda pair: pair[0])
        names = _names(names, rest)
        best = None
        for _, p in ranked[:FULL_STARTS]:
            lower, upper = _bounds(names, p)
            fixed = {k: v for k, v in p.items() if k not in names}
            trial = output_error(half, fixed, names, p, lower=lower, upper=upper,
                                 max_nfev=START_EVALUATIONS, tolerance=TRIAL_TOLERANCE)
            if best is None or trial.rss < best.rss:
                best = trial
        stage = best.values
    return _with_draws(sim, stage, _names(base.names, tried),
                       "+ " + ", ".join(d.what for d in tried), REFIT_EVALUATIONS)


def _with_draws(sim: Simulator, start: Mapping[str, float], names: Sequence[str], label: str,
                evaluations: int, per_move: bool = False,
                prior: tuple[float, float, float] | None = None) -> Trial:
    """The model ``names`` fitted from ``start``. Where it depends on the breakaway
    (Stribeck, a lag) its moves break away at ``f_s``, fitted too, or, ``per_move``, each at
    its own draw of random stiction, fitted from ``start``'s ``f_s``; elsewhere where they
    break away does not matter (Eq. (1)'s moves start at once)."""
    start = dict(start)
    draws = None
    names = tuple(n for n in names if n != "f_s")
    if not _depends_on_breakaway(start):
        start["f_s"] = start["f_c"]
    elif per_move:
        draws = np.full(len(sim.moves), float(start.get("f_s", start["f_c"])))
    else:
        names += ("f_s",)
        start.setdefault("f_s", 1.3 * start["f_c"])
    lower, upper = _bounds(names, start)
    fixed = {k: v for k, v in start.items() if k not in names}
    return output_error(sim, fixed, names, start, lower=lower, upper=upper, label=label,
                        max_nfev=evaluations, tolerance=FINAL_TOLERANCE, draws=draws,
                        prior=prior if draws is not None else None)


def _names(base: Sequence[str], deviations: Sequence[Deviation]) -> tuple[str, ...]:
    """The free parameters of Eq. (1)'s ``base`` with ``deviations`` (each once)."""
    out = list(base)
    for dev in deviations:
        out += [p for p in dev.parameters if p not in out]
    return tuple(out)


def _without(sim: Simulator, model: Trial, dev: Deviation, others: Sequence[Deviation]
             ) -> Trial:
    """``model`` without ``dev`` (the deviations ``others`` kept), every other parameter
    free, fitted from ``model``'s values (and its moves' draws)."""
    names = _names(("m", "f_c", "c"), others)
    start = {k: v for k, v in model.values.items() if k in names or k not in dev.own}
    for name in dev.own:
        start.pop(name, None)
    return _with_draws(sim, start, names, f"without {dev.name}", TRIAL_EVALUATIONS)
