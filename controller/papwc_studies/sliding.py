"""The sliding friction from the slides of the wide pulses, read through the encoder.

The one-pulse candidates (:mod:`papwc_studies.one_pulse`) narrow through the table's encoder
only when they are told the sliding friction ``f_c`` (the ceiling study's rows 19 and 20),
and the exact-model controller's Eq. (3) fit is no estimate of it (its ``f_c_hat`` spans
30-160 N on tables of 100 N). A maneuver of a millimetre or more makes wide pulses, and after
each the table slides fast, far above any Stribeck speed, while the force dies away through
the actuator's lag::

    m*dv/dt = F_0*exp(-t/tau_u) - f_c - c*v,        t >= 0 (the pulse's end)

with ``F_0 = u*(1 - exp(-n*T/tau_u))`` the force a pulse of ``n`` samples at ``u`` built up.
For given ``c`` and ``tau_u`` the position is linear in the position and speed at the
pulse's end and in ``f_c`` (:func:`slide_basis`); :func:`fit_slide` solves those by least
squares on a grid over ``c`` and ``tau_u``, refines ``c`` between the grid's neighbours of
the best, and keeps the least residual, on the readings from the pulse's end to the last
step of at least ``D_MIN``. The mass is told (``m_est``).

Not modelled: the friction ripple (the slide averages it over its millimetres), the
Stribeck curve (left out by ``D_MIN``).

``python -m papwc_studies.sliding`` runs the exact-model controller's first iteration toward
10 mm and 1 mm on each rigid stick–slip table of ``realism_mc.toml`` and
``realism_mc_fresh.toml`` (the in-process plant, through the table's encoder) and prints, per
table, the sliding friction each wide pulse's slide gives and their median (``--no-ripple``:
the same tables without their friction ripple).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import statistics
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from papwc_studies.one_pulse import lag_share

__all__ = ["BAND", "BATTERY", "C_GRID", "D_MIN", "TAU_GRID", "battery_exact", "controller_slides",
           "f_c_band", "fit_slide", "slide_basis", "slides"]

#: A step of the slide counts while it is at least this long (m a sample; 0.1 mm at 10 ms
#: is 10 mm/s, where a Stribeck curve of up to 5 mm/s has let go of all but 2 % of its
#: excess).
D_MIN = 1e-4
#: The grids of the viscous damping (N.s/m) and of the actuator lag (s) the slides are
#: fitted over.
C_STEP = 1.1
C_GRID = tuple(100.0 * C_STEP**k for k in range(41))
#: Golden-section steps refining the damping between the grid's neighbours of the best.
C_REFINE = 20
TAU_GRID = tuple(2.5e-4 * k for k in range(25))
#: The battery whose exact-model controller and maneuver make the slides.
BATTERY = "realism_mc.toml"
#: The band of f_c the slides leave is widened by this share of their median on each side.
BAND = 0.1
#: Readings of a slide needed for a fit (three unknowns, two grid coordinates).
MIN_READINGS = 6


def slide_basis(t: np.ndarray, c: float, tau_u: float, m: float) -> np.ndarray:
    """Columns of the slide's position from its end-of-pulse state, m: ``x(t) = x_0*1 +
    v_0*B_1(t) + F_0*B_2(t) - f_c*B_3(t)`` for the damping c (N.s/m), the lag tau_u (s) and
    the mass m (kg); returns ``[1, B_1, B_2, B_3]`` (shape (len(t), 4))."""
    a = c / m
    decay = -np.expm1(-a * t) / a  # integral of exp(-a*s) from 0 to t
    b_v = decay
    b_f = (t - decay) / c
    if tau_u > 0.0:
        r = 1.0 / tau_u
        if abs(a - r) < 1e-9 * r:
            r *= 1.0 + 1e-6
        b_u = (-np.expm1(-r * t) / r - decay) / (m * (a - r))
    else:
        b_u = np.zeros_like(t)
    return np.column_stack([np.ones_like(t), b_v, b_u, b_f])


def fit_slide(x: Sequence[float], u: float, n: int, T: float, m: float
              ) -> tuple[float, float, float, float]:
    """The sliding friction of one slide: ``x`` the readings (m) from the pulse's end (its
    last sample's end) every T (s), the pulse ``n`` samples at ``u`` (N, along the slide);
    returns ``(f_c, c, tau_u, rms)``: N, N.s/m, s, and the readings' rms residual (m)."""
    x = np.asarray(x, dtype=float)
    t = T * np.arange(len(x))

    def solve(c: float, tau_u: float) -> tuple[float, float]:
        f_0 = u * float(lag_share(np.float64(tau_u), n * T))
        basis = slide_basis(t, c, tau_u, m)
        # the force's part is known: F_0 times its column
        rhs = x - f_0 * basis[:, 2]
        cols = basis[:, [0, 1, 3]]
        coef, *_ = np.linalg.lstsq(cols, rhs, rcond=None)
        return float(np.sum((cols @ coef - rhs) ** 2)), -float(coef[2])

    res, c, tau_u = min((solve(c, tau_u)[0], c, tau_u) for tau_u in TAU_GRID for c in C_GRID)
    # the damping between the grid's neighbours of the best (golden-section search on log c)
    lo, hi = math.log(c / C_STEP), math.log(c * C_STEP)
    g = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(C_REFINE):
        x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
        if solve(math.exp(x1), tau_u)[0] <= solve(math.exp(x2), tau_u)[0]:
            hi = x2
        else:
            lo = x1
    c_fine = math.exp(0.5 * (lo + hi))
    res_fine, f_c = solve(c_fine, tau_u)
    if res_fine <= res:
        res, c = res_fine, c_fine
    else:
        f_c = solve(c, tau_u)[1]
    return f_c, c, tau_u, math.sqrt(res / len(x))


