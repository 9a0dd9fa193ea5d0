"""Pulse control on the exact pulse model, Eq. (3), learned from the controller's own pulses.

PAPWC (Section 3) plans with the Coulomb-only model (4) and cannot move the mass
less than one sample at the stiction force, Eq. (20). This controller

* predicts a pulse's displacement with Eq. (3) (Eq. (2) at c = 0),
  :func:`papwc.model.pulse.pulse_displacement`;
* learns m, f_c and c from the measured displacements of its recent pulses by a
  small regularized least-squares fit (Levenberg-Marquardt), and brackets the
  breakaway force f_s between the highest amplitude that did not move the mass
  and the lowest that did;
* plans the fastest pulse: the fewest samples n whose required amplitude lies in
  [f_floor, f_p_max], the amplitude solving Eq. (3) exactly for the error;
* moves less than its smallest single pulse by two pulses: out by
  ``|e| + d_back``, then back by ``d_back``;
* stops pulsing once ``|e| <= tolerance``, once ``|e|`` is below what a move
  can achieve (half the encoder resolution, or the model's relative misfit times
  the move), and after ``max_pulses`` pulses in one maneuver at the latest, so
  it cannot limit-cycle.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math

from ..model.pulse import b_coulomb, pulse_amplitude, pulse_displacement
from .base import Controller, Mode
from .settings import ControllerSettings

__all__ = ["ExactController", "PulseModelEstimator"]

#: Relative size of the back pulse of a two-pulse move above the smallest single pulse.
_MARGIN = 0.5
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
#: Largest pulse width searched, samples.
_N_SEARCH_MAX = 1 << 20


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

    with ``sigma_i = 1e-6*d_i + x_resolution`` (m), by Levenberg-Marquardt steps
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
        Levenberg-Marquardt iterations per new pulse.
    """

    def __init__(
        self,
        m_est: float,
        f_c_est: float,
        c_est: float,
        T: float,
        f_p_max: float,
        history: int = 16,
        x_resolution: float = 0.0,
        iterations: int = 12,
    ) -> None:
        self.m_est = float(m_est)
        self.f_c_est = float(f_c_est)
        self.T = float(T)
        self.f_p_max = float(f_p_max)
        self.c_scale = self.m_est / (10.0 * self.T)
        self.size = int(history)
        self.x_resolution = float(x_resolution)
        self.iterations = int(iterations)
        self.theta0 = (0.0, 0.0, self._clip(2, float(c_est) / self.c_scale))
        self.theta = list(self.theta0)
        #: Highest height known not to move the mass and lowest known to move it, N.
        self.f_s_lo = 0.0
        self.f_s_hi = self.f_p_max
        #: Pulses (n, |f_p| in N, displacement along f_p in m), oldest first.
        self.pulses: list[tuple[int, float, float]] = []
        #: Relative misfit of the model over the history beyond the measurement
        #: resolution (root mean square, at least ``_MISFIT_MIN``).
        self.rel_misfit = _MISFIT_MIN

    # -- parameters --------------------------------------------------------------------
    @staticmethod
    def _clip(j: int, value: float) -> float:
        lo, hi = _THETA_BOUNDS[j]
        return min(max(value, lo), hi)

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

    def displacement(self, f_p: float, n: int) -> float:
        """Predicted displacement of a pulse of height f_p (N) and n samples, Eq. (3), m."""
        m, f_c, c = self.params()
        return pulse_displacement(f_p, n * self.T, m, f_c, c)

    def _theta2_max(self) -> float:
        # f_c <= f_s < f_s_hi: a height that moved the mass lies above f_c.
        cap = math.log(self.f_s_hi * (1.0 - 1e-9) / self.f_c_est)
        return max(min(_THETA_BOUNDS[1][1], cap), _THETA_BOUNDS[1][0])

    # -- observations ------------------------------------------------------------------
    def observe(self, n: int, f_p: float, d: float) -> None:
        """Take one pulse: n samples of height f_p (N, signed), displacement d (m, signed).

        A pulse whose displacement along f_p is zero (or negative) did not break
        the mass away: it raises ``f_s_lo``. A pulse that moved lowers
        ``f_s_hi``, joins the history and the model is refitted. Non-finite or
        meaningless observations are ignored.
        """
        if not (math.isfinite(f_p) and math.isfinite(d)) or f_p == 0.0 or n < 1:
            return
        f = min(abs(f_p), self.f_p_max)
        d_along = d if f_p > 0.0 else -d
        if d_along > 0.0:
            if f <= 1.01 * self.f_c_est * math.exp(_THETA_BOUNDS[1][0]):
                return  # far below any Coulomb friction the fit allows: not credible
            self.f_s_hi = min(self.f_s_hi, f)
            if self.f_s_lo >= self.f_s_hi:
                self.f_s_lo = 0.0  # contradicting observations: forget the lower bound
            self._remember(int(n), f, d_along)
            self.fit()
        else:
            self.f_s_lo = max(self.f_s_lo, f)
            if self.f_s_lo >= self.f_s_hi:
                self.f_s_hi = self.f_p_max
                self.f_s_lo = min(self.f_s_lo, self.f_p_max * (1.0 - 1e-6))

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
        out = []
        for n, f, d in self.pulses:
            sigma = _SIGMA_REL * d + self.x_resolution + _SIGMA_MIN
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
        """Levenberg-Marquardt iterations from the current estimate over the history."""
        theta = list(self.theta)
        theta[1] = min(theta[1], self._theta2_max())
        r = self._residuals(theta)
        if r is None:
            return
        cost = sum(q * q for q in r)
        mu = 1e-3
        h = 1e-6
        for _ in range(self.iterations):
            jac: list[list[float]] = []
            for j in range(3):
                tp, tm = list(theta), list(theta)
                tp[j] += h
                tm[j] -= h
                rp, rm = self._residuals(tp), self._residuals(tm)
                if rp is None or rm is None:
                    return
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
            if not improved or moved < 1e-14:
                break
        self.theta = theta
        self.rel_misfit = self._misfit()

    def _misfit(self) -> float:
        """Root mean square of the relative model errors beyond the resolution.

        Each pulse's term is capped at 1; the result is at least ``_MISFIT_MIN``.
        """
        if not self.pulses:
            return _MISFIT_MIN
        m, f_c, c = self.params()
        total = 0.0
        for n, f, d in self.pulses:
            err = abs(pulse_displacement(f, n * self.T, m, f_c, c) - d) - self.x_resolution
            total += min(max(err, 0.0) / d, 1.0) ** 2
        value = math.sqrt(total / len(self.pulses))
        return max(value, _MISFIT_MIN) if math.isfinite(value) else 1.0

    # -- state -------------------------------------------------------------------------
    def state(self) -> list[float]:
        """Everything that evolves, as a flat list of ``7 + 3*history`` floats."""
        out = [*self.theta, self.f_s_lo, self.f_s_hi, self.rel_misfit, float(len(self.pulses))]
        for i in range(self.size):
            out.extend(self.pulses[i] if i < len(self.pulses) else (0.0, 0.0, 0.0))
        return [float(v) for v in out]

    def set_state(self, values: list[float]) -> None:
        """Restore a state returned by :meth:`state`."""
        v = [float(q) for q in values]
        self.theta = v[0:3]
        self.f_s_lo, self.f_s_hi, self.rel_misfit = v[3], v[4], v[5]
        count = int(v[6])
        self.pulses = [(int(v[7 + 3 * i]), v[8 + 3 * i], v[9 + 3 * i]) for i in range(count)]


