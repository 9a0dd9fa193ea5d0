"""The "exact" controller: the model of Eq. (3), its inversion, the fit, and closed loops."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from papwc.controllers import CONTROLLER_KINDS, Mode, make_controller
from papwc.controllers.exact import (
    ExactController,
    PulseModelEstimator,
    pulse_amplitude,
    pulse_model,
)
from papwc.controllers.settings import ControllerSettings
from papwc.fmu_src import papwc_stickslip as physics
from papwc.master import Maneuver, run_controller
from papwc.master import summarize
from papwc.scenario import load_scenario
from papwc.master import PhysicsSlave

TABLE_1 = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
T = 0.01
SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


def _settings(tolerance: float = 1e-7, **kw) -> ControllerSettings:
    extra = kw.pop("extra", {})
    base = {"kind": "exact", "f_p_max": 300.0, "m_est": 150.0, "f_c_est": 80.0}
    return ControllerSettings(**{**base, **kw}, tolerance=tolerance, extra=extra)


def _run(plant: dict, settings: ControllerSettings, iterations: int = 10):
    slave = PhysicsSlave()
    slave.set_parameters(plant)
    result = run_controller(slave, settings, Maneuver(iterations=iterations))
    assert not result.error
    return result


# -- the model, Eq. (3) ------------------------------------------------------------------
@pytest.mark.parametrize("c", [0.0, 1e-9, 3.0, 700.0, 5000.0])
@pytest.mark.parametrize("f_p", [130.000001, 135.0, 200.0, 300.0])
@pytest.mark.parametrize("n", [1, 2, 7, 30])
def test_model_equals_the_exact_plant(c, f_p, n):
    m, f_c, f_s = 150.0, 100.0, 130.0
    exact = physics.pulse_displacement(f_p, n * T, m, f_c, f_s, c)
    assert_allclose(pulse_model(f_p, n * T, m, f_c, c), exact, rtol=1e-13)
    assert pulse_model(-f_p, n * T, m, f_c, c) == pulse_model(f_p, n * T, m, f_c, c)


@pytest.mark.parametrize("f_p", [140.0, 300.0])
@pytest.mark.parametrize("n", [1, 3, 10])
def test_model_is_eq3_as_printed(f_p, n):
    m, f_c, c = 150.0, 100.0, 700.0
    t_p = n * T
    eq3 = f_p * t_p / c - (m * f_c / c**2) * math.log((f_p / f_c) * math.expm1(c * t_p / m) + 1)
    assert_allclose(pulse_model(f_p, t_p, m, f_c, c), eq3, rtol=1e-9)


def test_model_limits():
    assert pulse_model(100.0, 0.05, 150.0, 100.0, 700.0) == 0.0  # f_p <= f_c: no motion
    assert pulse_model(300.0, 0.0, 150.0, 100.0, 700.0) == 0.0
    # Coulomb friction 0: the mass coasts m*v1/c further.
    v1 = 300.0 / 700.0 * -math.expm1(-700.0 * 0.05 / 150.0)
    x1 = 300.0 / 150.0 * 0.05**2 * physics._phi2(700.0 * 0.05 / 150.0)
    assert_allclose(pulse_model(300.0, 0.05, 150.0, 0.0, 700.0), x1 + 150.0 * v1 / 700.0,
                    rtol=1e-13)
    assert math.isinf(pulse_model(300.0, 0.05, 150.0, 0.0, 0.0))


# -- inverting Eq. (3) -------------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 5, 10])
@pytest.mark.parametrize("fraction", [0.0, 1e-6, 0.3, 0.77, 1.0])
def test_inversion_gives_the_requested_exact_displacement(n, fraction):
    m, f_c, f_s, c = TABLE_1["m"], TABLE_1["f_c"], TABLE_1["f_s"], TABLE_1["c"]
    f_lo, f_hi = 130.5, 300.0
    d_lo = physics.pulse_displacement(f_lo, n * T, m, f_c, f_s, c)
    d_hi = physics.pulse_displacement(f_hi, n * T, m, f_c, f_s, c)
    target = d_lo + fraction * (d_hi - d_lo)
    f_p = pulse_amplitude(target, n * T, m, f_c, c, f_lo, f_hi)
    assert f_lo <= f_p <= f_hi
    assert_allclose(physics.pulse_displacement(f_p, n * T, m, f_c, f_s, c), target, rtol=1e-12)


def _true_model_controller(**kw) -> ExactController:
    ctl = make_controller(_settings(**kw), T)
    est = ctl.estimator
    est.theta = [math.log(150.0 / est.m_est), math.log(100.0 / est.f_c_est), 700.0 / est.c_scale]
    est.f_s_lo, est.f_s_hi = 129.0, 131.0
    return ctl


@pytest.mark.parametrize("target", [1e-5, 2.2e-5, 3e-4, 1.7e-3, 0.01, 0.03])
def test_planned_pulse_is_the_fastest_that_moves_exactly_by_the_error(target):
    ctl = _true_model_controller()
    n, f_p = ctl.plan_displacement(target)
    m, f_c, f_s, c = (TABLE_1[k] for k in ("m", "f_c", "f_s", "c"))
    if target < physics.pulse_displacement(ctl.f_floor, T, m, f_c, f_s, c):
        assert (n, f_p) == (1, ctl.f_floor)  # the smallest single pulse
        return
    assert ctl.f_floor <= f_p <= 300.0
    assert_allclose(physics.pulse_displacement(f_p, n * T, m, f_c, f_s, c), target, rtol=1e-12)
    if n > 1:  # one sample fewer cannot reach the target at f_p_max
        assert physics.pulse_displacement(300.0, (n - 1) * T, m, f_c, f_s, c) < target


def test_error_below_the_smallest_pulse_is_a_two_pulse_move():
    ctl = _true_model_controller()
    d_small = ctl.estimator.displacement(ctl.f_floor, 1)
    e = 0.2 * d_small
    n, f_p = ctl.plan_pulse(e)
    d_out = physics.pulse_displacement(f_p, n * T, 150.0, 100.0, 130.0, 700.0)
    assert f_p > 0.0 and d_out == pytest.approx(e + 1.5 * d_small, rel=1e-12)
    n2, f_back = ctl.plan_pulse(e - d_out)  # the residual: back by 1.5 d_small
    assert f_back < 0.0
    d_back = physics.pulse_displacement(f_back, n2 * T, 150.0, 100.0, 130.0, 700.0)
    assert d_out + d_back == pytest.approx(e, rel=1e-9, abs=1e-17)


# -- learning ----------------------------------------------------------------------------
PULSES = [(7, 264.0), (1, 213.0), (10, 280.0), (1, 150.0), (3, 300.0), (2, 171.0), (5, 190.0)]


@pytest.mark.parametrize(
    "plant",
    [TABLE_1, {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 0.0},
     {"m": 110.0, "f_c": 125.0, "f_s": 140.0, "c": 400.0},
     {"m": 190.0, "f_c": 75.0, "f_s": 110.0, "c": 900.0}],
)
def test_fit_recovers_m_f_c_c_from_exact_displacements(plant):
    est = PulseModelEstimator(m_est=130.0, f_c_est=90.0, c_est=0.0, T=T, f_p_max=300.0)
    for n, f_p in PULSES:
        d = physics.pulse_displacement(f_p, n * T, plant["m"], plant["f_c"], plant["f_s"],
                                       plant["c"])
        est.observe(n, f_p, d)
    assert_allclose([est.m_hat, est.f_c_hat], [plant["m"], plant["f_c"]], rtol=1e-6)
    assert est.c_hat == pytest.approx(plant["c"], rel=1e-6, abs=1e-3)
    assert est.f_s_hi == min(f for _, f in PULSES)


def test_pulses_of_one_shape_keep_the_prior_where_they_say_nothing():
    est = PulseModelEstimator(m_est=150.0, f_c_est=80.0, c_est=0.0, T=T, f_p_max=300.0)
    d = physics.pulse_displacement(300.0, 5 * T, 150.0, 100.0, 130.0, 700.0)
    for _ in range(5):
        est.observe(5, 300.0, d)
    assert est.displacement(300.0, 5) == pytest.approx(d, rel=1e-8)  # fits the data
    assert all(math.isfinite(p) for p in est.params())


def test_f_s_bracket_from_pulses_that_did_or_did_not_move():
    ctl = make_controller(_settings(), T)
    est = ctl.estimator
    ctl.learn(1, -120.0, 0.0)
    assert (est.f_s_lo, est.f_s_hi) == (120.0, 300.0)
    ctl.learn(1, 140.0, physics.pulse_displacement(140.0, T, 150.0, 100.0, 130.0, 700.0))
    assert (est.f_s_lo, est.f_s_hi) == (120.0, 140.0)
    assert 120.0 <= ctl.f_floor <= 140.0
    ctl.learn(1, 125.0, 3e-6 * -1)  # moved the wrong way: no breakaway in f_p's direction
    assert est.f_s_lo == 125.0


history = st.lists(
    st.tuples(
        st.integers(-2, 60),
        st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.just(0.0)),
        st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(0.0),
                  st.floats(-1.0, 1.0), st.floats(-1e-4, 1e-4)),
    ),
    max_size=30,
)


@settings(max_examples=150, deadline=None)
@given(history=history, e=st.one_of(st.floats(-1.0, 1.0), st.floats(-1e-9, 1e-9)),
       t_p_max=st.sampled_from([0.03, math.inf]))
def test_estimator_stays_finite_and_bounded_on_adversarial_histories(history, e, t_p_max):
    ctl = make_controller(_settings(t_p_max=t_p_max, extra={"history": 8}), T)
    n_state = len(ctl.state())
    for n, f_p, d in history:
        ctl.learn(n, f_p, d)
        est = ctl.estimator
        m, f_c, c = est.params()
        assert 150.0 * math.exp(-3.0) <= m <= 150.0 * math.exp(3.0)
        assert 0.0 < f_c <= est.f_s_hi <= 300.0 and 0.0 <= est.f_s_lo <= 300.0
        assert 0.0 <= c < math.inf
        assert all(math.isfinite(v) for v in ctl.estimates().values())
        assert math.isfinite(est.rel_misfit) and est.rel_misfit > 0.0
        n_plan, f_plan = ctl.plan_pulse(e)
        assert 1 <= n_plan <= ctl.n_max
        assert math.isfinite(f_plan) and 0.0 <= abs(f_plan) <= 300.0
        ctl._stop_now = False
        assert len(ctl.state()) == n_state


def test_state_round_trip_continues_identically():
    plant = PhysicsSlave()
    plant.set_parameters(TABLE_1)
    plant.initialize(0.0)
    a = make_controller(_settings(), T)
    forces = []
    for k in range(60):  # into the first maneuver, a few pulses in
        x = plant.get_outputs()[2]
        u = a.update(k * T, x, 0.01)
        plant.set_input(u)
        plant.do_step(k * T, T)
    saved = a.state()
    b = make_controller(_settings(), T)
    assert len(b.state()) == len(saved)
    b.set_state(saved)
    assert b.state() == saved
    x_saved, v_saved = plant.x, plant.v
    for ctl in (a, b):
        plant.x, plant.v = x_saved, v_saved
        out = []
        for k in range(60, 200):
            u = ctl.update(k * T, plant.get_outputs()[2], 0.01)
            out.append(u)
            plant.set_input(u)
            plant.do_step(k * T, T)
        forces.append(out)
    assert forces[0] == forces[1]


def test_extra_settings_are_validated():
    assert set(ExactController.EXTRA_KEYS) == set(ExactController.EXTRA_DEFAULTS)
    assert CONTROLLER_KINDS["exact"] is ExactController
    for bad in ({"c_est": -1.0}, {"history": 0}, {"max_pulses": 2.5}, {"x_resolution": -1e-6},
                {"f_s_tol": 0.0}, {"c_est": "big"}, {"nonsense": 1.0}):
        with pytest.raises(ValueError):
            make_controller(_settings(extra=bad), T)


# -- closed loops ------------------------------------------------------------------------
def _check_maneuvers(result, tolerance, bound, first=2, max_pulses=3):
    for tr in result.traces:
        s = summarize(tr, tolerance)
        if tr.iteration < first:
            continue
        assert abs(s["final_error_m"]) <= bound, (tr.iteration, s)
        assert s["pulses"] <= max_pulses, (tr.iteration, s)
        assert not s["limit_cycle"]
        modes, us = tr.column("mode"), tr.column("u")
        assert modes[-1] == Mode.SETTLED
        k = len(modes) - 1
        while modes[k - 1] == Mode.SETTLED:
            k -= 1
        assert all(u == 0.0 for u in us[k:-1])  # no pulse after settling


def test_paper_plant_ideal_encoder_reaches_1e_7_with_one_pulse_after_learning():
    result = _run(TABLE_1, _settings(tolerance=1e-7))
    _check_maneuvers(result, 1e-7, 1e-7)
    _check_maneuvers(result, 1e-7, 1e-7, first=1, max_pulses=8)
    assert all(summarize(tr, 1e-7)["pulses"] == 1 for tr in result.traces[1:])


def test_paper_plant_1e_6_encoder_reaches_the_reference_count():
    res = 1e-6
    settings = _settings(tolerance=0.5 * res, extra={"x_resolution": res})
    result = _run({**TABLE_1, "x_resolution": res}, settings)
    _check_maneuvers(result, 0.5 * res, res, max_pulses=5)
    _check_maneuvers(result, 0.5 * res, res, first=3, max_pulses=1)


def test_quantized_rest_detection_measures_each_pulse_within_one_count():
    res = 1e-6
    plant = PhysicsSlave()
    plant.set_parameters({**TABLE_1, "x_resolution": res})
    ctl = make_controller(_settings(tolerance=0.5 * res, extra={"x_resolution": res}), T)
    starts, pairs = [], []
    plan, learn = ctl.plan_pulse, ctl.learn

    def plan_pulse(e):
        starts.append(plant.x)
        return plan(e)

    def learn_(n, f_p, d):
        if n > 0:
            assert plant.v == 0.0  # rest is declared only once the mass is at rest
            pairs.append((d, plant.x - starts[-1]))
        learn(n, f_p, d)

    ctl.plan_pulse, ctl.learn = plan_pulse, learn_
    plant.initialize(0.0)
    for k in range(200):
        plant.set_input(ctl.update(k * T, plant.get_outputs()[2], 0.01))
        plant.do_step(k * T, T)
    assert len(pairs) >= 2
    for d_meas, d_true in pairs:
        assert abs(d_meas - d_true) <= res * (1.0 + 1e-9)


def test_zero_tolerance_stops_at_the_achievable_precision():
    result = _run(TABLE_1, _settings(tolerance=0.0), iterations=3)
    for tr in result.traces:
        s = summarize(tr, 0.0)
        assert abs(s["final_error_m"]) <= 1e-12 and s["pulses"] < 20
        assert tr.column("mode")[-1] == Mode.SETTLED


def test_max_pulses_stops_without_leaving_a_two_pulse_move_half_done():
    settings = _settings(tolerance=1e-7, m_est=60.0, f_c_est=40.0, extra={"max_pulses": 2})
    result = _run(TABLE_1, settings, iterations=1)
    tr = result.traces[0]
    assert summarize(tr, 1e-7)["pulses"] <= 2
    assert tr.column("mode")[-1] == Mode.SETTLED and tr.column("u")[-2] == 0.0


def _draw(seed: int) -> tuple[dict, float, float]:
    rng = random.Random(seed)
    m = 150.0 * rng.uniform(0.7, 1.3)
    f_c = 100.0 * rng.uniform(0.7, 1.3)
    f_s = max(130.0 * rng.uniform(0.7, 1.3), f_c)
    c = 700.0 * rng.uniform(0.7, 1.3)
    return ({"m": m, "f_c": f_c, "f_s": f_s, "c": c}, m * rng.uniform(0.8, 1.2),
            f_c * rng.uniform(0.8, 1.2))


@pytest.mark.parametrize("res", [0.0, 1e-6])
def test_robust_to_spread_plants_and_wrong_estimates(res):
    # Plant parameters +-30 %, initial estimates +-20 % off; 20 seeded draws.
    for seed in range(20):
        plant, m_est, f_c_est = _draw(seed)
        tol = 1e-7 if res == 0.0 else 0.5 * res
        extra = {"x_resolution": res} if res else {}
        settings = _settings(tolerance=tol, m_est=m_est, f_c_est=f_c_est, extra=extra)
        result = _run({**plant, "x_resolution": res}, settings, iterations=4)
        bound = 1e-7 if res == 0.0 else res
        _check_maneuvers(result, tol, bound, max_pulses=3 if res == 0.0 else 8)
        _check_maneuvers(result, tol, bound, first=3, max_pulses=3)


@pytest.mark.parametrize("name", ["exact.toml", "exact_encoder.toml"])
def test_scenario_files(name):
    sc = load_scenario(SCENARIOS / name)
    assert [s.kind for s in sc.controllers] == ["exact"]
    slave = PhysicsSlave()
    slave.set_parameters(sc.plant)
    man = Maneuver(**{**sc.maneuver.__dict__, "iterations": 3})
    result = run_controller(slave, sc.controllers[0], man)
    bound = max(sc.plant["x_resolution"], 1e-7)
    _check_maneuvers(result, sc.controllers[0].tolerance, bound, max_pulses=5)
