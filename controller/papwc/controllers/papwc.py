"""Adaptive Pulse Amplitude Pulse Width Control, the paper's Section 3."""

from __future__ import annotations

import math

from ..model.variables import Variable
from .base import PulseControllerBase, cut_width
from .estimators import Rls2
from .pwc import REGRESSOR_PLANNED, REGRESSOR_SETTING, UPDATE_COVARIANCE
from .sequencer import M_D_EST, Z_DECIDE
from .settings import ControllerSettings

#: The settings PAPWC reads besides the shared ones.
PAPWC_SETTINGS: tuple[Variable, ...] = (
    Variable("delta_inv", "P(0) = delta_inv*I of the PAPWC estimator, Eq. (13)-(17) (the "
             "paper: delta^-1 = 1e-5; its advice 'delta small without noise' reads as 1e5, "
             "P(0) = F(0))", "1",
             1e-5, min=1e-12, max=1e12),
    Variable("lambda", "Forgetting factor lambda of Eq. (14)-(15)", "1", 1.0, min=0.0,
             max=1.0, min_open=True, attr="lam"),
    REGRESSOR_SETTING,
    UPDATE_COVARIANCE,
    Variable("floor_mode", "PAPWC pulse that did not move the mass (height at or below "
             "f_s, Eq. (20)): 0 the amplitude floor rises floor_raise above it and the "
             "estimator skips it; 1 the floor rises and Eq. (13)-(17) take d = 0; 2 the floor "
             "stays f_p_min and Eq. (13)-(17) take d = 0", "", 0, type="Integer", min=0, max=2,
             note="(0 raise, 1 raise and learn d = 0, 2 learn d = 0)"),
    M_D_EST,
)


#: ``floor_mode``: a pulse that did not move raises the floor and is not learned.
FLOOR_RAISE = 0
#: ``floor_mode``: it raises the floor and is learned with d = 0.
FLOOR_RAISE_LEARN = 1
#: ``floor_mode``: the floor stays ``f_p_min``; the pulse is learned with d = 0.
FLOOR_LEARN = 2
#: With safeguards: a pulse that moved less than this fraction of its Eq. (4) prediction
#: raises the floor as a pulse that did not move.
FAR_LESS = 0.25


def creep_prediction(f_p: float, eq4: float, creeps: tuple[float, float, float, float]
                     ) -> float:
    """Move (m) of a one-sample pulse at the floor, f_p N, after pulses that crept.

    One-sample pulses that moved less than Eq. (4) predicts (a height near a breakaway
    that friction keeps up at low speed: Stribeck, an actuator lag) are the evidence
    near the floor; those that moved less than ``FAR_LESS`` of it raised the floor.
    Where the last two grew with their height, as a creep does, the next pulse at the
    floor is predicted to move

    * as far as the last one if it is no higher;
    * else as the last two grew, extrapolated geometrically in the height (for a move
      that grows as a power of the excess over the breakaway, an overestimate);

    at least ``FAR_LESS`` times Eq. (4) (the least move Eq. (4) learns from) and never
    more than Eq. (4). Where they did not grow but moved alike (within a factor
    1/``FAR_LESS``: the breakaway drawn anew at every stop scatters them), a pulse no
    higher than a creep is predicted to move as far as the farthest creep at least as high,
    within the same limits. Else Eq. (4) (creeps far apart in size are a table that reads
    noise while a compliant drive winds up).

    Parameters
    ----------
    f_p : float
        Height of the pulse, N (> 0).
    eq4 : float
        Eq. (4)'s move for it, m.
    creeps : tuple of float
        ``(f_0, d_0, f_1, d_1)``: height (N) and move (m) of the one-sample pulse before
        the last that moved less than Eq. (4) predicts, and of the last (0: none).

    Returns
    -------
    float
        Predicted move along the pulse, m.
    """
    f_0, d_0, f_1, d_1 = creeps
    if not (f_1 > f_0 > 0.0 and d_1 > d_0 > 0.0):
        # no growth with the height to go by: where the two moved alike (within a factor
        # 1/FAR_LESS: the scatter of a breakaway drawn anew, not a table that reads noise
        # while a compliant drive winds up), a pulse no higher than a creep moves as far as
        # the farthest of those at least as high
        if not (f_0 > 0.0 and min(d_0, d_1) >= FAR_LESS * max(d_0, d_1) > 0.0):
            return eq4
        above = [d for f, d in ((f_0, d_0), (f_1, d_1)) if f >= f_p]
        return min(eq4, max(FAR_LESS * eq4, max(above))) if above else eq4
    grown = d_1 if f_p <= f_1 else d_1 * (d_1 / d_0) ** ((f_p - f_1) / (f_1 - f_0))
    return min(eq4, max(FAR_LESS * eq4, grown))


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


