"""Fitting the friction plant to a log: regression start, output error, deviations, intervals.

1. **Start** (:func:`regression`). While the table slides in one direction ``s`` over two
   sample intervals with the force held over each, Eq. (1) gives exactly (``a =
   exp(-c*h/m)``, ``dx_k = x_{k+1} - x_k``)::

       dx_{k+1} = a*dx_k + p_1*u_k + p_2*u_{k+1} - (p_1 + p_2)*s*f_c,
       p_2 = h^2*phi2(z)/m,  z = c*h/m,

   (``phi2`` of :mod:`papwc.model.stickslip`), linear in ``a``, ``p_1``, ``p_2`` and
   ``(p_1 + p_2)*f_c``: least squares over every such triple of sliding intervals gives
   ``m``, ``c`` and ``f_c``.
2. **Breakaway**: ``f_s`` is the middle of the bracket of the rests
   (:func:`papwc.identify.motion.breakaway_bracket`), its interval the bracket; it is held
   fixed in the output error, so every breakaway and every rest of the log happens in the
   simulation as it did on the machine.
3. **Output error** (:func:`output_error`): the log is cut at every breakaway into moves;
   each move is simulated through :class:`papwc.model.dynamics.Plant` from the measured
   rest before it (``v = 0``; the mean of the rest's positions), with the logged force
   replayed, and ``scipy.optimize.least_squares`` minimizes the sum of the squared
   differences of the simulated and measured positions, each move's mean difference removed
   (its offset, the encoder's error on the rest it starts from, estimated by least squares:
   :meth:`Simulator.project`). Starting every move at its rest keeps the errors of one move
   from accumulating into the next, and keeps the stick-slip switches (breakaways) out of
   the parameters' reach. With the Stribeck curve, ``f_s`` is fitted too (it shapes the
   sliding friction at low speed), below the smallest force that moved the table.
4. **Intervals**: 95 % intervals from the Jacobian at the optimum, ``cov = s^2 (J^T J)^-1``,
   with ``s^2`` the residual variance (at least :data:`SIGMA_FLOOR` squared, the
   integrator's accuracy) and Student's t; widened by :data:`RELATIVE_FLOOR` of the value
   (the optimizer's tolerance).
5. **Deviations** (:func:`identify`): each deviation of :data:`DEVIATIONS` is fitted with
   ``f_c`` and ``c`` on top of the plant chosen so far (its other parameters held), on every
   n-th move (about :data:`TRIAL_SAMPLES` samples in motion), and compared with that plant
   refitted on the same moves with every parameter free; it is added when the F-test of the
   nested models rejects "no improvement" at :data:`ALPHA` and its intervals exclude 0; the
   one with the smallest p-value is added first, then the others are tried again on top of
   it. The plant chosen is refitted with every parameter free on every move.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from papwc.identify import IdentifyError
from papwc.identify.log_file import Log, LogError
from papwc.identify.motion import Bracket, Motion, analyse, breakaway_bracket
from papwc.model.plant import PLANT_PARAMETERS
from papwc.model.stickslip import _phi2, quantize

__all__ = [
    "ALPHA",
    "DEVIATIONS",
    "RELATIVE_FLOOR",
    "SIGMA_FLOOR",
    "Estimate",
    "Identification",
    "Trial",
    "check_log",
    "identify",
    "output_error",
    "regression",
    "replay",
]

#: Significance level of the F-test that adds a deviation.
ALPHA = 0.01
#: Smallest standard deviation of a residual, m: the accuracy of the plant's integrator
#: (papwc.model.dynamics.TOLERANCES), below which an improvement is not one.
SIGMA_FLOOR = 1e-11
#: Unit of the residuals the optimizer sees, m (its gradient test is absolute).
RESIDUAL_UNIT = 1e-6
#: Relative width added to every interval: the optimizer's tolerance.
RELATIVE_FLOOR = 1e-6
#: Most samples in motion that a deviation's trial fit simulates (every n-th move).
TRIAL_SAMPLES = 400

#: Most evaluations and the tolerance of the least squares of a model with a deviation
#: (each evaluation integrates the moves).
TRIAL_EVALUATIONS = 20
TRIAL_TOLERANCE = 1e-5
#: The same for a model fitted again on other samples (from its optimum on the trial's).
REFIT_EVALUATIONS = 5
FINAL_TOLERANCE = 1e-8

_UNITS = {v.name: v.unit for v in PLANT_PARAMETERS}


@dataclass(frozen=True)
class Deviation:
    """A deviation the fit can add: its parameters and their starting values to try."""

    name: str
    parameters: tuple[str, ...]
    starts: tuple[tuple[float, ...], ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    what: str


#: The deviations tried, in order.
DEVIATIONS: tuple[Deviation, ...] = (
    Deviation("stribeck", ("v_s", "f_s"), ((3e-4, math.nan), (1e-3, math.nan), (3e-3, math.nan)),
              (1e-7, math.nan), (10.0, math.nan), "Stribeck curve (v_s, f_s; delta_s held at 2)"),
    Deviation("lag", ("tau_u",), ((5e-4,), (2e-3,), (5e-3,)), (1e-6,), (1.0,),
              "actuator lag (tau_u)"),
)
#: Deviations not tried, and why (for the report).
NOT_TRIED: tuple[tuple[str, str], ...] = (
    ("ripple", "position-dependent friction: its period is not searched (a log of moves "
               "around one place does not span many periods)"),
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


# -- simulation ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Chunk:
    """A move: from the rest at sample ``k0`` (position ``x0``) to sample ``k1``."""

    k0: int
    k1: int
    x0: float


def chunks_of(log: Log, motion: Motion, rest_mean: int = 50) -> list[Chunk]:
    """The moves of the log, each starting at a breakaway and ending at the next one."""
    out = []
    starts = list(motion.breakaways) + [log.x.size - 1]
    moved = motion.moved
    for k0, k1 in zip(starts[:-1], starts[1:], strict=True):
        first = k0
        while first > 0 and not moved[first - 1] and k0 - first < rest_mean:
            first -= 1
        out.append(Chunk(int(k0), int(k1), float(np.mean(log.x[first:k0 + 1]))))
    return out


def lagged_force(u: np.ndarray, h: float, tau_u: float) -> np.ndarray:
    """The lagging actuator's force at the end of each interval (its largest there), N."""
    if tau_u <= 0.0:
        return u
    decay = math.exp(-h / tau_u)
    f = np.empty_like(u)
    f_a = 0.0
    for k, target in enumerate(u):
        f_a = target + (f_a - target) * decay
        f[k] = f_a
    return f


