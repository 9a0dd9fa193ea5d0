"""The friction ripple's wavelength, searched over a grid before it is fitted.

A friction ripple multiplies the friction by ``r(x) = 1 + a*sin(k*x + phi)``
(:mod:`papwc.model.effects.ripple`, ``k = 2*pi/ripple_period``). The residual of a fit
without it, as a function of the wavelength, has a peak at the table's and as many local
optima as periods the moves span, so a local fit from a guess of the wavelength finds one of
those. :func:`search` therefore tries every wavelength of a grid, fine enough that no peak
falls between two of its points, at little cost: to first order in ``a`` the ripple adds to
the table the force ``-g(v)*sgn(v)*a*sin(k*x + phi)`` while it slides (``g`` the sliding
friction's level, Stribeck's where the plant has it), along the trajectory ``x(t)`` of the
plant without ripple; the move's response to it, through ``m*dv/dt = F - c*v`` while the
table slides (it is held once it stops), is linear in ``alpha = a*cos(phi)`` and
``beta = a*sin(phi)``. So for each ``k`` two responses (of ``sin(k*x)`` and ``cos(k*x)``)
are regressed on the residual by least squares (each move's offset removed, as in the fit),
and the residual sum of squares they remove is the score of ``k``. The wavelengths of the
highest local peaks start the fit of the ripple (:mod:`.fit`), which refines ``a``, the
wavelength and ``phi`` on the plant itself.

The grid spans wavelengths from :data:`LAMBDA_MIN` to the larger of :data:`LAMBDA_MAX` and
the span of positions the moves reach; its step in ``k`` is ``pi/(4*L)``, ``L`` that span: a
step moves the phase at the far end of the span by at most a quarter of a period.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from papwc.identify.simulate import Simulator

__all__ = ["LAMBDA_MAX", "LAMBDA_MIN", "SUBSTEPS", "Peak", "search", "wave_numbers"]

#: Shortest wavelength searched, m (the plant's shortest ripple period is 0.1 mm).
LAMBDA_MIN = 2e-4
#: Longest wavelength searched at least, m.
LAMBDA_MAX = 2e-2
#: Points per sample interval at which the trajectories are followed.
SUBSTEPS = 10
#: Most grid points (a wider span of positions is searched on this many).
GRID_MAX = 4000


@dataclass(frozen=True)
class Peak:
    """A local peak of the search: wavelength (m), the amplitude and phase (rad) the linear
    fit gives there, and the share of the residual sum of squares it removes."""

    wavelength: float
    amplitude: float
    phase: float
    share: float


def wave_numbers(span: float) -> np.ndarray:
    """The grid of wave numbers (rad/m) for moves spanning ``span`` m of positions."""
    longest = max(LAMBDA_MAX, span)
    k_min, k_max = 2.0 * math.pi / longest, 2.0 * math.pi / LAMBDA_MIN
    step = max(math.pi / (4.0 * max(span, LAMBDA_MIN)), (k_max - k_min) / GRID_MAX)
    return np.arange(k_min, k_max, step)


def _response(force_rows: np.ndarray, sliding: np.ndarray, q: float, gain: float, h: float
              ) -> np.ndarray:
    """A move's positions at its samples (each column one wave number, its mean removed)
    under the force ``force_rows`` acting while the table slides (rows where ``sliding``),
    through ``m*dv/dt = F - c*v`` stepped exactly (``q = exp(-c*h/m)``, ``gain = (1 -
    q)/c``) at the substeps ``h`` and held once the table stopped."""
    from scipy.signal import lfilter

    force = np.zeros((sliding.size, force_rows.shape[1]))
    force[sliding] = force_rows
    dv = lfilter([0.0, gain], [1.0, -q], force, axis=0)
    dv[~sliding] = 0.0
    dx = np.zeros_like(dv)
    np.cumsum(0.5 * h * (dv[1:] + dv[:-1]), axis=0, out=dx[1:])
    sampled = dx[::SUBSTEPS]
    return sampled - sampled.mean(axis=0)


def search(sim: Simulator, params: Mapping[str, Any], peaks: int = 3) -> list[Peak]:
    """The highest local peaks of the wavelength search (see the module), best first.

    Parameters
    ----------
    sim : Simulator
        The moves (sliding ones: the ripple acts while the table slides).
    params : mapping
        The plant fitted without ripple (its ``m``, ``f_c``, ``c`` and, where present,
        ``v_s``, ``delta_s``, ``tau_u``).
    peaks : int
        Peaks returned.

    Returns
    -------
    list of Peak
    """
    residual = sim.measured - sim.positions(params)
    span = float(np.ptp(sim.measured))
    ks = wave_numbers(span)
    m, c, f_c = float(params["m"]), float(params["c"]), float(params["f_c"])
    v_s, delta_s = float(params.get("v_s", 0.0)), float(params.get("delta_s", 2.0))
    h = sim.log.h / SUBSTEPS
    q = math.exp(-c * h / m)
    gain = -math.expm1(-c * h / m) / c if c > 0.0 else h / m
    g11, g12, g22, b1, b2 = (np.zeros(ks.size) for _ in range(5))
    for (xs, vs, f_b), start, size in zip(sim.trajectories(params, SUBSTEPS), sim.starts,
                                          sim._sizes, strict=True):
        sliding = vs != 0.0
        if not sliding.any():
            continue
        level = np.full(vs.shape, f_c)
        if v_s > 0.0:
            level = f_c + (f_b - f_c) * np.exp(-(np.abs(vs) / v_s) ** delta_s)
        weight = -(level * np.sign(vs))[sliding, np.newaxis]
        arg = xs[sliding, np.newaxis] * ks[np.newaxis, :]
        r = residual[start:start + size]
        r = r - r.mean()
        s_resp = _response(weight * np.sin(arg), sliding, q, gain, h)
        c_resp = _response(weight * np.cos(arg), sliding, q, gain, h)
        g11 += np.einsum("ij,ij->j", s_resp, s_resp)
        g12 += np.einsum("ij,ij->j", s_resp, c_resp)
        g22 += np.einsum("ij,ij->j", c_resp, c_resp)
        b1 += s_resp.T @ r
        b2 += c_resp.T @ r
    det = g11 * g22 - g12**2
    ok = det > 0.0
    alpha, beta, score = (np.zeros(ks.size) for _ in range(3))
    alpha[ok] = (g22[ok] * b1[ok] - g12[ok] * b2[ok]) / det[ok]
    beta[ok] = (g11[ok] * b2[ok] - g12[ok] * b1[ok]) / det[ok]
    score[ok] = alpha[ok] * b1[ok] + beta[ok] * b2[ok]
    total = float(np.sum(sim.project(residual) ** 2)) or 1.0
    local = np.flatnonzero((score[1:-1] >= score[:-2]) & (score[1:-1] >= score[2:])) + 1
    best = local[np.argsort(score[local])[::-1][:peaks]]
    return [Peak(2.0 * math.pi / float(ks[j]), float(math.hypot(alpha[j], beta[j])),
                 float(math.atan2(beta[j], alpha[j])), float(score[j]) / total) for j in best]
