"""The PID controller kind: the law at saturation (anti-windup), any measurements, the exact
plant, and no maneuver that ends farther than it started on the plant's deviations."""

from __future__ import annotations

import math

import pytest
from harness import DEVIATIONS, TABLE_1, run_on_physics, table_1
from hypothesis import given, settings
from hypothesis import strategies as st

from papwc.controllers import Mode, make_controller
from papwc.controllers.base import X_LIMIT, Outcome, Reason
from papwc.controllers.pid import (
    HUNTING,
    MODE_BANDWIDTH,
    PidController,
    in_position_window,
    pid_gains,
    trapezoid,
)
from papwc.controllers.rest import NOISE_WINDOW
from papwc.controllers.settings import ControllerSettings
from papwc.model.controller_settings import OUTCOME_REASONS
from papwc.results.pulses import pulses_of
from papwc.results.summary import summarize

F_MAX = 300.0


def _settings(**kw) -> ControllerSettings:
    return ControllerSettings(**{"kind": "pid", "f_p_max": F_MAX, "m_est": 150.0,
                                 "f_c_est": 80.0, "tolerance": 1e-6, **kw})


def _run(plant: dict, settings: ControllerSettings, **maneuver):
    return run_on_physics(plant, settings, **{"iterations": 2, **maneuver})


def test_default_gains_are_the_coarse_loops_at_the_papers_T_and_scale_with_T():
    s = _settings()
    assert pid_gains(s, 0.01) == pytest.approx((s.k_p_value, s.k_d_value, 0.25 * 150.0 * 1e3))
    k_p, k_d, k_i = pid_gains(s, 0.001)
    assert (k_p, k_d, k_i) == pytest.approx((150.0 * 1e4, 2 * 0.7 * 100.0 * 150.0, 37.5e6))
    assert pid_gains(_settings(k_p=1.0, k_d=2.0, k_i=3.0), 0.001) == (1.0, 2.0, 3.0)
    ctl = make_controller(_settings(), 0.001)
    assert isinstance(ctl, PidController) and ctl.a_max == pytest.approx(220.0 / 300.0)


@pytest.mark.parametrize("d", [0.01, -1e-3, 5e-5])
def test_the_reference_is_a_trapezoid_within_its_limits(d):
    a_max, v_max, T = 0.7, 0.05, 1e-3
    ts = [k * T for k in range(2000)]
    ref = [trapezoid(d, a_max, v_max, t) for t in ts]
    assert ref[0][:2] == (0.0, 0.0) and ref[-1] == (d, 0.0, 0.0)
    assert all(abs(v) <= v_max * (1 + 1e-12) and abs(a) <= a_max for _, v, a in ref)
    xs = [r for r, _, _ in ref]
    steps = [(b - a) * math.copysign(1.0, d) for a, b in zip(xs, xs[1:], strict=False)]
    assert min(steps) >= -1e-15  # it never goes back
    assert max(abs(b - a) for a, b in zip(xs, xs[1:], strict=False)) <= v_max * T * (1 + 1e-9)


def test_at_saturation_the_integral_holds_and_the_force_turns_at_once():
    """A mass that does not follow (held at 0) against a 1 m target: the force saturates at
    f_p_max, the integral stops growing (anti-windup); when the reading passes the reference
    the force turns negative within one sample, which a wound-up integral would not let it."""
    T = 0.01
    ctl = make_controller(_settings(), T)
    forces, integrals = [], []
    for k in range(300):
        forces.append(ctl.update(k * T, 0.0, 1.0))
        integrals.append(ctl.integral)
    assert forces[-1] == F_MAX and max(forces) == F_MAX
    k0 = max(k for k, u in enumerate(forces) if u != F_MAX) + 1  # the last stretch saturated
    assert k0 < 100
    assert integrals[k0 + 1:] == [integrals[k0]] * (299 - k0)  # held while saturated
    assert abs(ctl.k_i * ctl.integral) <= F_MAX
    r = ctl.reference()[0]
    assert 0.0 < r < 1.0
    u = ctl.update(300 * T, r + 1e-3, 1.0)  # the mass suddenly 1 mm ahead of the reference
    assert u < 0.0
    # without anti-windup the integral would have grown by the errors r_k - 0 while
    # saturated, and the same force would still push forward
    grown = sum(trapezoid(1.0, ctl.a_max, ctl.v_max, k * T)[0] * T for k in range(k0 + 1, 300))
    assert u + ctl.k_i * grown > 0.0