class PapwcController(PulseControllerBase):
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
    #: The settings this kind reads besides the shared ones (registry: every kind's).
    SETTINGS = PAPWC_SETTINGS

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
        #: Height (N) and move (m) of the one-sample pulse before the last that moved less
        #: than Eq. (4) predicts, and of the last (0: none since one moved as far as Eq. (4)
        #: has it): :func:`creep_prediction`.
        self.creeps = (0.0, 0.0, 0.0, 0.0)

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
        """Eq. (6) at f_p_max for the width, Eq. (11) for the height, within the floor.

        With safeguards, K_c is at most the trust region (a pulse is planned to
        move at most ``trust*|e|`` by Eq. (4)), and a width whose height the
        floor lifts so that Eq. (4) predicts more than that is cut by whole
        samples. A one-sample pulse at the floor that may end farther than the
        maneuver started gives way to the highest height of the creeps kept that,
        on their evidence (:meth:`reach` below Eq. (4)), may not; the floor stays.
        """
        f_max = self.settings.f_p_max
        f_c = self.f_c_hat
        b = self.b_hat(f_max)
        self.f_p_plan = f_max
        if not (b > 0.0 and f_c > 0.0):
            # The estimates say f_p_max cannot move the mass: probe at full height.
            self.t_p_plan = self.T
            return 1, math.copysign(f_max, e)
        k_c = self.settings.K_c
        if self.guarded:
            k_c = min(k_c, self.trust())
        t_p = math.sqrt(k_c * abs(e) / b)  # Eq. (6)
        self.t_p_plan = min(t_p, self.n_max * self.T)

        def height(n: int) -> float:
            """Eq. (11) for the width n*T, within the floor and f_p_max (N)."""
            T_x = n * self.T
            f_p = f_max if t_p >= T_x else papwc_amplitude(f_c, f_max, t_p, T_x)
            return min(max(f_p, self.f_p_floor), f_max)

        n = self.width_samples(t_p)
        if self.guarded:
            n = cut_width(n, lambda n: self.predict(n, height(n)) > self.trust() * abs(e))
        f_p = math.copysign(height(n), e)
        if (self.guarded and n == 1 and not self.seq.flexible()
                and self.seq.may_end_farther(e, f_p, self.reach(1, f_p))):
            # the floor may end farther; a creep's own height that cannot, by the creeps'
            # evidence (not by Eq. (4) alone), is fired instead (the floor stays)
            for f in sorted((f for f in (self.creeps[0], self.creeps[2]) if 0.0 < f < abs(f_p)),
                            reverse=True):
                f = math.copysign(f, e)
                reach = self.reach(1, f)
                if reach < self.predict(1, f) and not self.seq.may_end_farther(e, f, reach):
                    return 1, f
        return n, f_p

    def reach(self, n: int, f_p: float) -> float:
        """Eq. (4) (:meth:`predict`); for a one-sample pulse at the floor after one-sample
        pulses that moved less than Eq. (4) has them, :func:`creep_prediction`, m (>= 0)."""
        eq4 = self.predict(n, f_p)
        if n == 1 and abs(f_p) <= self.f_p_floor and not self.seq.flexible():
            return creep_prediction(abs(f_p), eq4, self.creeps)
        return eq4

    def predict(self, n: int, f_p: float) -> float:
        """Eq. (4) with Eq. (12): ``(A1*f_p**2 - A2*f_p)*(n*T)**2`` at abs(f_p) (>= 0), m."""
        t = n * self.T
        a1, a2 = self.estimator.a
        f = abs(f_p)
        return max(a1 * f * f - a2 * f, 0.0) * t * t  # b_hat(|f_p|), Eq. (12)

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Eq. (13)-(18) with the pulse's displacement ``d`` along its direction.

        With safeguards, a pulse that moved less than ``FAR_LESS`` of what
        Eq. (4) predicts for it (a height barely above a breakaway force that
        friction keeps up at low speed, as on a Stribeck curve) is the evidence
        a pulse that did not move is: the floor rises above its height and the
        estimator skips it.
        """
        d_along = d if f_p > 0.0 else -d
        if n == 1:
            self._keep_creep(f_p, d_along)
        if self.guarded and d_along > 0.0 and d_along < FAR_LESS * self.predict(n, f_p):
            self._raise_floor(f_p)
            return
        if not d_along > 0.0:
            mode = int(self.settings.floor_mode)
            if mode in (FLOOR_RAISE, FLOOR_RAISE_LEARN):
                self._raise_floor(f_p)
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

    def _keep_creep(self, f_p: float, d_along: float) -> None:
        """Keep a one-sample pulse of f_p N that moved d_along (m) less than Eq. (4) has it,
        if the move stands out of the noise of a measured displacement (``Z_DECIDE``
        standard deviations); forget the creeps after one that moved as far as Eq. (4) or
        that did not move visibly (the creeps no longer tell what the next pulse does: a
        table held back by a compliant drive reads noise while the drive winds up)."""
        if Z_DECIDE * self.rest.sigma_move() < d_along < self.predict(1, f_p):
            f_0, d_0, f_1, d_1 = self.creeps
            if abs(f_p) == f_1:
                # the same height again: the farther of its moves (the breakaway drawn anew
                # scatters them), the creep below kept for the growth with the height
                self.creeps = (f_0, d_0, f_1, max(d_1, d_along))
            else:
                self.creeps = (f_1, d_1, abs(f_p), d_along)
        else:
            self.creeps = (0.0, 0.0, 0.0, 0.0)

    def _raise_floor(self, f_p: float) -> None:
        """Lift the amplitude floor to ``1 + floor_raise`` times abs(f_p) (N), at most f_p_max."""
        self.f_p_floor = min(max(self.f_p_floor, abs(f_p) * (1.0 + self.settings.floor_raise)),
                             self.settings.f_p_max)

    def estimates(self) -> dict[str, float]:
        """``b_hat`` at f_p_max (m/s**2) and ``f_c_hat`` = A2/A1 (N)."""
        return {"b_hat": self.b_hat(self.settings.f_p_max), "f_c_hat": self.f_c_hat}

    def law_state(self) -> dict[str, float]:
        """The floor, the estimates A1, A2, the covariance P and the pulse planned at f_p_max."""
        a1, a2, p11, p12, p22 = self.estimator.state()
        return {**super().law_state(), "A1": a1, "A2": a2, "P11": p11, "P12": p12, "P22": p22,
                "f_p_plan": self.f_p_plan, "t_p_plan": self.t_p_plan,
                "creeps": list(self.creeps)}

    def set_law_state(self, values) -> None:
        super().set_law_state(values)
        self.estimator.set_state([values[k] for k in ("A1", "A2", "P11", "P12", "P22")])
        self.f_p_plan, self.t_p_plan = float(values["f_p_plan"]), float(values["t_p_plan"])
        f_0, d_0, f_1, d_1 = (float(v) for v in values["creeps"])
        self.creeps = (f_0, d_0, f_1, d_1)
