"""Adaptive Pulse Width Control (Yang and Tomizuka), the paper's Section 2."""

from __future__ import annotations

import math

from ..model.pulse import b_coulomb
from .base import Controller
from .estimators import ScalarRls
from .settings import ControllerSettings


class PwcController(Controller):
    """Adaptive PWC: Eq. (4)-(9).

    Every pulse has the height ``f_p_max * sgn(e)``; its width follows from
    Eq. (6), ``t_p**2 = K_c*|e|/b_hat``, rounded up to whole samples (the ZOH
    can do nothing else) and bounded by ``t_p_max``. After each pulse b_hat is
    updated from the measured displacement with Eq. (7)-(9), using the width
    that was actually applied.
    """

    kind = "pwc"

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        super().__init__(settings, T)
        b0 = b_coulomb(settings.f_p_max, settings.m_est, settings.f_c_est)
        self.estimator = ScalarRls(
            b0,
            F_inv0=settings.F_inv0,
            lambda_1=settings.lambda_1,
            lambda_2=settings.lambda_2,
            b_bounds=(b0 * 1e-3, b0 * 1e3),
        )

    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Eq. (6): ``u_p = K_c*e/b_hat``, ``t_p = sqrt(|u_p|)``, height ``f_p_max*sgn(e)``."""
        t_p = math.sqrt(self.settings.K_c * abs(e) / self.estimator.b_hat)
        return self.width_samples(t_p), math.copysign(self.settings.f_p_max, e)

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Eq. (7)-(9) with ``u_p = (n*T)**2 * sgn(f_p)``; a pulse that did not move is skipped."""
        if d == 0.0:
            return
        t_p = n * self.T
        self.estimator.update(math.copysign(t_p * t_p, f_p), d)

    def estimates(self) -> dict[str, float]:
        """``b_hat`` (m/s**2) and the Coulomb friction it implies with m = m_est (N)."""
        b = self.estimator.b_hat
        f_p = self.settings.f_p_max
        return {"b_hat": b, "f_c_hat": f_p * f_p / (2.0 * self.settings.m_est * b + f_p)}

    def state(self) -> list[float]:
        return super().state() + self.estimator.state()

    def set_state(self, values: list[float]) -> None:
        n = len(super().state())
        super().set_state(values[:n])
        self.estimator.set_state(values[n:])