class Simulator:
    """Simulates the moves of a log through :class:`papwc.model.dynamics.Plant`."""

    def __init__(self, log: Log, motion: Motion, chunks: Sequence[Chunk]) -> None:
        self.log = log
        self.motion = motion
        self.chunks = list(chunks)
        self._u = [float(f) for f in log.u]
        self.index = np.concatenate([np.arange(c.k0, c.k1) for c in self.chunks])
        self.measured = log.x[self.index]
        #: Where each move's samples start in :attr:`index`.
        self.starts = np.cumsum([0] + [c.k1 - c.k0 for c in self.chunks[:-1]])
        self._sizes = np.array([c.k1 - c.k0 for c in self.chunks], dtype=float)
        #: Samples less one per move (its offset is estimated): the residual's size.
        self.n = int(self.index.size - len(self.chunks))

    def project(self, r: np.ndarray) -> np.ndarray:
        """``r`` less its mean over each move: each move's offset estimated by least squares.

        The rest a move starts from is known only through the encoder; an error in it
        would shift all of the move's samples alike (correlated errors). Removing each
        move's mean residual fits that offset, so the residual left is the move's shape.
        """
        means = np.add.reduceat(r, self.starts) / self._sizes
        return r - np.repeat(means, self._sizes.astype(int))

    def positions(self, params: Mapping[str, Any]) -> np.ndarray:
        """Simulated positions at :attr:`index` (m)."""
        from papwc.model.dynamics import Plant

        plant = Plant(params)
        u, h = self._u, self.log.h
        out = np.empty(self.index.size)
        i = 0
        for chunk in self.chunks:
            plant.reset()
            plant.x = plant.x_d = chunk.x0
            plant.v = plant.v_d = 0.0
            plant.f_a = u[chunk.k0 - 1] if chunk.k0 > 0 else 0.0
            step = plant.step
            out[i] = chunk.x0
            i += 1
            for k in range(chunk.k0, chunk.k1 - 1):
                reason = step(u[k], h)
                if reason is not None:
                    raise IdentifyError(f"{self.log.source}: the plant refused to simulate "
                                        f"row {k + 1}: {reason}")
                out[i] = plant.x
                i += 1
        return out


