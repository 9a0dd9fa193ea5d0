"""Recursive estimators of the pulse models: Eq. (7)-(9) and Eq. (13)-(18).

Standard library only; every estimate is kept finite and inside stated bounds.
"""

from __future__ import annotations

import math


class ScalarRls:
    """Self-tuning estimate of the PWC gain b, Eq. (7)-(9).

    The model is ``d(k) = b * u_p(k-1)`` with ``u_p = t_p**2 * sgn(f_p)``
    (Eq. (5)).

    Parameters
    ----------
    b0 : float
        Initial estimate b_hat(0), m/s**2, > 0.
    F_inv0 : float
        Initial inverse gain F^-1(0), s**4/m**2... (> 0; the paper uses 1e-5).
    lambda_1, lambda_2 : float
        Forgetting parameters of Eq. (8): 0 < lambda_1 <= 1, 0 <= lambda_2 < 2.
    b_bounds : (float, float)
        The estimate is kept inside this interval (m/s**2).
    update_gain : bool
        Update F^-1 by Eq. (8) (default); False keeps F^-1(0), so that Eq. (9)
        runs with the fixed gain F(0).
    """

    def __init__(
        self,
        b0: float,
        F_inv0: float = 1e-5,
        lambda_1: float = 1.0,
        lambda_2: float = 1.0,
        b_bounds: tuple[float, float] = (0.0, math.inf),
        update_gain: bool = True,
    ) -> None:
        self.b_hat = float(b0)
        self.F_inv = float(F_inv0)
        self.lambda_1 = float(lambda_1)
        self.lambda_2 = float(lambda_2)
        self.b_min = max(float(b_bounds[0]), 1e-300)
        self.b_max = float(b_bounds[1])
        self.update_gain = bool(update_gain)

    def update(self, u_p: float, d: float) -> float:
        """Take one pulse (regressor u_p, s**2, signed; displacement d, m) into the estimate.

        Returns the prediction error epsilon_0^0 of Eq. (7), m.
        """
        eps = d - self.b_hat * u_p  # Eq. (7)
        F_inv = self.F_inv
        if self.update_gain:
            F_inv = self.lambda_1 * F_inv + self.lambda_2 * u_p * u_p  # Eq. (8)
        if not (math.isfinite(F_inv) and F_inv > 0.0) or not math.isfinite(eps):
            return 0.0
        self.F_inv = F_inv
        b_new = self.b_hat + u_p * eps / F_inv  # Eq. (9)
        if math.isfinite(b_new):
            self.b_hat = min(max(b_new, self.b_min), self.b_max)
        return eps

    def state(self) -> list[float]:
        """The estimator's state as a flat list (for FMU state and serialization)."""
        return [self.b_hat, self.F_inv]

    def set_state(self, values: list[float]) -> None:
        """Restore a state returned by :meth:`state`."""
        self.b_hat, self.F_inv = (float(v) for v in values)


class Rls2:
    """Two-parameter recursive least squares with forgetting, Eq. (13)-(17).

    Estimates ``a = [A1, A2]`` of the PAPWC model ``d = a^T phi`` where the
    regressor is ``phi = [f_p**2 * t_p**2, -f_p * t_p**2]`` (Eq. (18) with the
    sign corrected as in the reading notes; ``f_p = |pulse height|`` and ``d``
    the displacement in the pulse's direction).

    Parameters
    ----------
    a0 : (float, float)
        Initial estimates A1(0) (1/(kg*N)) and A2(0) (1/kg).
    delta_inv : float
        P(0) = delta_inv * I (> 0; the paper uses 1e-5).
    lam : float
        Forgetting factor lambda, 0 < lambda <= 1.
    a_bounds : ((float, float), (float, float))
        Bounds that A1 and A2 are projected into after each update.
    update_covariance : bool
        Update P by Eq. (14) (default); False keeps P(0), so that Eq. (15)
        and (17) run with the fixed P(0).
    """

    def __init__(
        self,
        a0: tuple[float, float],
        delta_inv: float = 1e-5,
        lam: float = 1.0,
        a_bounds: tuple[tuple[float, float], tuple[float, float]] = (
            (0.0, math.inf),
            (0.0, math.inf),
        ),
        update_covariance: bool = True,
    ) -> None:
        self.a = [float(a0[0]), float(a0[1])]
        self.delta_inv = float(delta_inv)
        self.P = [[self.delta_inv, 0.0], [0.0, self.delta_inv]]
        self.lam = float(lam)
        self.bounds = [tuple(map(float, a_bounds[0])), tuple(map(float, a_bounds[1]))]
        self.update_covariance = bool(update_covariance)

    def update(self, phi: tuple[float, float], d: float) -> float:
        """Take one observation (regressor phi, displacement d in m) into the estimate.

        Returns the a-priori error xi of Eq. (16), m. A non-finite step leaves the
        estimate and P unchanged; P is kept symmetric positive definite.
        """
        (p00, p01), (p10, p11) = self.P
        phi0, phi1 = phi
        a0, a1 = self.a
        lam = self.lam
        pi0 = p00 * phi0 + p01 * phi1  # Eq. (13)
        pi1 = p10 * phi0 + p11 * phi1
        denom = lam + phi0 * pi0 + phi1 * pi1
        xi = d - (a0 * phi0 + a1 * phi1)  # Eq. (16)
        isfinite = math.isfinite
        if not (isfinite(denom) and denom > 0.0 and isfinite(xi)):
            return 0.0
        k0 = pi0 / denom  # Eq. (15)
        k1 = pi1 / denom
        # Eq. (14): P = (P - K pi^T) / lambda, written symmetric (pi = P phi, P = P^T).
        q00 = (p00 - k0 * pi0) / lam
        q11 = (p11 - k1 * pi1) / lam
        q01 = 0.5 * ((p01 - k0 * pi1) + (p10 - k1 * pi0)) / lam
        a0 = a0 + k0 * xi  # Eq. (17)
        a1 = a1 + k1 * xi
        if not (isfinite(q00) and isfinite(q11) and isfinite(q01) and isfinite(a0)
                and isfinite(a1)):
            return 0.0
        if not self.update_covariance:
            pass  # P stays P(0): Eq. (14) is not applied
        elif q00 > 0.0 and q11 > 0.0 and q00 * q11 - q01 * q01 > 0.0:
            self.P = [[q00, q01], [q01, q11]]
        else:
            # Rounding has cost P its definiteness: restart the covariance.
            self.P = [[self.delta_inv, 0.0], [0.0, self.delta_inv]]
        (lo0, hi0), (lo1, hi1) = self.bounds
        self.a = [lo0 if a0 < lo0 else hi0 if a0 > hi0 else a0,
                  lo1 if a1 < lo1 else hi1 if a1 > hi1 else a1]
        return xi

    def state(self) -> list[float]:
        """The estimator's state as a flat list (for FMU state and serialization)."""
        return [self.a[0], self.a[1], self.P[0][0], self.P[0][1], self.P[1][1]]

    def set_state(self, values: list[float]) -> None:
        """Restore a state returned by :meth:`state`."""
        a0, a1, p00, p01, p11 = (float(v) for v in values)
        self.a = [a0, a1]
        self.P = [[p00, p01], [p01, p11]]
