"""The figures behind the spec's bound (papwc_studies.bound_physics), on the model layer."""

from __future__ import annotations

import pytest

from papwc_studies import bound_physics as study


def test_the_move_grows_from_zero_and_a_lag_needs_more_excess() -> None:
    """Without lag one count needs 0.30 N over the height that breaks the table away (v_s =
    1 mm/s); with a 2.5 ms lag 5.6 N: the force reaches the band top only as it falls."""
    assert study.excess_for_one_count(1e-3, 0.0) == pytest.approx(0.302, abs=0.005)
    assert study.excess_for_one_count(1e-3, 2.5e-3) == pytest.approx(5.6, abs=0.05)


def test_a_fresh_stick_moves_tens_of_micrometres() -> None:
    """One sample sure to break away anywhere in a 15 % band with 15 % ripple, on a stick
    drawn at the band's bottom, moves about 54 um (v_s = 1 mm/s, no lag, 5 mm period)."""
    assert study.fresh_stick_move(1e-3, 0.0, 5e-3) == pytest.approx(54.1e-6, rel=0.01)


def test_the_staircase_counts_the_approaches_whose_first_seen_move_runs_away() -> None:
    """v_s = 0.2 mm/s, no lag: some of 40 approaches from 1 um pass 1.5*abs(e) + q."""
    runaways, approaches = study.staircase_runaways(2e-4, 0.0, 40)
    assert approaches == 40 and 0 < runaways < 20