readings = st.lists(st.one_of(
    st.floats(-0.05, 0.05), st.floats(-1e-5, 1e-5), st.just(0.0),
    st.floats(allow_nan=True, allow_infinity=True)), min_size=1, max_size=150)


@settings(max_examples=150, deadline=None)
@given(xs=readings, x_ref=st.sampled_from([0.01, 1e-3, 5e-5, -2e-4]),
       T=st.sampled_from([0.01, 0.001]))
def test_no_measurement_sequence_makes_nan_or_a_force_beyond_the_limit(xs, x_ref, T):
    ctl = make_controller(_settings(), T)
    for k, x in enumerate(xs):
        stopped = ctl.outcome == Outcome.STOPPED
        u = ctl.update(k * T, x, x_ref)
        assert math.isfinite(u) and abs(u) <= F_MAX
        assert ctl.pulses == 0 and ctl.mode in (Mode.COARSE, Mode.WAIT, Mode.SETTLED)
        if not abs(x) <= X_LIMIT:
            assert ctl.outcome == Outcome.STOPPED and u == 0.0
            assert stopped or ctl.outcome_reason == Reason.INVALID_MEASUREMENT
    values = [q for v in ctl.state().values() for q in (v if isinstance(v, list) else [v])]
    assert all(math.isfinite(v) for v in values) or not abs(xs[0]) <= X_LIMIT


def test_the_state_restores_the_controller():
    T = 0.001
    a = make_controller(_settings(), T)
    for k in range(50):
        a.update(k * T, 1e-6 * k, 1e-3)
    b = make_controller(_settings(), T)
    b.set_state(a.state())
    assert b.state() == a.state()
    assert [a.update(k * T, 5e-5 + 1e-6 * k, 1e-3) for k in range(50, 90)] == [
        b.update(k * T, 5e-5 + 1e-6 * k, 1e-3) for k in range(50, 90)]


@pytest.mark.parametrize(("in_position", "settle_max"), [(False, 0.5), (True, 0.6)])
@pytest.mark.parametrize("x_ref", [1e-2, 1e-3, 5e-5])
def test_at_1_khz_it_settles_on_the_exact_plant(x_ref, in_position, settle_max):
    """Released near the target, or (the default at 1 kHz) with the in-position window,
    whose hold is judged after its force has settled and its readings are still."""
    result = _run(TABLE_1, _settings(in_position=in_position), x_ref=x_ref, T=1e-3,
                  duration=1.0)
    for trace in result.traces:
        m = summarize(trace, 1e-6)
        assert m["outcome"] == "settled" and abs(m["final_error_m"]) <= 1e-6, m
        assert m["pulses"] == 0 and pulses_of(trace) == []
        assert m["settle_time_s"] < settle_max


def test_at_100_hz_it_reports_what_it_did_not_reach():
    """At T = 10 ms (w = 10 rad/s) the integral is too slow for a 50 um move in 2 s: the
    mass never breaks away and the outcome says time_ended, not settled."""
    result = _run(TABLE_1, _settings(), x_ref=5e-5, T=0.01, duration=2.0)
    m = summarize(result.traces[-1], 1e-6)
    assert m["outcome"] == "stopped" and m["outcome_reason"] == "time_ended"
    assert m["final_error_m"] == 5e-5