def _parameter(name: str) -> Any:
    return next(v for v in PLANT_PARAMETERS if v.name == name)


def output_error(sim: Simulator, fixed: Mapping[str, Any], names: Sequence[str],
                 start: Mapping[str, float], f_s_of: Callable[[dict], float] | None = None,
                 lower: Mapping[str, float] | None = None,
                 upper: Mapping[str, float] | None = None, label: str = "",
                 max_nfev: int = 200, tolerance: float = 1e-12) -> Trial:
    """Least squares on the positions of ``sim`` over the parameters ``names``.

    ``fixed`` holds the other plant parameters; ``f_s_of(values)`` gives ``f_s`` for the
    parameters tried (the bracket under a lagging actuator) when it depends on them.
    """
    from scipy.optimize import least_squares

    lower, upper = dict(lower or {}), dict(upper or {})
    scale = np.array([max(abs(start[n]), 1e-12) for n in names])
    lo = np.array([lower.get(n, max(_parameter(n).min or 0.0, 0.0)) for n in names]) / scale
    hi = np.array([upper.get(n, _parameter(n).max or np.inf) for n in names]) / scale
    theta0 = np.clip(np.ones(len(names)), lo, hi)

    def params_of(theta: np.ndarray) -> dict[str, Any]:
        values = {n: float(t * s) for n, t, s in zip(names, theta, scale, strict=True)}
        p = {**fixed, **values}
        if f_s_of is not None:
            p["f_s"] = f_s_of(p)
        p["f_c"] = min(p["f_c"], p["f_s"])
        return p

    def residual(theta: np.ndarray) -> np.ndarray:
        return sim.project(sim.positions(params_of(theta)) - sim.measured) / RESIDUAL_UNIT

    began = time.perf_counter()
    res = least_squares(residual, theta0, bounds=(lo, hi), method="trf", x_scale=1.0,
                        ftol=tolerance, xtol=tolerance, gtol=1e-14, max_nfev=max_nfev,
                        diff_step=1e-7)
    values = params_of(res.x)
    rss = float(np.sum(res.fun**2)) * RESIDUAL_UNIT**2
    jac = res.jac * RESIDUAL_UNIT / scale[np.newaxis, :]
    return Trial(label, tuple(names), values, rss, sim.n,
                 time.perf_counter() - began, jac, converged=res.status != 0)


def intervals(trial: Trial, n_params: int) -> dict[str, tuple[float, float]]:
    """95 % intervals of a trial's free parameters (see the module)."""
    from scipy.stats import t as student

    dof = max(trial.n - n_params, 1)
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