def slides(x_meas: Sequence[float], u: Sequence[float], T: float, m: float
           ) -> list[tuple[int, int, float, float, float, float]]:
    """Every slide after a pulse of at least two samples in a trace (``x_meas`` the readings
    at each sample, m; ``u`` the force applied over the sample that follows, N): ``(k, n,
    f_c, c, tau_u, rms)``, the sample the pulse ended at and its width, then
    :func:`fit_slide`'s results."""
    out = []
    k, total = 0, len(u)
    while k < total:
        if u[k] == 0.0 or not math.isfinite(u[k]):
            k += 1
            continue
        start, height = k, u[k]
        while k < total and u[k] == height:
            k += 1
        n, end = k - start, k
        if n < 2 or end >= total:
            continue
        sign = math.copysign(1.0, height)
        last = end
        while (last + 1 < len(x_meas) and last + 1 < total and u[last] == 0.0
               and sign * (x_meas[last + 1] - x_meas[last]) >= D_MIN):
            last += 1
        readings = [sign * (xi - x_meas[end]) for xi in x_meas[end:last + 1]]
        if len(readings) >= MIN_READINGS:
            out.append((end, n, *fit_slide(readings, abs(height), n, T, m)))
    return out


@functools.cache
def battery_exact() -> tuple[Any, Any]:
    """The exact-model controller's settings and the maneuver of ``realism_mc.toml``'s rigid
    runs (read once a process)."""
    from papwc.battery.plan import plan_runs
    from papwc.battery.schema import load_battery
    from papwc.scenario import parse_scenario
    from papwc_studies import scenario_path

    path = scenario_path(BATTERY)
    run = next(r for r in plan_runs([load_battery(path)]) if r.case == "rigid")
    scenario = parse_scenario(run.data, f"{path} run {run.run_id}")
    labels = list(scenario.labels)
    return scenario.controllers[labels.index("exact")], scenario.maneuver


def controller_slides(params: dict[str, float]) -> list[tuple[int, int, float, float, float,
                                                                 float]]:
    """:func:`slides` of the exact-model controller's first iterations toward 10 mm and 1 mm
    (its settings and maneuver period and length those of ``realism_mc.toml``) on the table
    of plant parameters ``params``, the in-process plant read through its encoder."""
    from papwc.master import PhysicsSlave, run_controller

    settings, maneuver = battery_exact()
    found = []
    for x_ref in (1e-2, 1e-3):
        plant = PhysicsSlave()
        plant.set_start_values(dict(params))
        once = dataclasses.replace(maneuver, x_ref=x_ref, iterations=1)
        trace = run_controller(plant, settings, once).traces[0]
        found += slides(trace.columns["x_meas"], trace.columns["u"], once.T, settings.m_est)
    return found


def f_c_band(params: dict[str, float]) -> tuple[float, float]:
    """The band of sliding friction (N) the controller's slides on a table leave
    (:func:`controller_slides`): from the least to the greatest of their ``f_c``, each side
    widened by ``BAND`` of their median ((0, inf): no slide)."""
    f_cs = [f for _, _, f, _, _, _ in controller_slides(params)]
    if not f_cs:
        return 0.0, math.inf
    margin = BAND * statistics.median(f_cs)
    return min(f_cs) - margin, max(f_cs) + margin


def main(argv: Sequence[str] | None = None) -> int:
    from papwc_studies.ceiling import tables

    parser = argparse.ArgumentParser(prog="python -m papwc_studies.sliding",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--no-ripple", action="store_true",
                        help="the same tables without their friction ripple")
    args = parser.parse_args(argv)
    t_start = time.process_time()
    every = []
    for name in ("realism_mc.toml", "realism_mc_fresh.toml"):
        for i, params in enumerate(tables(name)):
            if args.no_ripple:
                params = {**params, "ripple": 0.0}
            found = controller_slides(params)
            f_cs = [f for _, _, f, _, _, _ in found]
            med = statistics.median(f_cs) if f_cs else math.nan
            every.append(med)
            print(f"{name} table {i}: tau_u {params.get('tau_u', 0) * 1e3:.2f} ms, ripple "
                  f"{params.get('ripple', 0):.3f} over {params.get('ripple_period', 0) * 1e3:.2f}"
                  f" mm: {len(found)} slides, f_c " + ", ".join(f"{f:.1f}" for f in f_cs)
                  + f"; median {med:.1f} N; c " + ", ".join(f"{c:.0f}" for _, _, _, c, _, _
                                                          in found)
                  + "; tau_u " + ", ".join(f"{tau * 1e3:.2f}" for *_, tau, _ in found))
    good = [f for f in every if math.isfinite(f)]
    print(f"{len(good)} of {len(every)} tables with a slide; median f_c from "
          f"{min(good):.1f} to {max(good):.1f} N (the tables: 100 N); "
          f"{sum(1 for f in good if abs(f - 100.0) <= 5.0)} within 5 N, "
          f"{sum(1 for f in good if abs(f - 100.0) <= 10.0)} within 10 N; "
          f"{time.process_time() - t_start:.0f} s of processor time", file=sys.stdout)
    return 0


if __name__ == "__main__":
    from papwc.exit_status import run_command

    sys.exit(run_command("python -m papwc_studies.sliding", main))