def _hunt(ctl, sides: list[float], x_ref: float = 1e-3, hold: int = 5) -> list[float]:
    """Readings that rest ``hold`` samples at x_ref + each of ``sides`` in turn (after 0)."""
    T = ctl.T
    xs = [0.0] + [x_ref + d for d in sides for _ in range(hold)]
    return [ctl.update(k * T, x, x_ref) for k, x in enumerate(xs)]


def test_a_hunting_pid_stops_at_a_rest_nearer_than_it_started():
    """Rests on alternating sides of the target: after hunt_max reversals the PID stops
    (reason hunting) at the next rest nearer than it started; not at one farther."""
    fast = {"a_max": 1e3, "v_max": 1e3, "tolerance": 1e-7, "hunt_max": 2, "in_position": False}
    ctl = make_controller(_settings(**fast), 1e-3)
    _hunt(ctl, [5e-6, -5e-6])
    assert ctl.outcome == Outcome.ACTIVE and ctl.reversals == 1
    _hunt(ctl, [4e-6])
    assert ctl.outcome == Outcome.STOPPED and ctl.outcome_reason == HUNTING
    assert OUTCOME_REASONS[HUNTING] == "hunting" and ctl.update(1.0, 0.0, 1e-3) == 0.0
    far = make_controller(_settings(**fast), 1e-3)
    forces = _hunt(far, [5e-6, -5e-6, 2e-3])  # the third rest is 2 mm past: farther
    assert far.reversals == 2 and far.outcome == Outcome.ACTIVE and forces[-1] < 0.0
    within = make_controller(_settings(**fast), 1e-3)
    _hunt(within, [5e-6, -5e-6, 5e-8])  # the third rest is within the tolerance
    assert within.outcome == Outcome.SETTLED


RIGID_DEVIATIONS = {name: plant for name, plant in DEVIATIONS.items() if name != "flexible"}


@pytest.mark.parametrize("T", [0.01, 0.001])
@pytest.mark.parametrize("case", list(RIGID_DEVIATIONS))
def test_no_maneuver_ends_farther_and_none_is_falsely_settled(case, T):
    for x_ref in (1e-3, 5e-5):
        result = _run(table_1(**RIGID_DEVIATIONS[case]), _settings(), x_ref=x_ref, T=T)
        for trace in result.traces:
            x = trace.columns["x"]
            assert abs(x_ref - x[-1]) <= abs(x_ref - x[0]), (case, x_ref, trace.iteration)
            m = summarize(trace, 1e-6)
            assert m["outcome"] != "settled" or abs(m["final_error_m"]) <= 1e-6, m


@pytest.mark.slow
@pytest.mark.parametrize("c_t", [50.0, 500.0])
@pytest.mark.parametrize(("f_mode", "k_t"), [(10.0, 1.974e5), (20.0, 7.896e5), (40.0, 3.158e6)])
def test_on_a_flexible_drive_told_its_mode_no_maneuver_ends_farther(f_mode, k_t, c_t):
    """Table and motor coupled by a spring (the modes of realism_mc.toml, damping 0.2-10 %):
    with sgn(e) fed forward after arrival and w = 0.1/T the PID at 1 kHz limit-cycles
    2.7 mm peak to peak and ends farther than it started; told f_mode it keeps its bandwidth
    below the mode and feeds no friction forward once the reference has arrived."""
    plant = {**TABLE_1, "m": 100.0, "m_d": 50.0, "k_t": k_t, "c_t": c_t}
    settings = _settings(f_mode=f_mode)
    assert pid_gains(settings, 1e-3)[0] == pytest.approx(150.0 * (2 * math.pi * f_mode
                                                                   * MODE_BANDWIDTH) ** 2)
    for x_ref in (1e-2, 1e-3, 5e-5):
        for T in (1e-3, 1e-2):
            for trace in _run(plant, settings, x_ref=x_ref, T=T).traces:
                x = trace.columns["x"]
                assert abs(x_ref - x[-1]) <= abs(x_ref - x[0]), (x_ref, T, trace.iteration)


