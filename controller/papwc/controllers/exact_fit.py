"""The fit of the exact-model controller: m, f_c and c of Eq. (3) and a bracket of f_s.

:class:`PulseModelEstimator` keeps a history of pulses (samples, height, measured
displacement) and fits Eq. (3) (:func:`papwc.model.pulse.pulse_displacement`) to it by
a small regularized, weighted least-squares problem (Levenberg-Marquardt); the
controller is :class:`papwc.controllers.exact.ExactController`.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..model.pulse import pulse_displacement
from .budget import Ops
from .sequencer import Z_DECIDE

__all__ = ["JOB_FIELDS", "PulseModelEstimator"]

#: A fit from a fresh start replaces the one continued from the current estimate only if
#: its cost is below this fraction of the other's.
_RESTART_GAIN = 0.01
#: Where a pulse that did not move contradicts the f_s bracket, the new upper end of it
#: relative to the new lower end.
_F_S_EXPAND = 1.1
#: Relative standard deviation of a measured displacement (model and rounding).
_SIGMA_REL = 1e-6
#: Smallest standard deviation of a measured displacement, m.
_SIGMA_MIN = 1e-15
#: Prior standard deviations of log(m), log(f_c) and c/c_scale.
_SIGMA_PRIOR = (0.5, 0.5, 1.0)
#: Bounds of the fit variables: log(m/m_est), log(f_c/f_c_est), c/c_scale.
_THETA_BOUNDS = ((-3.0, 3.0), (-3.0, 3.0), (0.0, 50.0))
#: Smallest relative error assumed for a planned pulse (model and rounding).
_MISFIT_MIN = 1e-9
#: The numbers of a fit under way (:attr:`PulseModelEstimator.job`): the start (0: from the
#: estimate, 1: from the settings' estimates, 2: those with c = c_scale, 3: every start made),
#: the Levenberg-Marquardt iterations made in it (-1: not begun), its damping, theta and cost,
#: whether a best was found (1) and that theta and cost.
JOB_FIELDS = ("start", "iteration", "mu", "theta_m", "theta_f_c", "theta_c", "cost", "found",
              "best_m", "best_f_c", "best_c", "best_cost")


def _solve3(a: list[list[float]], b: list[float]) -> list[float] | None:
    """Solution of a 3x3 linear system by Gaussian elimination with pivoting (None if singular)."""
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for col in range(3):
        piv = max(range(col, 3), key=lambda r: abs(m[r][col]))
        if not (abs(m[piv][col]) > 0.0 and math.isfinite(m[piv][col])):
            return None
        m[col], m[piv] = m[piv], m[col]
        for r in range(col + 1, 3):
            f = m[r][col] / m[col][col]
            for k in range(col, 4):
                m[r][k] -= f * m[col][k]
    x = [0.0, 0.0, 0.0]
    for r in (2, 1, 0):
        s = m[r][3] - sum(m[r][k] * x[k] for k in range(r + 1, 3))
        x[r] = s / m[r][r]
    return x if all(math.isfinite(v) for v in x) else None


class PulseModelEstimator:
    """Estimates of m, f_c, c (Eq. (3)) and a bracket of f_s from a history of pulses.

    The fit minimizes, over ``theta = (log(m/m_est), log(f_c/f_c_est), c/c_scale)``,
    ::

        sum_i ((d_model(f_i, n_i*T; theta) - d_i) / sigma_i)**2
            + sum_j ((theta_j - theta0_j) / sigma_prior_j)**2

    with ``sigma_i = 1e-6*d_i + x_resolution + meas_sigma`` (m; ``meas_sigma``
    the standard deviation of a displacement measured with a noisy encoder, set
    by the controller), by Levenberg-Marquardt steps
    from the current estimate. The prior term keeps the directions that the
    pulses do not determine (e.g. all pulses of one shape) at the initial
    estimates, and every estimate stays inside fixed bounds.

    Parameters
    ----------
    m_est : float
        Initial estimate of the mass, kg (> 0).
    f_c_est : float
        Initial estimate of the Coulomb friction, N (> 0).
    c_est : float
        Initial estimate of the viscous damping, N.s/m (>= 0).
    T : float
        Sample period, s.
    f_p_max : float
        Largest pulse height, N (upper end of the f_s bracket).
    history : int
        Number of pulses kept for the fit (>= 1).
    x_resolution : float
        Resolution of the position measurement, m (>= 0; 0 for an ideal one).
    iterations : int
        Levenberg-Marquardt iterations per start of a fit.
    ops : Ops, optional
        The operations counter of the controller's update (:mod:`papwc.controllers.budget`);
        without one, every fit is made at once.

    Attributes
    ----------
    job : list of float
        The fit under way (:data:`JOB_FIELDS`; empty: none): after a pulse, the fit goes on
        over as many updates as the budget asks (:meth:`advance`), the estimate
        (``theta``) the last one completed.
    """

    def __init__(self, m_est: float, f_c_est: float, c_est: float, T: float, f_p_max: float,
                 history: int = 16, x_resolution: float = 0.0, iterations: int = 12,
                 ops: Ops | None = None) -> None:
        self.m_est = float(m_est)
        self.f_c_est = float(f_c_est)
        self.T = float(T)
        self.f_p_max = float(f_p_max)
        self.c_scale = self.m_est / (10.0 * self.T)
        self.size = int(history)
        self.x_resolution = float(x_resolution)
        self.iterations = int(iterations)
        #: Standard deviation of a measured displacement from the encoder noise, m.
        self.meas_sigma = 0.0
        self.theta0 = (0.0, 0.0, self._clip(2, float(c_est) / self.c_scale))
        self.theta = list(self.theta0)
        #: Highest height known not to move the mass and lowest known to move it, N.
        self.f_s_lo = 0.0
        self.f_s_hi = self.f_p_max
        #: Pulses (n, abs(f_p) in N, displacement along f_p in m), oldest first.
        self.pulses: list[tuple[int, float, float]] = []
        #: Relative misfit of the model over the history beyond the measurement
        #: resolution (root mean square, at least ``_MISFIT_MIN``).
        self.rel_misfit = _MISFIT_MIN
        self.ops = ops if ops is not None else Ops()
        self.job: list[float] = []

    # -- parameters --------------------------------------------------------------------
    @staticmethod
    def _clip(j: int, value: float) -> float:
        lo, hi = _THETA_BOUNDS[j]
        return min(max(value, lo), hi)

    def prior_distance(self) -> float:
        """How far the estimate lies from the settings' estimates, in prior standard
        deviations (the largest over log(m), log(f_c) and c/c_scale)."""
        return max(abs(th - th0) / sigma
                   for th, th0, sigma in zip(self.theta, self.theta0, _SIGMA_PRIOR, strict=True))

    def params(self, theta: list[float] | tuple[float, ...] | None = None) -> tuple[float, ...]:
        """``(m, f_c, c)`` in kg, N, N.s/m for ``theta`` (default: the current estimate)."""
        th = self.theta if theta is None else theta
        return (
            self.m_est * math.exp(th[0]),
            self.f_c_est * math.exp(th[1]),
            self.c_scale * th[2],
        )

    @property
    def m_hat(self) -> float:
        """Estimated mass, kg."""
        return self.params()[0]

    @property
    def f_c_hat(self) -> float:
        """Estimated Coulomb friction, N."""
        return self.params()[1]

    @property
    def c_hat(self) -> float:
        """Estimated viscous damping, N.s/m."""
        return self.params()[2]

    @property
    def widest(self) -> int:
        """Most samples of a pulse in the history (0 without pulses)."""
        return max((n for n, _, _ in self.pulses), default=0)

    def displacement(self, f_p: float, n: int) -> float:
        """Predicted displacement of a pulse of height f_p (N) and n samples, Eq. (3), m."""
        m, f_c, c = self.params()
        self.ops.eq3 += 1
        return pulse_displacement(f_p, n * self.T, m, f_c, c)

    def _theta2_max(self) -> float:
        # f_c <= f_s < f_s_hi: a height that moved the mass lies above f_c.
        cap = math.log(self.f_s_hi * (1.0 - 1e-9) / self.f_c_est)
        return max(min(_THETA_BOUNDS[1][1], cap), _THETA_BOUNDS[1][0])

    # -- observations ------------------------------------------------------------------
    def observe(self, n: int, f_p: float, d: float, reserve: int | None = None) -> None:
        """Take one pulse: n samples of height f_p (N, signed), displacement d (m, signed).

        A pulse whose displacement along f_p is zero or negative (at most
        ``3*meas_sigma``, with a noisy encoder) did not break the mass away: it
        raises ``f_s_lo`` (and, if that reaches ``f_s_hi``, the breakaway force
        is sought anew up to ``1.1*f_s_lo``). A pulse that
        moved lowers ``f_s_hi``, joins the history and the model is refitted: at once
        (``reserve`` None), or as far as the update's operations allow after ``reserve`` of
        them, the rest at the next updates (:meth:`advance`).
        Non-finite or meaningless observations are ignored.
        """
        if not (math.isfinite(f_p) and math.isfinite(d)) or f_p == 0.0 or n < 1:
            return
        f = min(abs(f_p), self.f_p_max)
        d_along = d if f_p > 0.0 else -d
        if d_along > Z_DECIDE * self.meas_sigma:
            if f <= 1.01 * self.f_c_est * math.exp(_THETA_BOUNDS[1][0]):
                return  # far below any Coulomb friction the fit allows: not credible
            self.f_s_hi = min(self.f_s_hi, f)
            if self.f_s_lo >= self.f_s_hi:
                self.f_s_lo = 0.0  # contradicting observations: forget the lower bound
            self._remember(int(n), f, d_along)
            self.begin_fit()
            if reserve is None:
                self.finish_fit()
            else:
                self.advance(reserve)
        else:
            self.f_s_lo = max(self.f_s_lo, f)
            if self.f_s_lo >= self.f_s_hi:
                # The breakaway force here is above where the mass moved before (it
                # varies along the way): look for it just above the new lower bound.
                self.f_s_hi = min(self.f_p_max, _F_S_EXPAND * self.f_s_lo)
                self.f_s_lo = min(self.f_s_lo, self.f_s_hi * (1.0 - 1e-6))

    def _remember(self, n: int, f: float, d: float) -> None:
        """Append a pulse; when full, drop the oldest of the same width (else the oldest)."""
        if self.size <= 0:
            return
        if len(self.pulses) >= self.size:
            same = [i for i, p in enumerate(self.pulses) if p[0] == n]
            drop = same[0] if len(same) >= 2 else 0
            del self.pulses[drop]
        self.pulses.append((n, f, d))

    # -- the fit -----------------------------------------------------------------------
    def _residuals(self, theta: list[float]) -> list[float] | None:
        m, f_c, c = self.params(theta)
        self.ops.eq3 += len(self.pulses)
        out = []
        for n, f, d in self.pulses:
            sigma = _SIGMA_REL * d + self.x_resolution + self.meas_sigma + _SIGMA_MIN
            try:
                r = (pulse_displacement(f, n * self.T, m, f_c, c) - d) / sigma
            except (ValueError, OverflowError, ZeroDivisionError):
                # A difference quotient at theta_3 = 0 evaluates c < 0, where coasting
                # may never end (log of a negative number): no residual there.
                return None
            if not math.isfinite(r):
                return None
            out.append(r)
        for j in range(3):
            out.append((theta[j] - self.theta0[j]) / _SIGMA_PRIOR[j])
        return out

    def fit(self) -> None:
        """Refit the model to the history at once (:meth:`begin_fit`, :meth:`finish_fit`)."""
        self.begin_fit()
        self.finish_fit()

    def begin_fit(self) -> None:
        """Start a fit of the history: Levenberg-Marquardt iterations, the best of three starts.

        From the current estimate (or, where a fit is under way, from where it got), and from
        the initial one and the initial one with ``c = c_scale``, whose result is taken only
        when it explains the pulses far better (cost below ``_RESTART_GAIN`` times the
        other's): a fit that ran into a bound (``c = 0`` after a few pulses of one shape) is
        not kept there by the next pulses. With an encoder (``x_resolution > 0``) or noise
        measured (``meas_sigma > 0``) the fit is only continued: a fresh start would chase the
        rounding and the noise. :meth:`advance` makes it.
        """
        job = self.job
        if job and job[0] == 0.0:
            theta = job[3:6]  # the fit under way, continued on the longer history
        elif job and job[7]:
            theta = job[8:11]
        else:
            theta = self.theta
        self.job = [0.0, -1.0, 0.0, *(float(v) for v in theta), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

    def finish_fit(self) -> None:
        """Make the fit under way to its end, whatever it costs."""
        while self.job:
            self.advance(None)

    def lm_cost(self) -> int:
        """Most Eq. (3) evaluations a step of the fit makes: the residuals it starts from,
        one Levenberg-Marquardt iteration (its Jacobian by central differences and at most
        12 trial steps) and the misfit of the estimate it leaves: 21 evaluations of the
        history."""
        return 21 * max(len(self.pulses), 1)

    def advance(self, reserve: int | None = 0) -> None:
        """Go on with the fit under way, while the update's operations allow (keeping
        ``reserve`` of them; None: to its end).

        A step is the residuals of a start or one Levenberg-Marquardt iteration, each at
        most :meth:`lm_cost` evaluations of Eq. (3) with the misfit of the estimate. The
        estimate is the best of the starts made, and while the first (from the estimate
        before the pulse) is under way, its present iterate (it explains the pulses better
        than the estimate it started from): a plan made before the fit's end uses that. The
        end is the same as a fit made at once (:meth:`fit`) when nothing changes meanwhile.
        """
        job = self.job
        r: list[float] | None = None
        while job:
            if reserve is not None and self.ops.left() - reserve < self.lm_cost():
                if job[0] == 0.0 and job[1] > 0.0 and job[3:6] != self.theta:
                    # the first start under way: its iterate is the estimate until it ends
                    self.theta = job[3:6]
                    self.rel_misfit = self._misfit()
                return
            start, k = int(job[0]), int(job[1])
            if start == 3:
                self.job = []  # every start made: the best is the estimate
                return
            if k < 0:
                theta = job[3:6] if start == 0 else list(self.theta0)
                if start == 2:
                    theta[2] = 1.0
                theta = [self._clip(j, theta[j]) for j in range(3)]
                theta[1] = min(theta[1], self._theta2_max())
                r = self._residuals(theta)
                if r is None:
                    self._start_done(job, None)
                    continue
                job[1], job[2], job[3:6] = 0.0, 1e-3, theta
                job[6] = sum(q * q for q in r)
                if self.iterations <= 0:
                    self._start_done(job, (job[3:6], job[6]))
                continue
            if r is None:
                r = self._residuals(job[3:6])
                if r is None:  # (the history changed under it: as the start's end)
                    self._start_done(job, (job[3:6], job[6]))
                    continue
            r, done = self._lm_iteration(job, r)
            job[1] = k + 1.0
            if done or k + 1 >= self.iterations:
                self._start_done(job, (job[3:6], job[6]))
                r = None

    def _start_done(self, job: list[float], found: tuple[list[float], float] | None) -> None:
        """A start of the fit under way ended at ``found`` (theta and cost; None: no
        residuals there): keep the best, go on with the next start."""
        start = int(job[0])
        if found is not None and (start == 0 or not job[7]
                                  or found[1] < _RESTART_GAIN * job[11]):
            # the best so far is the estimate from now on (a plan made before the fit's
            # end uses it)
            job[7], job[8:11], job[11] = 1.0, list(found[0]), found[1]
            self.theta = list(found[0])
            self.rel_misfit = self._misfit()
        elif start == 0:
            self.rel_misfit = self._misfit()
        exact_sensor = self.meas_sigma == 0.0 and self.x_resolution == 0.0
        job[0] = start + 1.0 if exact_sensor else 3.0
        job[1] = -1.0

    def _lm_iteration(self, job: list[float], r: list[float]) -> tuple[list[float], bool]:
        """One Levenberg-Marquardt iteration of the start under way (``job``: its theta,
        cost and damping, updated), from its residuals r: the residuals it ends at, and
        whether the start has ended (no step lowered the cost, or the step was below
        1e-14)."""
        theta, cost, mu = job[3:6], job[6], job[2]
        h = 1e-6
        jac: list[list[float]] = []
        for j in range(3):
            tp, tm = list(theta), list(theta)
            tp[j] += h
            tm[j] -= h
            rp, rm = self._residuals(tp), self._residuals(tm)
            if rp is None or rm is None:
                return r, True
            jac.append([(a - b) / (2.0 * h) for a, b in zip(rp, rm, strict=True)])
        jtj = [[sum(a * b for a, b in zip(jac[i], jac[k], strict=True)) for k in range(3)]
               for i in range(3)]
        jtr = [sum(a * b for a, b in zip(jac[i], r, strict=True)) for i in range(3)]
        improved = False
        moved = 0.0
        for _ in range(12):
            lhs = [[jtj[i][k] + (mu * jtj[i][i] if i == k else 0.0) for k in range(3)]
                   for i in range(3)]
            step = _solve3(lhs, [-g for g in jtr])
            if step is None:
                mu *= 10.0
                continue
            trial = [self._clip(j, theta[j] + step[j]) for j in range(3)]
            trial[1] = min(trial[1], self._theta2_max())
            r_trial = self._residuals(trial)
            if r_trial is not None:
                cost_trial = sum(q * q for q in r_trial)
                if cost_trial < cost:
                    moved = max(abs(a - b) for a, b in zip(trial, theta, strict=True))
                    theta, r, cost = trial, r_trial, cost_trial
                    mu = max(mu / 10.0, 1e-12)
                    improved = True
                    break
            mu *= 10.0
        job[2], job[3:6], job[6] = mu, theta, cost
        return r, not improved or moved < 1e-14

    def _misfit(self) -> float:
        """Root mean square of the relative model errors beyond the resolution.

        Each pulse's term is capped at 1; the result is at least ``_MISFIT_MIN``.
        """
        if not self.pulses:
            return _MISFIT_MIN
        m, f_c, c = self.params()
        self.ops.eq3 += len(self.pulses)
        total = 0.0
        for n, f, d in self.pulses:
            err = (abs(pulse_displacement(f, n * self.T, m, f_c, c) - d) - self.x_resolution
                   - Z_DECIDE * self.meas_sigma)
            total += min(max(err, 0.0) / d, 1.0) ** 2
        value = math.sqrt(total / len(self.pulses))
        return max(value, _MISFIT_MIN) if math.isfinite(value) else 1.0

    # -- state -------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """Everything that evolves, by name: ``theta`` (3 numbers), ``f_s_lo``, ``f_s_hi``
        (N), ``rel_misfit``, ``pulses`` (n, abs(f_p), d of each, flat, oldest first) and
        ``job`` (the fit under way, :data:`JOB_FIELDS`; empty: none)."""
        return {"theta": [float(v) for v in self.theta], "f_s_lo": self.f_s_lo,
                "f_s_hi": self.f_s_hi, "rel_misfit": self.rel_misfit,
                "pulses": [float(v) for p in self.pulses for v in p],
                "job": [float(v) for v in self.job]}

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state` (ValueError if it does not fit)."""
        theta = [float(q) for q in values["theta"]]
        flat = [float(q) for q in values["pulses"]]
        job = [float(q) for q in values["job"]]
        if len(theta) != 3 or len(flat) % 3 or len(flat) > 3 * self.size:
            raise ValueError(f"estimator state: theta holds {len(theta)} numbers (3), pulses "
                             f"{len(flat)} (a multiple of 3, at most {3 * self.size})")
        if job and not (len(job) == len(JOB_FIELDS) and job[0] in (0.0, 1.0, 2.0, 3.0)):
            raise ValueError(f"estimator state: job holds {len(job)} numbers ({len(JOB_FIELDS)}: "
                             f"{', '.join(JOB_FIELDS)}, start 0 to 3) or none")
        self.job = job
        self.theta = theta
        self.f_s_lo, self.f_s_hi = float(values["f_s_lo"]), float(values["f_s_hi"])
        self.rel_misfit = float(values["rel_misfit"])
        self.pulses = [(int(flat[i]), flat[i + 1], flat[i + 2]) for i in range(0, len(flat), 3)]