def replay(log: Log, params: Mapping[str, Any], moved: np.ndarray | None = None) -> np.ndarray:
    """The whole log simulated from its first rest with the force replayed (x_meas, m).

    The encoder's count is applied, its noise is not (the machine's noise is not known).
    The start is the mean of the positions before the first interval that ``moved``.
    """
    from papwc.model.dynamics import Plant

    first = int(np.argmax(moved)) if moved is not None and moved.any() else 0
    x0 = float(np.mean(log.x[:min(first, 50) + 1]))  # the first rest, averaged
    p = {**params, "noise_std": 0.0, "x0": x0, "v0": 0.0}
    plant = Plant(p)
    out = np.empty(log.x.size)
    out[0] = quantize(plant.x, p.get("x_resolution", 0.0))
    for k in range(log.x.size - 1):
        reason = plant.step(float(log.u[k]), log.h)
        if reason is not None:
            raise IdentifyError(f"{log.source}: the identified plant refused to replay row "
                                f"{k + 1}: {reason}")
        out[k + 1] = plant.x_meas()
    return out


# -- the whole identification ---------------------------------------------------------------


def check_log(log: Log) -> None:
    """Refuse a log without motion, without a breakaway or too short (:class:`LogError`)."""
    regression(log, analyse(log))


def _subset(sim: Simulator, samples: int) -> Simulator:
    """A simulator of every n-th move, with about ``samples`` samples in motion (trials)."""
    moving = int(np.count_nonzero(sim.motion.moved[sim.index[sim.index < sim.motion.moved.size]]))
    if moving <= samples:
        return sim
    step = max(2, int(math.ceil(moving / samples)))
    return Simulator(sim.log, sim.motion, sim.chunks[::step])