# -- the in-position window ----------------------------------------------------------------

#: A PID whose reference arrives at once (the window acts from the second sample).
ARRIVES = {"a_max": 1e6, "v_max": 1e6}


def test_the_window_is_on_by_default_at_1_khz_and_its_band_is_the_tolerance_or_a_count():
    assert in_position_window(_settings(), 1e-3) == (True, 1e-6)
    assert in_position_window(_settings(), 1e-3 * (1 + 1e-12)) == (True, 1e-6)  # T written
    assert in_position_window(_settings(), 2e-3)[0] is False
    assert in_position_window(_settings(), 0.01) == (False, 1e-6)
    assert in_position_window(_settings(in_position=True), 0.01)[0] is True
    assert in_position_window(_settings(in_position=False), 1e-3)[0] is False
    assert in_position_window(_settings(tolerance=0.0, x_resolution=1e-7), 1e-3) == (True, 1e-7)
    assert in_position_window(_settings(in_position_band=3e-6), 1e-3) == (True, 3e-6)
    assert make_controller(_settings(), 1e-3).window and not make_controller(_settings(),
                                                                             0.01).window


def _still_at(ctl, x: float, x_ref: float, n: int, k0: int = 0) -> list[float]:
    """n samples of the reading x (m) against x_ref (m); the forces."""
    return [ctl.update((k0 + k) * ctl.T, x, x_ref) for k in range(n)]


def test_inside_the_window_the_integrator_is_frozen_and_the_force_bled_to_zero():
    """A table stuck 0.5 um short of the target (a noiseless encoder) inside a 1 um window:
    while the PID pushes, its integral grows; once the readings are still, the force is
    bled to zero at once and held there (PidSequencer.holding_force) and the integral
    frozen; a reading 3 um away (outside the window by more than noise) hands the table
    back to the PID, which acts with the integral it had."""
    ctl = make_controller(_settings(**ARRIVES), 1e-3)
    x_ref = 1e-3
    pushing = _still_at(ctl, x_ref - 0.5e-6, x_ref, 10)
    assert ctl.mode == Mode.COARSE and not ctl.holding
    assert len(set(pushing[1:])) > 1 and pushing[-1] > 0.0  # the integral grows
    held = _still_at(ctl, x_ref - 0.5e-6, x_ref, 200, 10)
    assert ctl.holding and ctl.mode in (Mode.WAIT, Mode.SETTLED)
    k = held.index(0.0)
    assert k <= NOISE_WINDOW and held[k:] == [0.0] * (200 - k) and ctl.u_hold == 0.0
    frozen = ctl.integral
    assert frozen != 0.0
    _still_at(ctl, x_ref - 0.5e-6, x_ref, 100, 210)
    assert ctl.integral == frozen
    u = ctl.update(0.31, x_ref - 3e-6, x_ref)
    assert not ctl.holding and ctl.mode == Mode.COARSE and u > 0.0
    ctl.update(0.312, x_ref - 3e-6, x_ref)
    assert ctl.integral != frozen  # the integrator acts again


def test_settled_only_within_the_tolerance_at_rest_counts_rounding_in():
    """Holding inside a 2 um window but 1 um from the target: not settled (the outcome stays
    active, time would end it); a reading one count (0.1 um) from the target on a
    noiseless 0.1 um encoder may be 0.15 um away: not settled with a 0.1 um tolerance; at
    the target's count, settled."""
    band = {**ARRIVES, "tolerance": 1e-7, "in_position_band": 2e-6, "x_resolution": 1e-7}
    x_ref = 1e-3
    away = make_controller(_settings(**band), 1e-3)
    _still_at(away, x_ref - 1e-6, x_ref, 300)
    assert away.holding and away.outcome == Outcome.ACTIVE and away.mode == Mode.WAIT
    count = make_controller(_settings(**band), 1e-3)
    _still_at(count, x_ref - 1e-7, x_ref, 300)
    assert count.holding and count.outcome == Outcome.ACTIVE
    at = make_controller(_settings(**band), 1e-3)
    _still_at(at, x_ref, x_ref, 300)
    assert at.holding and at.outcome == Outcome.SETTLED and at.mode == Mode.SETTLED


