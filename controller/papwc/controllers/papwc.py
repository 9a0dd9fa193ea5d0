"""Adaptive Pulse Amplitude Pulse Width Control, the paper's Section 3."""

from __future__ import annotations

import math

from .base import Controller
from .estimators import Rls2
from .pwc import REGRESSOR_PLANNED
from .settings import ControllerSettings

#: ``floor_mode``: a pulse that did not move raises the floor and is not learned.
FLOOR_RAISE = 0
#: ``floor_mode``: it raises the floor and is learned with d = 0.
FLOOR_RAISE_LEARN = 1
#: ``floor_mode``: the floor stays ``f_p_min``; the pulse is learned with d = 0.
FLOOR_LEARN = 2


def papwc_amplitude(f_c: float, f_p: float, t_p: float, T_x: float) -> float:
    """Pulse height f_p* that moves a pulse of width T_x as far as (f_p, t_p), Eq. (11).

    ``f_p* = 0.5*f_c + 0.5*sqrt(f_c**2 + 4*f_p*(f_p - f_c)*t_p**2/T_x**2)``,
    the positive root, so that Eq. (4) gives the same displacement for
    (f_p*, T_x) as for (f_p, t_p). The radicand is clipped at 0.

    Parameters
    ----------
    f_c : float
        (Estimated) Coulomb friction, N.
    f_p : float
        Height of the planned pulse, N (> 0).
    t_p : float
        Width of the planned pulse, s.
    T_x : float
        Width actually applied, a whole number of samples, s (> 0).

    Returns
    -------
    float
        Pulse height, N.
    """
    radicand = f_c * f_c + 4.0 * f_p * (f_p - f_c) * (t_p / T_x) ** 2
    return 0.5 * f_c + 0.5 * math.sqrt(max(radicand, 0.0))


class PapwcController(Controller):
    """Adaptive PAPWC: Eq. (10)-(18), with the regressor sign corrected.

    The width follows from Eq. (4)/(6) at f_p_max with ``b_hat = A1*f_p_max**2
    - A2*f_p_max``, rounded up to whole samples n (bounded by t_p_max); the
    height from Eq. (11) with ``f_c_hat = A2/A1``, clamped to
    ``[f_p_floor, f_p_max]``. A1 and A2 are estimated by RLS, Eq. (13)-(17),
    with the regressor ``[f_p**2*t_p**2, -f_p*t_p**2]``.

    The readings the paper leaves open are settings: the estimator is fed the
    applied pulse (f_p*, n*T) or the planned one (f_p_max, t_p of Eq. (6)
    bounded by t_p_max; ``regressor``); P is updated by Eq. (14) or kept at
    P(0) (``update_covariance``); a pulse that does not move the mass (its
    height was at or below the stiction force) raises the amplitude floor by the
    factor ``1 + floor_raise`` above it and is not given to the estimator
    (``floor_mode = 0``), raises the floor and is given to the estimator with
    d = 0 (1), or leaves the floor at ``f_p_min`` and is given to the estimator
    with d = 0 (2). An update that would give ``A1 <= 0``, ``A2 <= 0`` or
    ``f_c_hat >= f_p_max`` is rejected.
    """

    kind = "papwc"

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        super().__init__(settings, T)
        a1 = 1.0 / (2.0 * settings.m_est * settings.f_c_est)  # Eq. (12)
        a2 = 1.0 / (2.0 * settings.m_est)
        self.estimator = Rls2(
            (a1, a2),
            delta_inv=settings.delta_inv,
            lam=settings.lam,
            a_bounds=((a1 * 1e-3, a1 * 1e3), (a2 * 1e-3, a2 * 1e3)),
            update_covariance=settings.update_covariance,
        )
        #: Height (N, > 0) and width (s) of the last pulse as planned at f_p_max by Eq. (6).
        self.f_p_plan = settings.f_p_max
        self.t_p_plan = 0.0

    @property
    def f_c_hat(self) -> float:
        """Estimated Coulomb friction A2/A1, N."""
        a1, a2 = self.estimator.a
        return a2 / a1

    def b_hat(self, f_p: float) -> float:
        """Eq. (12): ``b* = A1*f_p**2 - A2*f_p``, m/s**2."""
        a1, a2 = self.estimator.a
        return a1 * f_p * f_p - a2 * f_p

    def plan_pulse(self, e: float) -> tuple[int, float]:
        f_max = self.settings.f_p_max
        f_c = self.f_c_hat
        b = self.b_hat(f_max)
        self.f_p_plan = f_max
        if not (b > 0.0 and f_c > 0.0):
            # The estimates say f_p_max cannot move the mass: probe at full height.
            self.t_p_plan = self.T
            return 1, math.copysign(f_max, e)
        t_p = math.sqrt(self.settings.K_c * abs(e) / b)  # Eq. (6)
        self.t_p_plan = min(t_p, self.n_max * self.T)
        n = self.width_samples(t_p)
        T_x = n * self.T
        f_p = f_max if t_p >= T_x else papwc_amplitude(f_c, f_max, t_p, T_x)
        f_p = min(max(f_p, self.f_p_floor), f_max)
        return n, math.copysign(f_p, e)

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Eq. (13)-(18) with the pulse's displacement ``d`` along its direction."""
        d_along = d if f_p > 0.0 else -d
        if not d_along > 0.0:
            mode = int(self.settings.floor_mode)
            if mode in (FLOOR_RAISE, FLOOR_RAISE_LEARN):
                self.f_p_floor = min(
                    max(self.f_p_floor, abs(f_p) * (1.0 + self.settings.floor_raise)),
                    self.settings.f_p_max,
                )
            if mode == FLOOR_RAISE:
                return
            d_along = 0.0
        if int(self.settings.regressor) == REGRESSOR_PLANNED:
            f, t2 = self.f_p_plan, self.t_p_plan**2
        else:
            f, t2 = abs(f_p), (n * self.T) ** 2
        before = self.estimator.state()
        self.estimator.update((f * f * t2, -f * t2), d_along)
        a1, a2 = self.estimator.a
        if not (a1 > 0.0 and a2 > 0.0 and a2 / a1 < self.settings.f_p_max):
            # An estimate by which f_p_max could not move the mass is rejected.
            self.estimator.set_state(before)

    def estimates(self) -> dict[str, float]:
        """``b_hat`` at f_p_max (m/s**2) and ``f_c_hat`` = A2/A1 (N)."""
        return {"b_hat": self.b_hat(self.settings.f_p_max), "f_c_hat": self.f_c_hat}

    def state(self) -> list[float]:
        return super().state() + self.estimator.state() + [self.f_p_plan, self.t_p_plan]

    def set_state(self, values: list[float]) -> None:
        n = len(super().state())
        m = len(self.estimator.state())
        super().set_state(values[:n])
        self.estimator.set_state(values[n:n + m])
        self.f_p_plan, self.t_p_plan = float(values[n + m]), float(values[n + m + 1])