class ExactController(Controller):
    """Pulse control on the exact model, Eq. (3), with m, f_c, c and f_s learned online.

    Each pulse is planned for the measured error ``e``: the fewest samples n
    for which Eq. (3) reaches ``|e|`` with a height in ``[f_floor, f_p_max]``,
    the height solving Eq. (3) for ``|e|`` (see :func:`pulse_amplitude`).
    ``f_floor`` is the lowest height known to move the mass, or, while the f_s
    bracket is wider than ``f_s_tol`` (relative), the middle of the bracket, so
    that pulses below the known height probe f_s. An error smaller than the
    smallest single pulse (n = 1 at ``f_floor``) is reached with a two-pulse
    move: out by ``|e| + d_back``, then back by ``d_back = 1.5 * d(1, f_floor)``.

    It reads the settings of kind ``exact`` (see
    :data:`papwc.model.settings.CONTROLLER_SETTINGS`): ``c_est`` (initial
    estimate of c, N.s/m), ``history`` (pulses kept for the fit), ``max_pulses``
    (pulses per maneuver after which it stops), ``x_resolution`` (resolution of
    the measurement, m, weights the fit) and ``f_s_tol`` (relative width of the
    f_s bracket below which no more probing is done).
    """

    kind = "exact"

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        self.max_pulses = int(settings.max_pulses)
        self.f_s_tol = float(settings.f_s_tol)
        self.estimator = PulseModelEstimator(
            settings.m_est,
            settings.f_c_est,
            float(settings.c_est),
            T,
            settings.f_p_max,
            history=int(settings.history),
            x_resolution=float(settings.x_resolution),
        )
        self._stopped = False
        self._stop_now = False
        super().__init__(settings, T)

    def reset(self) -> None:
        """Start a new maneuver from rest; the learned model and f_s bracket are kept."""
        super().reset()
        self._stopped = False
        self._stop_now = False

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force to hold over the next sample, N (see :meth:`Controller.update`).

        After ``max_pulses`` pulses in this maneuver (or for a non-finite error)
        the controller stops: mode settled and ``u = 0`` until :meth:`reset`.
        """
        if self._stopped:
            return 0.0
        u = super().update(t, x_meas, x_ref)
        if self._stop_now:
            # plan_pulse refused: undo the pulse the base class started.
            self._stop_now = False
            self._stopped = True
            self.pulses -= 1
            self.mode = Mode.SETTLED
            self._pulse_left = 0
            self._f_pulse = 0.0
            return 0.0
        return u

    # -- planning ----------------------------------------------------------------------
    @property
    def f_floor(self) -> float:
        """Lowest height a pulse is planned with, N: known to move, or probing f_s."""
        est = self.estimator
        lower = max(est.f_s_lo, est.f_c_hat)
        floor = est.f_s_hi
        if floor - lower > self.f_s_tol * floor:
            floor = 0.5 * (lower + floor)
        # Eq. (3) gives no motion at or below f_c.
        return min(max(floor, est.f_c_hat * (1.0 + 1e-9)), self.settings.f_p_max)

    def plan_displacement(self, d: float, f_floor: float | None = None) -> tuple[int, float]:
        """Fastest pulse for a displacement d > 0 (m): n samples and height (N, > 0).

        The fewest samples n (<= n_max) for which ``d(n, f_p_max) >= d``; the
        height solves Eq. (3) at that n. If even ``d(n, f_floor)`` exceeds d,
        the pulse of n - 1 samples at f_p_max (which falls short) is taken, or,
        for n = 1, the smallest pulse ``(1, f_floor)``.
        """
        f_max = self.settings.f_p_max
        f_lo = self.f_floor if f_floor is None else f_floor
        m, f_c, c = self.estimator.params()
        T = self.T
        n_cap = min(self.n_max, _N_SEARCH_MAX)

        def reach(n: int) -> float:
            return pulse_displacement(f_max, n * T, m, f_c, c)

        if not d > 0.0 or not math.isfinite(d):
            return 1, f_lo
        # Smallest n with reach(n) >= d: exponential then binary search.
        hi = 1
        while hi < n_cap and reach(hi) < d:
            hi = min(2 * hi, n_cap)
        if reach(hi) < d:
            return n_cap, f_max
        lo = hi // 2  # reach(lo) < d, or lo = 0
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if reach(mid) < d:
                lo = mid
            else:
                hi = mid
        n = hi
        if pulse_displacement(f_lo, n * T, m, f_c, c) > d:
            return (n - 1, f_max) if n > 1 else (1, f_lo)
        return n, pulse_amplitude(d, n * T, m, f_c, c, f_lo, f_max)

    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Pulse for the error e (m): single pulse, or the out pulse of a two-pulse move.

        Refuses (the controller stops, see :meth:`update`) when e is not finite,
        when ``max_pulses`` pulses have been applied in this maneuver, when a
        two-pulse move would not fit into them, or when ``|e|`` is below what a
        move can achieve: half the measurement resolution, or the error the
        model's relative misfit implies for the pulses of the move.
        """
        if not math.isfinite(e) or self.pulses >= self.max_pulses:
            self._stop_now = True
            return 1, 0.0
        est = self.estimator
        f_lo = self.f_floor
        d = abs(e)
        d_small = est.displacement(f_lo, 1)
        two_pulse = d < d_small
        if two_pulse:
            d += (1.0 + _MARGIN) * d_small  # out now, back by d_back next
        achievable = max(0.5 * est.x_resolution, est.rel_misfit * (2.0 * d - abs(e)))
        if abs(e) <= achievable or (two_pulse and self.pulses + 2 > self.max_pulses):
            self._stop_now = True
            return 1, 0.0
        n, f_p = self.plan_displacement(d, f_lo)
        return n, math.copysign(f_p, e)

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Take the measured displacement d (m) of the pulse (n samples, f_p N) into the model."""
        self.estimator.observe(n, f_p, d)

    def estimates(self) -> dict[str, float]:
        """``b_hat`` (Eq. (4) at f_p_max, m/s**2), ``f_c_hat``, ``m_hat``, ``c_hat``, f_s bracket.

        Units: m/s**2, N, kg, N.s/m, N.
        """
        est = self.estimator
        m, f_c, c = est.params()
        f_p = self.settings.f_p_max
        return {
            "b_hat": b_coulomb(f_p, m, f_c),
            "f_c_hat": f_c,
            "m_hat": m,
            "c_hat": c,
            "f_s_lo": est.f_s_lo,
            "f_s_hi": est.f_s_hi,
        }

    def state(self) -> list[float]:
        """Base state, the stop flags and the estimator's state (fixed length)."""
        return (super().state() + [float(self._stopped), float(self._stop_now)]
                + self.estimator.state())

    def set_state(self, values: list[float]) -> None:
        """Restore a state returned by :meth:`state`."""
        n = len(super().state())
        super().set_state(values[:n])
        self._stopped, self._stop_now = bool(values[n]), bool(values[n + 1])
        self.estimator.set_state(values[n + 2:])
