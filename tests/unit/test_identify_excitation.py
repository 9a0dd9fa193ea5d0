"""The excitation of ``papwc identify --design``: its bounds (f_p_max, the travel on every
plant within +-50 % of the expected one) and its refusals."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from papwc.identify import IdentifyError
from papwc.identify.excitation import LEVEL_RATIO, apply_to_plant, design
from papwc.model.stickslip import simulate

H = 0.01


def test_the_design_stays_within_f_p_max_and_the_travel_on_every_corner_plant():
    u = design(H, 250.0, 0.02, 60.0)
    assert u.size == 6000
    assert float(np.max(np.abs(u))) <= 250.0
    assert (u > 0).any() and (u < 0).any()
    for a, b, d in itertools.product((0.5, 1.5), repeat=3):
        m, f_c, c = 150.0 * a, 100.0 * b, 700.0 * d
        states = simulate(list(u), H, m, f_c, f_c, c)
        assert max(abs(x) for x, _ in states) <= 0.02


def test_the_staircase_brackets_every_breakaway_in_the_spread_to_one_step():
    u = design(H, 300.0, 0.05, 60.0)
    levels = np.unique(np.abs(u[u != 0.0]))
    for f_s in (65.0, 130.0, 194.0):
        below = levels[levels <= f_s].max()
        above = levels[levels > f_s].min()
        assert above / below <= LEVEL_RATIO + 1e-12


def test_a_plant_at_the_design_rests_between_pulses():
    u = design(H, 300.0, 0.05, 60.0)
    log = apply_to_plant(u, H, {"m": 225.0, "f_c": 50.0, "f_s": 65.0, "c": 350.0})
    # Every pulse starts from rest: before each nonzero force after a zero one, the last
    # two intervals did not move.
    starts = [k for k in range(2, u.size) if u[k] != 0.0 and u[k - 1] == 0.0]
    dx = np.diff(log.x)
    assert all(dx[k - 1] == 0.0 and dx[k - 2] == 0.0 for k in starts)


@pytest.mark.parametrize("kwargs, message", [
    ({"f_p_max": 100.0}, "--f-p-max 100.0 N: must exceed 1.1*f_s"),
    ({"travel": 1e-5}, "--travel 1e-05 m: too short"),
    ({"duration": 5.0}, "--duration 5.0 s: too short"),
])
def test_a_design_that_cannot_be_made_is_refused(kwargs, message):
    args = {"h": H, "f_p_max": 300.0, "travel": 0.05, "duration": 60.0, **kwargs}
    with pytest.raises(IdentifyError) as info:
        design(**args)
    assert str(info.value).startswith(message)
