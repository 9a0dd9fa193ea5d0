"""The stiction band of ``papwc identify``: the prediction interval for the next draws, the
sticks it needs, the point estimates."""

from __future__ import annotations

import numpy as np
import pytest

from papwc.identify.band import (
    COVERAGE,
    NEXT_DRAWS,
    WIDTH_MAX,
    band_of,
    expected_width,
    prediction_factor,
    sticks_needed,
)


@pytest.mark.parametrize("n", [6, 14, 30])
def test_the_band_holds_the_next_draws_as_often_as_it_says(n):
    # uniform draws on [100, 130] N, 20000 bands: the share whose band holds all the next
    # NEXT_DRAWS draws is COVERAGE within the Monte Carlo's error (3 standard errors)
    rng = np.random.default_rng(n)
    trials = 20000
    seen = 100.0 + 30.0 * rng.random((trials, n))
    following = 100.0 + 30.0 * rng.random((trials, NEXT_DRAWS))
    delta = prediction_factor(n)
    lo, hi = seen.min(axis=1), seen.max(axis=1)
    span = hi - lo
    holds = np.all((following >= (lo - delta * span)[:, None])
                   & (following <= (hi + delta * span)[:, None]), axis=1)
    error = 3.0 * np.sqrt(COVERAGE * (1.0 - COVERAGE) / trials)
    assert abs(holds.mean() - COVERAGE) < error
    # a band 20 % narrower does not
    narrower = np.all((following >= (lo - 0.8 * delta * span)[:, None])
                      & (following <= (hi + 0.8 * delta * span)[:, None]), axis=1)
    assert narrower.mean() < COVERAGE - error


def test_the_sticks_needed_are_the_fewest_within_the_width():
    n = sticks_needed()
    assert expected_width(n) <= WIDTH_MAX < expected_width(n - 1)


def test_a_band_of_uniform_draws_estimates_f_s_and_the_spread():
    rng = np.random.default_rng(7)
    draws = 130.0 * (1.0 + 0.1 * (2.0 * rng.random(200) - 1.0))
    band = band_of(draws)
    assert band.f_s == pytest.approx(130.0, rel=0.005)
    assert band.spread == pytest.approx(0.1, rel=0.05)
    assert band.spread_low <= 0.1 <= band.spread_high
    assert band.f_s_low <= 130.0 <= band.f_s_high
    assert band.low <= band.lowest == draws.min() and band.highest == draws.max() <= band.high
    assert not band.single and band.sticks == 200


def test_draws_placed_by_few_get_the_band_of_few():
    draws = [120.0, 125.0, 130.0] + [121.0 + 0.1 * k for k in range(80)]
    assert band_of(draws, sticks=3).factor == prediction_factor(3)
    assert band_of(draws).factor == prediction_factor(len(draws))


def test_brackets_that_all_overlap_are_one_breakaway():
    band = band_of([129.9, 130.1, 130.0], brackets=[(129.5, 130.4), (129.8, 130.6),
                                                    (129.0, 130.2)])
    assert band.single and band.spread == 0.0
    assert band.f_s == pytest.approx(0.5 * (129.8 + 130.2))


@pytest.mark.parametrize("draws, message", [
    ([130.0, 131.0], "2 breakaway(s) seen; a band needs at least 3"),
    ([130.0, float("nan"), 131.0], "not a finite positive number"),
])
def test_too_few_or_bad_draws_are_refused(draws, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        band_of(draws)
