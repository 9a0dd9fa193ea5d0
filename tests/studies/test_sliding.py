"""The sliding friction read from the slides after wide pulses (papwc_studies.sliding)."""

from __future__ import annotations

import math
import statistics

import pytest

from papwc.model.dynamics import Plant
from papwc_studies import ceiling, sliding
from papwc_studies.sliding import fit_slide, slides

T = ceiling.T
#: A Monte Carlo table without ripple, noise or random stiction.
TABLE = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0, "v_s": 2e-3}


def trace(params: dict, pulses: list[tuple[int, float]], rest: int = 20
          ) -> tuple[list[float], list[float]]:
    """Readings and forces of the model layer's plant given each pulse (samples, N) from
    rest, ``rest`` samples of no force after each."""
    plant = Plant(params)
    xs, us = [], []
    for n, u in pulses:
        for force in [u] * n + [0.0] * rest:
            xs.append(plant.x_meas())
            us.append(force)
            plant.step(force, T)
    return xs, us


@pytest.mark.parametrize("tau_u", [0.0, 1.5e-3, 4e-3])
def test_a_slide_gives_the_tables_sliding_friction_and_damping(tau_u):
    xs, us = trace({**TABLE, "tau_u": tau_u}, [(5, 260.0), (6, -280.0), (7, 240.0)])
    found = slides(xs, us, T, TABLE["m"])
    assert [(k, n) for k, n, *_ in found] == [(5, 5), (31, 6), (58, 7)]
    for _, _, f_c, c, tau, rms in found:
        # the slide follows the model of the fit: friction and damping as the table's, the
        # lag within three of the grid's steps (it trades against the damping)
        assert f_c == pytest.approx(100.0, rel=0.015)
        assert c == pytest.approx(700.0, rel=0.06)
        assert tau == pytest.approx(tau_u, abs=7.6e-4)
        assert rms < 2e-7
    if tau_u == 4e-3:
        # a lag on the grid: the slides are the fit's model exactly
        assert all(f_c == pytest.approx(100.0, rel=1e-6) for _, _, f_c, *_ in found)


def test_the_encoders_noise_costs_a_few_newtons():
    params = {**TABLE, "tau_u": 2e-3, "x_resolution": 1e-7, "noise_std": 4e-7, "seed": 3}
    xs, us = trace(params, [(5, 260.0), (6, -260.0), (8, 250.0)])
    f_cs = [f for _, _, f, *_ in slides(xs, us, T, TABLE["m"])]
    assert len(f_cs) == 3
    assert all(abs(f - 100.0) < 2.0 for f in f_cs)


def test_one_sample_pulses_slow_slides_and_missing_forces_give_no_slide():
    xs, us = trace({**TABLE, "tau_u": 1e-3}, [(1, 300.0), (3, 140.0)])
    # one sample is no wide pulse; 3 samples at 140 N slide slower than D_MIN a sample
    assert slides(xs, us, T, TABLE["m"]) == []
    us[3] = math.nan
    assert slides(xs, us, T, TABLE["m"]) == []


def test_a_slide_too_short_is_not_fitted():
    # a pulse of two samples, then three steps of the slide at least D_MIN long
    xs = [0.0, 1e-4, 3e-4, 5e-4, 7e-4, 8.5e-4, 8.6e-4, 8.6e-4]
    us = [200.0, 200.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    assert len(xs[2:6]) < sliding.MIN_READINGS
    assert slides(xs, us, T, TABLE["m"]) == []
    # any readings give numbers on the grids' span
    f_c, c, tau_u, rms = fit_slide([0.0, 4e-4, 7e-4, 9e-4, 1.0e-3, 1.05e-3], 200.0, 3, T, 150.0)
    assert math.isfinite(f_c) and math.isfinite(rms) and rms >= 0.0
    assert sliding.C_GRID[0] / sliding.C_STEP <= c <= sliding.C_GRID[-1] * sliding.C_STEP
    assert tau_u in sliding.TAU_GRID


def test_the_controllers_slides_bound_the_sliding_friction():
    # the exact-model controller's first 10 mm and 1 mm moves on a table with a lag, read
    # through a noisy encoder: the band holds the table's f_c and is narrower than the
    # ceiling study's grid of it (60-130 N)
    params = {**TABLE, "tau_u": 3e-3, "f_s_spread": 0.1, "x_resolution": 1e-7,
              "noise_std": 3e-7, "seed": 5}
    found = sliding.controller_slides(params)
    assert len(found) >= 2
    lo, hi = sliding.f_c_band(params)
    f_cs = [f for _, _, f, *_ in found]
    assert lo == pytest.approx(min(f_cs) - sliding.BAND * statistics.median(f_cs))
    assert lo < 100.0 < hi and hi - lo < 40.0