def test_noisy_readings_are_averaged_before_the_outcome_is_settled():
    """Readings 0.3 um from the target with 0.2 um of noise and a 0.5 um window, 0.1 um
    tolerance: held, never settled (the average shows the error); at the target, settled
    once the average is known to 3 standard errors within the tolerance, not before."""
    import random

    rng = random.Random(4)
    x_ref = 1e-3
    s = _settings(**ARRIVES, tolerance=1e-7, in_position_band=5e-7)
    off = make_controller(s, 1e-3)
    for k in range(1500):
        off.update(k * 1e-3, x_ref - 3e-7 + rng.gauss(0.0, 2e-7), x_ref)
    assert off.holding and off.outcome == Outcome.ACTIVE
    on = make_controller(s, 1e-3)
    settled_at = None
    for k in range(1500):
        on.update(k * 1e-3, x_ref + rng.gauss(0.0, 2e-7), x_ref)
        if on.outcome == Outcome.SETTLED and settled_at is None:
            settled_at = k
            n, sigma = on.h_n, math.sqrt(on.rest.sigma2)
            assert 3.0 * sigma / math.sqrt(n) <= 1e-7 and sigma > 1e-7
    assert settled_at is not None and on.holding


def test_a_hunting_pid_with_the_window_stops():
    fast = {**ARRIVES, "tolerance": 1e-7, "hunt_max": 2, "in_position_band": 1e-6}
    ctl = make_controller(_settings(**fast), 1e-3)
    x_ref = 1e-3
    k = 0
    for side in (5e-6, -5e-6, 4e-6):
        _still_at(ctl, x_ref + side, x_ref, 30, k)
        k += 30
    assert ctl.outcome == Outcome.STOPPED and ctl.outcome_reason == HUNTING
    assert ctl.update(k * 1e-3, x_ref, x_ref) == 0.0


@settings(max_examples=100, deadline=None)
@given(xs=readings, x_ref=st.sampled_from([0.01, 1e-3, 5e-5, -2e-4]),
       band=st.sampled_from([None, 0.0, 1e-6, 5e-5]), q=st.sampled_from([0.0, 1e-7]))
def test_with_the_window_no_measurement_sequence_makes_nan_or_a_force_beyond_the_limit(
        xs, x_ref, band, q):
    ctl = make_controller(_settings(in_position=True, in_position_band=band, x_resolution=q,
                                    **ARRIVES), 1e-3)
    for k, x in enumerate(xs):
        u = ctl.update(k * 1e-3, x, x_ref)
        assert math.isfinite(u) and abs(u) <= F_MAX
        assert not ctl.holding or abs(ctl.u_hold) <= ctl.settings.f_c_est
    values = [q for v in ctl.state().values() for q in (v if isinstance(v, list) else [v])]
    assert all(math.isfinite(v) for v in values) or not abs(xs[0]) <= X_LIMIT


def test_with_the_window_the_state_restores_the_controller():
    import random

    rng = random.Random(1)
    a, b = make_controller(_settings(), 1e-3), make_controller(_settings(), 1e-3)
    xs = [1e-3 - 4e-7 + rng.gauss(0.0, 1e-7) for _ in range(400)]
    for k, x in enumerate(xs[:300]):
        a.update(k * 1e-3, x, 1e-3)
    b.set_state(a.state())
    assert b.state() == a.state()
    assert [a.update(k * 1e-3, x, 1e-3) for k, x in enumerate(xs[300:], 300)] == [
        b.update(k * 1e-3, x, 1e-3) for k, x in enumerate(xs[300:], 300)]