def identify(log: Log, deviations: Sequence[str] = ("stribeck", "lag"),
             progress: Callable[[str], None] | None = None) -> Identification:
    """Identify the plant of ``log`` (see the module's description).

    Parameters
    ----------
    log : Log
        A checked log (:func:`papwc.identify.log_file.read_log`).
    deviations : sequence of str
        The deviations to try beyond Eq. (1): ``"stribeck"``, ``"lag"``, or none.
    progress : callable, optional
        Called with a line of text at each stage (``papwc identify`` prints them).

    Returns
    -------
    Identification
        The identified ``plant`` parameters, each ``estimates`` entry with its 95 %
        interval, the models tried, the replay of the log and its residual.

    Raises
    ------
    LogError
        If the log holds no motion, no breakaway, or too few sliding samples.

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
    >>> abs(found.plant["f_s"] - 130.0) <= 0.01 * 130.0, found.chosen
    (True, [])
    """
    from papwc.progress import doing

    say = progress or (lambda text: None)
    began = time.perf_counter()
    doing("finding the moves and rests in the log")
    motion = analyse(log)
    start, rows = regression(log, motion)
    say(f"regression on {rows} sliding triples: m = {start['m']:.6g} kg, f_c = "
        f"{start['f_c']:.6g} N, c = {start['c']:.6g} N.s/m")
    bracket = breakaway_bracket(motion, log.u)
    f_s = bracket.middle
    if bracket.low_k < 0:
        bracket = Bracket(min(start["f_c"], bracket.high), bracket.high, -1, bracket.high_k)
        f_s = bracket.middle
    say(f"breakaway between {bracket.low:.6g} N (held) and {bracket.high:.6g} N (moved)")
    sim = Simulator(log, motion, chunks_of(log, motion))
    fixed = {"f_s": f_s}
    base_names = ("m", "f_c", "c")
    upper = {"f_c": f_s}
    doing("output error, Eq. (1): fitting m, f_c, c")
    base = output_error(sim, fixed, base_names, {**start, "f_c": min(start["f_c"], f_s)},
                        upper=upper, label="Eq. (1): m, f_c, c")
    say(f"output error, Eq. (1): rss = {base.rss:.4g} m^2 in {base.seconds:.3g} s")
    trials = [base]
    current = base
    chosen: list[str] = []
    candidates = [d for d in DEVIATIONS if d.name in deviations]
    trial_sim = _subset(sim, TRIAL_SAMPLES)
    notes = []
    if trial_sim is not sim:
        notes.append(f"the deviations' trials fit {len(trial_sim.chunks)} of the "
                     f"{len(sim.chunks)} moves (evenly spread); the chosen model is refitted "
                     "on all")
    while candidates:
        # The current model on the trial samples, for a fair comparison.
        names = current.names
        # (From the refit with every parameter free: a trial holds some of them, and a
        # deviation must not be credited with what freeing them gains.)
        if trial_sim is not sim:
            doing(f"refitting {current.label} on the trial moves")
        current_here = current if trial_sim is sim else _refit(
            trial_sim, current, bracket, current.label, TRIAL_TOLERANCE)
        results = []
        for dev in candidates:
            doing(f"trying {dev.name}: {dev.what}")
            trial = _fit_deviation(trial_sim, current_here, dev, bracket)
            extra = len([p for p in dev.parameters if p not in names])
            trial.f_stat, trial.p_value = f_test(current_here, trial, extra,
                                                 len(names) + extra)
            ci = intervals(trial, len(trial.names))
            ok = trial.p_value < ALPHA and all(ci[p][0] > 0.0 for p in dev.parameters)
            if ok:
                trial.why = (f"F = {trial.f_stat:.4g}, p = {trial.p_value:.3g} < {ALPHA}: "
                             "lowers the residual beyond the noise")
            elif trial.p_value >= ALPHA:
                trial.why = (f"F = {trial.f_stat:.4g}, p = {trial.p_value:.3g} >= {ALPHA}: "
                             "no improvement beyond the noise")
            else:
                trial.why = (f"F = {trial.f_stat:.4g}, p = {trial.p_value:.3g}, but a 95 % "
                             "interval of its parameters includes 0")
            say(f"tried {dev.name}: {trial.why} ({trial.seconds:.3g} s)")
            trials.append(trial)
            results.append((dev, trial, ok))
        good = [(dev, trial) for dev, trial, ok in results if ok]
        if not good:
            break
        dev, best = min(good, key=lambda pair: pair[1].p_value)
        best.chosen = True
        chosen.append(dev.name)
        candidates = [d for d in candidates if d is not dev]
        # The chosen model with every parameter free (the trial held some), on every move.
        doing(f"refitting with {dev.name}, every parameter free, on every move")
        current = _refit(sim, best, bracket, best.label + " (all free, all moves)",
                         FINAL_TOLERANCE)
        trials.append(current)
        current.chosen = True
        current.why = "the chosen model refitted, every parameter free, on every move"
        say(f"refitted with {dev.name} on every move ({current.seconds:.3g} s)")
    final = current
    if not final.converged:
        notes.append(f"the final fit ({final.label}) stopped at its limit of "
                     f"{REFIT_EVALUATIONS} evaluations before its tolerance: its intervals are "
                     "those of a converged fit and may be too narrow")
    final.chosen = True
    if not final.why:
        final.why = "the model chosen"
    lag = final.values.get("tau_u", 0.0)
    if lag > 0.0:
        bracket = breakaway_bracket(motion, lagged_force(log.u, log.h, lag))
    ci = intervals(final, len(final.names))
    estimates = []
    for name in final.names:
        low, high = ci[name]
        estimates.append(Estimate(name, final.values[name], max(low, 0.0), high, _UNITS[name],
                                  "output error"))
    if "f_s" not in final.names:
        estimates.insert(2, Estimate("f_s", final.values["f_s"], bracket.low, bracket.high,
                                     "N", "rests: largest force held, smallest that moved"))
    order = ["m", "f_c", "f_s", "c"]
    estimates.sort(key=lambda e: order.index(e.name) if e.name in order else len(order))
    plant = {name: final.values[name] for name in final.names}
    plant["f_s"] = final.values["f_s"]
    plant["f_c"] = min(plant["f_c"], plant["f_s"])
    if "v_s" in plant:
        plant["delta_s"] = 2.0
    plant["x_resolution"] = motion.resolution
    plant["noise_std"] = motion.noise
    estimates.append(Estimate("x_resolution", motion.resolution, motion.resolution,
                              motion.resolution, "m", "encoder: smallest step of the position"))
    estimates.append(Estimate("noise_std", motion.noise, math.nan, math.nan, "m",
                              "encoder: scatter of the position at rest"))
    doing("replaying the log on the identified plant")
    replay_x = replay(log, plant, motion.moved)
    replay_rms = float(np.sqrt(np.mean((replay_x - log.x) ** 2)))
    bound = max(3.0 * motion.resolution, 2.0 * motion.noise, 1e-9)
    residual_rms = math.sqrt(final.rss / max(final.n, 1))
    return Identification(log, motion, bracket, start, plant, estimates, trials, chosen,
                          replay_x, replay_rms, bound, residual_rms,
                          time.perf_counter() - began, rows, notes)


