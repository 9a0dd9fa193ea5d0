"""The paper's quantitative statements recomputed from its formulas (Table 1).

Each entry of :func:`formula_numbers` is ``(quantity, paper's value, computed value)``;
the computations use the pulse model of :mod:`papwc.model.pulse` (Eq. (3), (4)
and their inverses), and Eq. (19)/(20) as printed (:func:`d_min`).
"""

from __future__ import annotations

import math

from papwc.model.pulse import b_coulomb, pulse_displacement, pulse_response, pulse_width

#: Table 1 of the paper (SI units).
TABLE_1 = {"m": 150.0, "f_c": 100.0, "c": 700.0, "f_s": 130.0, "f_p": 300.0, "T": 0.01}


def d_min(f_p: float, T: float, m: float, f_c: float, c: float) -> float:
    """Displacement of a one-sample pulse, Eq. (19) (Eq. (20) with f_p = f_s), as printed.

    ``f_p*T/c - (m*f_c/c**2)*log((f_p/f_c)*(exp(c*T/m) - 1) + 1)``, the form the
    paper evaluates; it is Eq. (3) at t_p = T and agrees with
    :func:`papwc.model.pulse.pulse_displacement` to about 1e-14 relative (the
    printed form cancels). Requires ``c > 0``.

    Parameters
    ----------
    f_p : float
        Pulse height, N (> f_c).
    T : float
        Sample period, s.
    m, f_c, c : float
        Mass (kg), Coulomb friction (N), viscous damping (N.s/m).

    Returns
    -------
    float
        Displacement, m.
    """
    return f_p * T / c - (m * f_c / c**2) * math.log((f_p / f_c) * math.expm1(c * T / m) + 1.0)


def formula_numbers(p: dict[str, float] = TABLE_1) -> list[tuple[str, str, float]]:
    """The reading notes' table: quantities the paper states, recomputed."""
    m, f_c, c, f_s, f_p, T = (p[k] for k in ("m", "f_c", "c", "f_s", "f_p", "T"))
    b = b_coulomb(f_p, m, f_c)  # Eq. (4)
    t3 = pulse_width(0.01, f_p, m, f_c, c)
    t4 = math.sqrt(0.01 / b)
    b_line = 0.01 / t3**2  # the b_hat that makes Eq. (4) hit 0.01 m
    b_03 = pulse_displacement(f_p, 0.03, m, f_c, c) / 0.03**2
    t_line = math.sqrt(0.002 / b_line)
    t_true = pulse_width(0.002, f_p, m, f_c, c)
    d19 = d_min(f_p, T, m, f_c, c)
    d20 = d_min(f_s, T, m, f_c, c)
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
         pulse_displacement(f_p, t_line, m, f_c, c)),
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
        d, v1, t_rest = pulse_response(p["f_p"], t_p, p["m"], p["f_c"], p["c"])
        out.append({"t_p": t_p, "d": d, "v_end": v1, "t_rest": t_rest})
    return out
