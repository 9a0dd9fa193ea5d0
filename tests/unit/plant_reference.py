"""An independent reference of the plant with deviations: scipy's solve_ivp with events.

Written from the equations of fmu_src/FrictionPlant/readme.md, sharing no code
with papwc.model.dynamics: each communication step is integrated mode by mode
(sliding forward, sliding backward, stuck; or the smooth LuGre system) with
``solve_ivp`` at tight tolerances, a terminal event ending each mode, and the
stick-slip transition applied there. Random stiction reads its breakaway
forces from the same random numbers (papwc.model.effects.draws), which are the
input of the test, not the physics under test.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from papwc.model.effects.draws import uniform
from papwc.model.plant import PLANT_DEFAULTS

#: solve_ivp tolerances of the reference.
RTOL = 1e-12
ATOL = 1e-16
#: Absolute tolerance with LuGre (z is of order 1e-6 m).
ATOL_LUGRE = 1e-18


class ReferencePlant:
    """The plant of the readme integrated by solve_ivp (see the module docstring)."""

    def __init__(self, params: dict) -> None:
        p = {**PLANT_DEFAULTS, **params}
        self.p = p
        self.x, self.v = p["x0"], p["v0"]
        self.z = 0.0
        self.x_d, self.v_d = p["x0"], p["v0"]
        self.f_a = 0.0
        self.draws = 0
        self.f_sn = p["f_s"]
        if p["f_s_spread"] > 0.0:
            self.f_sn = self._draw()
        self.lugre = p["sigma_0"] > 0.0
        self.flex = p["m_d"] > 0.0
        self.lag = p["tau_u"] > 0.0
        self.events = 0

    def _draw(self) -> float:
        p = self.p
        k = self.draws
        self.draws += 1
        return p["f_s"] * (1.0 + p["f_s_spread"] * (2.0 * uniform(int(p["seed"]), 1, k) - 1.0))

    # friction levels
    def r(self, x):
        p = self.p
        return 1.0 + p["ripple"] * math.sin(2 * math.pi * x / p["ripple_period"]
                                            + p["ripple_phase"])

    def g(self, x, v):
        p = self.p
        if p["v_s"] > 0.0:
            base = p["f_c"] + (self.f_sn - p["f_c"]) * math.exp(-(abs(v) / p["v_s"])
                                                                ** p["delta_s"])
        else:
            base = p["f_c"]
        return self.r(x) * base

    # state vector: x, v, z, x_d, v_d, f_a (all present; unused ones stay constant)
    def drive(self, y, u):
        p = self.p
        if self.flex:
            return p["k_t"] * (y[3] - y[0]) + p["c_t"] * (y[4] - y[1])
        return y[5] if self.lag else u

    def rhs(self, y, u, s):
        p = self.p
        dy = np.zeros(6)
        fa = y[5] if self.lag else u
        if self.lag:
            dy[5] = (u - y[5]) / p["tau_u"]
        F = self.drive(y, u)
        if self.flex:
            dy[3] = y[4]
            dy[4] = (fa - F) / p["m_d"]
        x, v = y[0], y[1]
        if self.lugre:
            zd = v - p["sigma_0"] * abs(v) * y[2] / self.g(x, v)
            dy[0] = v
            dy[1] = (F - p["sigma_0"] * y[2] - p["sigma_1"] * zd - p["c"] * v) / p["m"]
            dy[2] = zd
        elif s != 0:
            dy[0] = v
            dy[1] = (F - s * self.g(x, v) - p["c"] * v) / p["m"]
        return dy

    def step(self, u: float, h: float) -> None:
        y = np.array([self.x, self.v, self.z, self.x_d, self.v_d, self.f_a], dtype=float)
        t, t_end = 0.0, h
        p = self.p
        if self.lugre:
            # A smooth system (no switch): LSODA, stiff where the bristles are.
            sol = solve_ivp(lambda tt, yy: self.rhs(yy, u, 0), (0.0, h), y, method="LSODA",
                            rtol=RTOL, atol=ATOL_LUGRE)
            y = sol.y[:, -1]
            self.x, self.v, self.z = y[0], y[1], y[2]
            self.x_d, self.v_d, self.f_a = y[3], y[4], y[5]
            return
        v = y[1]
        if v != 0.0:
            s = 1.0 if v > 0 else -1.0
        else:
            F = self.drive(y, u)
            s = (1.0 if F > 0 else -1.0) if abs(F) > self.r(y[0]) * self.f_sn else 0.0
        while t < t_end:
            if s == 0 and not (self.flex or self.lag):
                break
            if s != 0:
                def ev(tt, yy, s=s):
                    return s * yy[1]
                ev.direction = -1
            else:
                thr = self.r(y[0]) * self.f_sn

                def ev(tt, yy, thr=thr):
                    return abs(self.drive(yy, u)) - thr
                ev.direction = 1
            ev.terminal = True
            method = "LSODA" if self.lag or self.flex else "DOP853"
            sol = solve_ivp(lambda tt, yy, s=s: self.rhs(yy, u, s), (t, t_end), y,
                            method=method, rtol=RTOL, atol=ATOL, events=ev)
            y = sol.y[:, -1].copy()
            if sol.status == 1 and sol.t[-1] < t_end:
                t = sol.t[-1]
                y = sol.y_events[0][0].copy()
                self.events += 1
                F = self.drive(y, u)
                if s != 0:
                    y[1] = 0.0
                    if abs(F) <= self.r(y[0]) * self.f_sn:
                        if p["f_s_spread"] > 0.0:
                            self.f_sn = self._draw()
                        s = 0.0
                        if abs(F) > self.r(y[0]) * self.f_sn:
                            s = 1.0 if F > 0 else -1.0
                    else:
                        s = 1.0 if F > 0 else -1.0
                else:
                    s = 1.0 if F > 0 else -1.0
            else:
                t = t_end
        if s == 0:
            y[1] = 0.0
        self.x, self.v, self.z = y[0], y[1], y[2]
        self.x_d, self.v_d, self.f_a = y[3], y[4], y[5]