def _model(names: Sequence[str], values: Mapping[str, float], bracket: Bracket,
           log: Log, motion: Motion
           ) -> tuple[dict[str, float], dict[str, float], Callable[[dict], float] | None]:
    """Bounds of a model's free parameters and its ``f_s`` as a function of them (or None).

    A fitted ``f_s`` (with the Stribeck curve) lies below the smallest force that moved the
    table from rest; under a lagging actuator ``f_s`` is the bracket of the lagged force.
    """
    lower, upper = {}, {}
    for dev in DEVIATIONS:
        for name, low, high in zip(dev.parameters, dev.lower, dev.upper, strict=True):
            if name in names and not math.isnan(low):
                lower[name], upper[name] = low, high
    f_s_of = None
    if "f_s" in names:
        lower["f_s"], upper["f_s"] = 0.5 * bracket.low, bracket.high
        upper["f_c"] = bracket.high
    elif "tau_u" in names and "v_s" not in values:
        def f_s_of(p: dict) -> float:
            return breakaway_bracket(motion, lagged_force(log.u, log.h, p["tau_u"])).middle
    else:
        upper["f_c"] = values["f_s"]
    return lower, upper, f_s_of


def _refit(sim: Simulator, trial: Trial, bracket: Bracket, label: str, tolerance: float
           ) -> Trial:
    """``trial``'s model fitted again on ``sim``, from its values."""
    names = ("m", "f_c", "c") + (("v_s", "f_s") if "v_s" in trial.values else ()) + (
        ("tau_u",) if "tau_u" in trial.values else ())
    lower, upper, f_s_of = _model(names, trial.values, bracket, sim.log, sim.motion)
    fixed = {k: v for k, v in trial.values.items() if k not in names}
    return output_error(sim, fixed, names, trial.values, f_s_of, lower=lower, upper=upper,
                        label=label, max_nfev=REFIT_EVALUATIONS, tolerance=tolerance)


def _fit_deviation(sim: Simulator, current: Trial, dev: Deviation, bracket: Bracket) -> Trial:
    """Fit ``dev`` on top of ``current``: the best of its starts, then least squares."""
    # A trial fits the deviation's parameters with f_c and c; the mass and the deviations
    # chosen before are held at the current model's values (they are free again in the refit
    # of the chosen model).
    names = ("f_c", "c") + tuple(p for p in dev.parameters if p not in ("f_c", "c"))
    values = dict(current.values)
    lower, upper, f_s_of = _model(names, values, bracket, sim.log, sim.motion)
    best, best_rss = None, math.inf
    for start in dev.starts:
        p = {**values, **{n: v for n, v in zip(dev.parameters, start, strict=True)
                          if not math.isnan(v)}}
        if f_s_of is not None:
            p["f_s"] = f_s_of(p)
        p["f_c"] = min(p["f_c"], p["f_s"])
        rss = float(np.sum(sim.project(sim.positions(p) - sim.measured) ** 2))
        if rss < best_rss:
            best, best_rss = p, rss
    fixed = {k: v for k, v in best.items() if k not in names}
    return output_error(sim, fixed, names, best, f_s_of, lower=lower, upper=upper,
                        label=f"+ {dev.what}", max_nfev=TRIAL_EVALUATIONS,
                        tolerance=TRIAL_TOLERANCE)
