"""papwc_studies.ringing: what pulses do to the flexible drive of scenarios/realism.toml."""

from __future__ import annotations

import re

import pytest

from papwc_studies import ringing


@pytest.mark.slow
def test_a_flexible_drive_has_a_smallest_move_and_keeps_ringing(capsys):
    ringing.main([])
    out = capsys.readouterr().out
    moves = [float(v) for v in re.findall(r"moves +([-0-9.]+) um(?! there)", out)]
    rings = [float(v) for v in re.findall(r"leaves +([-0-9.]+) N ringing", out)]
    n_heights = len(ringing.HEIGHTS)
    assert len(moves) == n_heights + 1 + len(ringing.WAITS) and len(rings) == n_heights + 1
    one_period = moves[:n_heights]
    # below the breakaway nothing moves; the first height that moves jumps by > 10 um
    assert one_period[0] == 0.0 and min(m for m in one_period if m > 0.0) > 10.0
    assert one_period == sorted(one_period)
    # every pulse that moved leaves the drive ringing; one sample leaves more than a period
    assert all(r > 1.0 for r in rings) and rings[-1] > 2.0 * max(rings[:n_heights])
    # the same pulse again moves from nothing to nearly what the first moved, by the wait
    again = moves[n_heights + 1:]
    assert min(again) == 0.0 and max(again) > 0.8 * one_period[ringing.HEIGHTS.index(75.0)]
    # the smallest move: just above its breakaway height every width moves some um at once,
    # and more for each newton above
    smallest = re.findall(r"breakaway of a (\d+)-sample pulse at ([0-9.]+) N: moves +([0-9.]+) um "
                          r"there and +([0-9.]+) um", out)
    assert [int(k) for k, *_ in smallest] == [1, 2, 5]
    for *_, there, above in smallest:
        assert float(there) > 5.0 and float(above) > float(there) + 1.0
    # the one-period breakaway lies between the heights above that did not and did move
    assert 67.0 < float(smallest[2][1]) <= 67.5


def test_the_breakaway_height_is_found_by_bisection():
    f_b = ringing.breakaway_height(lambda f: max(f - 123.456, 0.0))
    assert abs(f_b - 123.456) <= ringing.THRESHOLD_TOL
    assert ringing.breakaway_height(lambda f: 0.0) != ringing.breakaway_height(lambda f: 0.0)


def test_an_argument_is_refused_in_one_line(capsys):
    with pytest.raises(SystemExit) as stop:
        ringing.main(["--pulses", "3"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith("error: unrecognized arguments: --pulses 3")
