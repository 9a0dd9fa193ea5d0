"""The paper's quantitative statements recomputed from its formulas (Table 1).

Each entry of :func:`formula_numbers` is ``(quantity, paper's value, computed value)``;
the computations use the exact pulse response of ``papwc_stickslip``.
"""

from __future__ import annotations

import math

from papwc.core.pwc import b_coulomb
from papwc.fmu_src import papwc_stickslip as physics

#: Table 1 of the paper (SI units).
TABLE_1 = {"m": 150.0, "f_c": 100.0, "c": 700.0, "f_s": 130.0, "f_p": 300.0, "T": 0.01}


def width_for_displacement(d: float, f_p: float, m: float, f_c: float, f_s: float,
                           c: float) -> float:
    """Pulse width t_p (s) whose exact displacement, Eq. (3), is ``d`` (m); by bisection."""
    lo, hi = 0.0, 1.0
    while physics.pulse_displacement(f_p, hi, m, f_c, f_s, c) < d:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if physics.pulse_displacement(f_p, mid, m, f_c, f_s, c) < d:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def formula_numbers(p: dict[str, float] = TABLE_1) -> list[tuple[str, str, float]]:
    """The reading notes' table: quantities the paper states, recomputed."""
    m, f_c, c, f_s, f_p, T = (p[k] for k in ("m", "f_c", "c", "f_s", "f_p", "T"))
    b = b_coulomb(f_p, m, f_c)  # Eq. (4)
    t3 = width_for_displacement(0.01, f_p, m, f_c, f_s, c)
    t4 = math.sqrt(0.01 / b)
    b_line = 0.01 / t3**2  # the b_hat that makes Eq. (4) hit 0.01 m
    b_03 = physics.pulse_displacement(f_p, 0.03, m, f_c, f_s, c) / 0.03**2
    t_line = math.sqrt(0.002 / b_line)
    t_true = width_for_displacement(0.002, f_p, m, f_c, f_s, c)
    d19 = physics.d_min(f_p, T, m, f_c, c)
    d20 = physics.d_min(f_s, T, m, f_c, c)
    b0 = b_coulomb(f_p, m, 0.8 * f_c)
    return [
        ("b = f_p(f_p - f_c)/(2 m f_c) (m/s^2)", "", b),
        ("t_p for d = 0.01 m, Eq. (3) (s)", "0.092", t3),
        ("t_p for d = 0.01 m, Eq. (4) (s)", "0.070", t4),
        ("b_hat that makes Eq. (4) hit 0.01 m (/b)", "0.6", b_line / b),
        ("b_hat at t_p,max = 0.03 s (/b)", "0.81", b_03 / b),
        ("t_p for 2.0 mm on the b_hat line (s)", "0.041", t_line),
        ("t_p for 2.0 mm, exact (s)", "0.036", t_true),
        ("true displacement of that b_hat-line pulse (m)", "0.0025",
         physics.pulse_displacement(f_p, t_line, m, f_c, f_s, c)),
        ("d_min, Eq. (19), one sample at f_p (m)", "1.9e-4", d19),
        ("d_min, Eq. (20), one sample at f_s (m)", "1.3e-5", d20),
        ("ratio Eq. (19) / Eq. (20)", "15", d19 / d20),
        ("b_hat(0)/b with f_c,est = 0.8 f_c", "1.375", b0 / b),
    ]


def single_pulses(p: dict[str, float] = TABLE_1,
                  widths: tuple[float, ...] = (0.01, 0.03, 0.07, 0.092)) -> list[dict]:
    """Single pulses from rest on the exact plant: d (m), velocity at pulse end (m/s),
    time back at rest (s)."""
    out = []
    for t_p in widths:
        d, v1, t_rest = physics.pulse_response(p["f_p"], t_p, p["m"], p["f_c"], p["f_s"],
                                                p["c"])
        out.append({"t_p": t_p, "d": d, "v_end": v1, "t_rest": t_rest})
    return out
