"""Adaptive Pulse Width Control (Yang and Tomizuka), the paper's Section 2."""

from __future__ import annotations

import math

from ..model.pulse import b_coulomb
from ..model.variables import Variable
from .base import PulseControllerBase, cut_width
from .estimators import ScalarRls
from .sequencer import M_D_EST
from .settings import ControllerSettings

#: ``regressor`` and ``update_covariance``: read by PWC and PAPWC.
REGRESSOR_SETTING = (
    Variable("regressor", "Pulse the estimator is fed, a reading the paper leaves open: 0 "
             "the applied pulse (u_p = (n*T)**2, Eq. (7)-(9); PAPWC u of Eq. (18) with the "
             "applied height f_p* and width T_x = n*T), 1 the planned pulse (t_p of Eq. (6), "
             "at most t_p_max in whole samples; PAPWC Eq. (18) as printed, at f_p_max)", "", 0,
             type="Integer", min=0, max=1, note="(0 applied, 1 planned)")
)
UPDATE_COVARIANCE = (
    Variable("update_covariance", "Update F^-1 by Eq. (8) (PWC) and P by Eq. (14) (PAPWC) "
             "after each pulse; false keeps F^-1(0) and P(0) (the paper's runs 'without "
             "updating the inverse covariance matrix')", "", True, type="Boolean")
)

#: The settings PWC reads besides the shared ones.
PWC_SETTINGS: tuple[Variable, ...] = (
    Variable("F_inv0", "Initial inverse gain F^-1(0) of the PWC estimator, Eq. (8) (the "
             "paper: 1e-5, so F(0) = 1e5)", "s4",
             1e-5, min=1e-12, max=1e12),
    Variable("lambda_1", "Forgetting parameter lambda_1 of Eq. (8)", "1", 1.0, min=0.0,
             max=1.0, min_open=True, note="(Eq. (8))"),
    Variable("lambda_2", "Forgetting parameter lambda_2 of Eq. (8)", "1", 1.0, min=0.0,
             max=2.0, max_open=True, note="(Eq. (8))"),
    REGRESSOR_SETTING,
    UPDATE_COVARIANCE,
    M_D_EST,
)


#: ``regressor`` setting: the estimator is fed the applied width (n*T).
REGRESSOR_APPLIED = 0
#: ``regressor`` setting: the estimator is fed the planned width t_p of Eq. (6).
REGRESSOR_PLANNED = 1


class PwcController(PulseControllerBase):
    """Adaptive PWC: Eq. (4)-(9).

    Every pulse has the height ``f_p_max * sgn(e)``; its width follows from
    Eq. (6), ``t_p**2 = K_c*|e|/b_hat``, rounded up to whole samples (the ZOH
    can do nothing else) and bounded by ``t_p_max``. After each pulse b_hat is
    updated from the measured displacement with Eq. (7)-(9), using the width
    that was actually applied (``regressor = 0``) or the width Eq. (6) planned,
    bounded by ``t_p_max`` (``regressor = 1``: "the calculated pulse isn't the
    real input pulse"). With ``update_covariance = false`` F^-1 keeps F^-1(0).
    """

    kind = "pwc"
    #: The settings this kind reads besides the shared ones (registry: every kind's).
    SETTINGS = PWC_SETTINGS

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        super().__init__(settings, T)
        b0 = b_coulomb(settings.f_p_max, settings.m_est, settings.f_c_est)
        self.estimator = ScalarRls(
            b0,
            F_inv0=settings.F_inv0,
            lambda_1=settings.lambda_1,
            lambda_2=settings.lambda_2,
            b_bounds=(b0 * 1e-3, b0 * 1e3),
            update_gain=settings.update_covariance,
        )
        #: Width of the last pulse as Eq. (6) planned it, bounded by t_p_max, s.
        self.t_p_plan = 0.0

    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Eq. (6): ``u_p = K_c*e/b_hat``, ``t_p = sqrt(|u_p|)``, height ``f_p_max*sgn(e)``.

        With safeguards, a width rounded up to whole samples is cut by whole
        samples (to one at least) while Eq. (4) predicts more than the trust
        region, ``trust*|e|``.
        """
        t_p = math.sqrt(self.settings.K_c * abs(e) / self.estimator.b_hat)
        self.t_p_plan = min(t_p, self.n_max * self.T)
        n = self.width_samples(t_p)
        if self.guarded:
            limit = self.trust() * abs(e)
            n = cut_width(n, lambda n: self.predict(n, 1.0) > limit)
        return n, math.copysign(self.settings.f_p_max, e)

    @property
    def f_low(self) -> float:
        """PWC pulses at f_p_max only (N): its smallest pulse is d_min of Eq. (19)."""
        return self.settings.f_p_max

    def predict(self, n: int, f_p: float) -> float:
        """Eq. (4)/(5): ``b_hat*(n*T)**2``, m."""
        t = n * self.T
        return self.estimator.b_hat * t * t

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Eq. (7)-(9) with ``u_p = t_p**2 * sgn(f_p)``; a pulse that did not move is skipped.

        ``t_p`` is the applied width ``n*T`` or the planned one (setting ``regressor``).
        """
        if d == 0.0:
            return
        t_p = self.t_p_plan if int(self.settings.regressor) == REGRESSOR_PLANNED else n * self.T
        self.estimator.update(math.copysign(t_p * t_p, f_p), d)

    def estimates(self) -> dict[str, float]:
        """``b_hat`` (m/s**2) and the Coulomb friction it implies with m = m_est (N)."""
        b = self.estimator.b_hat
        f_p = self.settings.f_p_max
        return {"b_hat": b, "f_c_hat": f_p * f_p / (2.0 * self.settings.m_est * b + f_p)}

    def law_state(self) -> dict[str, float]:
        """The floor, the estimator's ``b_hat`` and ``F_inv``, and the planned width."""
        b_hat, f_inv = self.estimator.state()
        return {**super().law_state(), "b_hat": b_hat, "F_inv": f_inv, "t_p_plan": self.t_p_plan}

    def set_law_state(self, values) -> None:
        super().set_law_state(values)
        self.estimator.set_state([values["b_hat"], values["F_inv"]])
        self.t_p_plan = float(values["t_p_plan"])
