"""The one-pulse model of a stuck stick–slip table, vectorized over candidate tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from papwc.model.dynamics import Plant
from papwc_studies import ceiling
from papwc_studies.one_pulse import FRESH_MOVES, Candidates, TableEvidence, one_pulse
from papwc_studies.sliding import f_c_band

T = ceiling.T
HORIZON = ceiling.CYCLE
#: A table of the Monte Carlo's kind without ripple (not modelled) and without noise.
TABLE = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0, "v_s": 1e-3, "f_s_spread": 0.1,
         "seed": 2}


@pytest.mark.parametrize("tau_u, v_s", [(0.0, 1e-3), (1.2e-3, 3e-4), (4.5e-3, 4e-3)])
def test_the_model_moves_as_the_model_layers_plant(tau_u, v_s):
    params = {**TABLE, "tau_u": tau_u, "v_s": v_s}
    plant = Plant(params)
    for _ in range(3):
        plant.step(0.0, T)
    state = plant.state()
    compared = 0
    for f_b in (104.0, 131.0, 146.0):
        for u in (1.02 * f_b, 1.2 * f_b, 1.6 * f_b, -1.2 * f_b):
            plant.set_state(state)
            plant.f_s_now = f_b
            first, d = ceiling.pulse_path(plant, u)
            model_first, model_d = one_pulse(u, f_b, tau_u, v_s, TABLE["f_c"], m=TABLE["m"],
                                             c=TABLE["c"], T=T, horizon=HORIZON)
            assert np.sign(model_d) == np.sign(d)
            # the same physics, integrated in fixed steps: within 1 % of the move and of the
            # first reading (moves of a nanometre or more)
            if abs(d) > 1e-9:
                compared += 1
                assert model_d == pytest.approx(d, rel=1e-2)
                assert model_first == pytest.approx(first, rel=1e-2, abs=1e-12)
    assert compared >= 8


def test_a_sample_the_lag_keeps_below_the_breakaway_does_not_move():
    tables = Candidates({"tau_u": (0.0, 2e-3, 5e-3)}, {**TABLE, "tau_u": 0.0}, T=T,
                        horizon=HORIZON)
    every = np.arange(len(tables))
    held = tables.held(150.0, every)
    # the force the lag lets through by the sample's end: 150 N without lag, less with it
    assert held[0] == 150.0 and held[0] > held[1] > held[2] > TABLE["f_c"]
    assert np.all(tables.moves(150.0, held * (1.0 + 1e-9), every)[1] == 0.0)
    assert np.all(tables.moves(150.0, held * (1.0 - 1e-3), every)[1] > 0.0)
    # and, on the model layer's plant, the same pulse at that breakaway holds too
    plant = Plant({**TABLE, "tau_u": 5e-3})
    plant.f_s_now = float(held[2]) * (1.0 + 1e-9)
    assert ceiling.pulse(plant, 150.0) == 0.0
    plant = Plant({**TABLE, "tau_u": 5e-3})
    plant.f_s_now = float(held[2]) * (1.0 - 1e-3)
    assert ceiling.pulse(plant, 150.0) > 0.0


def test_the_implied_breakaway_and_the_plan_invert_the_model():
    grids = {"tau_u": (0.0, 3e-3), "v_s": (3e-4, 2e-3), "f_c": (80.0, 100.0)}
    tables = Candidates(grids, TABLE, T=T, horizon=HORIZON)
    assert len(tables) == 8 and tables.index.shape == (8, 3)
    every = np.arange(8)
    for u, d in ((180.0, 2e-5), (-160.0, -3e-6)):
        f_b = tables.implied(u, d, every)
        assert np.all((f_b >= tables.values["f_c"]) & (f_b <= abs(u)))
        np.testing.assert_allclose(tables.moves(u, f_b, every)[1], d, rtol=1e-3)
    for e in (4e-5, -7e-6):
        height = tables.plan(e, np.full(8, 135.0), every, ceiling.F_P_MAX)
        assert np.all(np.sign(height) == np.sign(e))
        moved = tables.moves(height, 135.0, every)[1]
        assert np.all(np.abs(moved) <= abs(e))
        # a newton higher moves farther than |e|: the highest such pulse
        assert np.all(np.abs(tables.moves(height + np.sign(e), 135.0, every)[1]) > abs(e))


#: A stick–slip table with a 4 ms lag and Stribeck friction (no ripple: not modelled).
LAG = {**TABLE, "tau_u": 4e-3, "seed": 4}
LAGS = {"tau_u": tuple(k * 5e-4 for k in range(11))}
TOLD = {"m": 150.0, "c": 700.0, "v_s": 1e-3, "f_c": 100.0}


def _pulse(height: float, f_b: float) -> tuple[float, float]:
    """First reading and move (m) of one sample at ``height`` on LAG breaking away at f_b."""
    plant = Plant(LAG)
    plant.f_s_now = f_b
    return ceiling.pulse_path(plant, height)


def test_the_first_reading_rules_out_the_lags_the_move_alone_leaves():
    evidence = TableEvidence(LAGS, TOLD, T)
    assert not evidence.ready()
    first, d = _pulse(175.0, 128.0)
    assert d > 1e-6
    evidence.observe_move(175.0, first, d, 1e-9, 1e-9)
    assert evidence.ready()
    lags = evidence.tables.values["tau_u"][evidence.tables.alive]
    # the table's own lag is left, and so are only its neighbours
    assert 4e-3 in lags and lags.min() >= 3e-3 and lags.max() <= 5e-3
    # without the first reading (its noise infinite) no lag is ruled out by the misfit
    moves_only = TableEvidence(LAGS, TOLD, T)
    moves_only.observe_move(175.0, first, d, math.inf, 1e-9)
    assert moves_only.tables.alive[:9].all()


def test_pulses_that_held_raise_the_lowest_breakaway_until_the_table_moves():
    evidence = TableEvidence(LAGS, TOLD, T)
    first, d = _pulse(160.0, 140.0)
    evidence.observe_move(160.0, first, d, 1e-9, 1e-9)
    ends = np.flatnonzero(evidence.tables.alive)
    fresh = evidence.lowest(ends)
    # on the table's own lag: just below the breakaway the move implies, by its margin
    own = fresh[evidence.tables.values["tau_u"][ends] == 4e-3]
    assert len(own) == 1 and 0.99 * 140.0 < own[0] < 140.0
    # a pulse that held proves the breakaway at least what its lag let through
    evidence.observe_held(165.0)
    held = evidence.lowest(ends)
    assert np.all(held >= evidence.tables.held(165.0, ends)) and np.all(held > fresh)
    # the next move ends the proofs: a fresh stick's lowest is the moves' again
    evidence.observe_move(160.0, first, d, 1e-9, 1e-9)
    assert not evidence.held
    assert np.all(evidence.lowest(ends) < held)


def test_the_plan_moves_no_candidate_left_beyond_the_goal():
    evidence = TableEvidence({**LAGS, "v_s": (2e-4, 1e-3, 5e-3), "f_c": (60.0, 80.0, 100.0, 120.0)},
                             {"m": 150.0, "c": 0.0}, T)
    for height, f_b in ((150.0, 131.0), (142.0, 125.0), (160.0, 136.0)):
        first, d = _pulse(height, f_b)
        evidence.observe_move(height, first, d, 1e-9, 1e-9)
    assert len(evidence.implied) == 3 <= FRESH_MOVES
    tables = evidence.tables
    left = np.flatnonzero(tables.alive)
    assert 0 < len(left) < len(tables)
    for goal in (4e-5, 3e-6):
        height, low = evidence.plan(goal, 300.0)
        assert low == pytest.approx(evidence.lowest(left).min())
        moved = tables.moves(height, evidence.lowest(left), left)[1]
        assert np.all(moved <= goal) and np.any(moved > 0.5 * goal)


def test_a_move_no_candidate_explains_ends_the_plans():
    evidence = TableEvidence(LAGS, TOLD, T)
    evidence.observe_move(131.0, 1e-3, 2e-3, 1e-9, 1e-9)  # 2 mm from one sample near f_s
    assert evidence.failed and not evidence.ready()
    assert evidence.tables.alive.all()  # the candidates stay as they were


@pytest.mark.slow
def test_learning_f_c_too_the_first_reading_keeps_the_table_and_rules_out_no_lag():
    lag = {**TABLE, "tau_u": 4e-3}
    done = ceiling.FastApproach(lag, ceiling.MODELS[17]).run(budget=1.2)
    tables = done.tables
    assert len(tables) == 11 * 9 * 15
    table = tables.values["tau_u"] == 4e-3
    f_c = tables.values["f_c"] == 100.0
    # the candidates nearest the table (4 ms, 100 N; v_s between grid points) are left
    assert np.any(tables.alive & table & f_c)
    lags = tables.values["tau_u"][tables.alive]
    assert lags.min() >= 3e-3
    # f_c is left open: planned for the candidate left that moves farthest, the 50 um take
    # small steps, and 20 pulses close most of the error
    assert done.error <= 4e-6
    for far in (True, False):
        assert ceiling.beyond(done.record, far)[1] == 0


def test_the_one_pulse_planner_is_not_told_the_band():
    with pytest.raises(ValueError, match="not told the band"):
        ceiling.FastApproach(TABLE, ceiling.MODELS[0])


def test_the_slides_band_narrows_the_candidates_f_c():
    # row 21: the candidates' f_c within the band the exact-model controller's slides leave
    told = ceiling.MODELS[20]
    assert told.slid and "f_c" in told.learn
    params = {**TABLE, "tau_u": 2e-3, "x_resolution": 1e-7, "noise_std": 2e-7}
    lo, hi = f_c_band(params)
    f_c = set(ceiling.FastApproach(params, told).tables.values["f_c"].tolist())
    assert f_c == {f for f in ceiling.GRIDS["f_c"] if lo <= f <= hi}
    assert 100.0 in f_c and 60.0 not in f_c
