"""The excitation of ``papwc identify --design``: its bounds (f_p_max, the travel on every
plant within +-50 % of the expected one), the teeth the stiction band needs, and its
refusals."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from papwc.identify import IdentifyError
from papwc.identify.band import sticks_needed
from papwc.identify.excitation import (
    TEETH,
    TOOTH_HIGH,
    TOOTH_LOW,
    TOOTH_RATIO,
    apply_to_plant,
    design,
    design_plan,
)
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


def _teeth(plan) -> list[np.ndarray]:
    """The levels of each tooth: runs of one-sample pulses one zero sample apart."""
    u = plan.u[:plan.teeth_end]
    teeth, current = [], []
    k = 0
    while k < u.size:
        if u[k] != 0.0 and (k + 1 >= u.size or u[k + 1] == 0.0) and (k == 0 or u[k - 1] == 0.0):
            if current and k - current[-1][0] > 2:
                teeth.append(np.array([abs(f) for _, f in current]))
                current = []
            current.append((k, u[k]))
        k += 1
    if current:
        teeth.append(np.array([abs(f) for _, f in current]))
    return [t for t in teeth if t.size == plan.levels]


def test_the_design_has_the_teeth_the_band_needs_each_rising_through_the_breakaway():
    plan = design_plan(H, 300.0, 0.05, 60.0)
    assert plan.teeth == TEETH == sticks_needed()
    teeth = _teeth(plan)
    assert len(teeth) == TEETH
    for tooth in teeth:
        ratios = tooth[1:] / tooth[:-1]
        assert np.all(ratios > 1.0) and np.all(ratios <= TOOTH_RATIO * (1 + 1e-12))
        assert tooth[0] <= TOOTH_LOW * 130.0 * TOOTH_RATIO
        assert tooth[-1] >= TOOTH_HIGH * 130.0 / TOOTH_RATIO
    # staggered: together they bracket a fixed breakaway far finer than one step
    levels = np.unique(np.concatenate(teeth))
    for f_s in (100.0, 130.0, 170.0):
        below, above = levels[levels <= f_s].max(), levels[levels > f_s].min()
        assert above / below <= 1.0 + (TOOTH_RATIO - 1.0) / TEETH * 1.5
    assert str(TEETH) in plan.summary()


def test_a_plant_at_the_design_rests_before_every_tooth_and_walk_pulse():
    plan = design_plan(H, 300.0, 0.05, 60.0)
    u = plan.u
    log = apply_to_plant(u, H, {"m": 225.0, "f_c": 50.0, "f_s": 65.0, "c": 350.0})
    dx = np.diff(log.x)
    # every pulse wider than one sample (the walk's) starts from rest
    starts = [k for k in range(2, u.size - 1) if u[k] != 0.0 and u[k - 1] == 0.0
              and u[k + 1] == u[k]]
    assert starts
    assert all(dx[k - 1] == 0.0 and dx[k - 2] == 0.0 for k in starts)


@pytest.mark.parametrize("kwargs, message", [
    ({"f_p_max": 100.0}, "--f-p-max 100.0 N: must exceed 1.1*f_s"),
    ({"travel": 1e-5}, "--travel 1e-05 m: too short"),
    ({"duration": 5.0}, "--duration 5.0 s: too short; the 14 teeth the stiction band needs"),
])
def test_a_design_that_cannot_be_made_is_refused(kwargs, message):
    args = {"h": H, "f_p_max": 300.0, "travel": 0.05, "duration": 60.0, **kwargs}
    with pytest.raises(IdentifyError) as info:
        design(**args)
    assert str(info.value).startswith(message)
