"""The 1 kHz pulse hybrid: its settings, its ramps cut on the first reliable move, no hunting
after it settles, any measurements, its state, and its ramps counted as pulses."""

from __future__ import annotations

import math

import pytest
from harness import TABLE_1, run_on_physics
from hypothesis import given, settings
from hypothesis import strategies as st

from papwc.controllers import Mode, make_controller
from papwc.controllers.base import X_LIMIT, Outcome
from papwc.controllers.exact import EXACT_SETTINGS
from papwc.controllers.hybrid import (
    CUT_SHARE,
    REACH,
    HybridController,
)
from papwc.controllers.pid import HYBRID_BAND
from papwc.controllers.settings import ControllerSettings, settings_for_kind
from papwc.model.controller_settings import CONTROLLER_SETTINGS, SHARED_SETTINGS
from papwc.results.pulses import PulseBound, pulses_of
from papwc.results.summary import settled_span, summarize

F_MAX = 300.0
T = 1e-3
#: The reference arrives at once (the window acts from the second sample).
ARRIVES = {"a_max": 1e6, "v_max": 1e6}


def _settings(**kw) -> ControllerSettings:
    return ControllerSettings(**{"kind": "hybrid", "f_p_max": F_MAX, "m_est": 150.0,
                                 "f_c_est": 80.0, "tolerance": 1e-7, "x_resolution": 1e-7,
                                 **kw})


def test_it_reads_the_pulse_controllers_shared_settings_and_the_exact_models_count():
    names = settings_for_kind("hybrid")
    for shared in ("f_p_max", "tolerance", "m_est", "f_c_est"):
        assert shared in names and shared in {v.name for v in SHARED_SETTINGS}
    x_resolution = next(v for v in EXACT_SETTINGS if v.name == "x_resolution")
    assert x_resolution in HybridController.SETTINGS  # the same Variable, not a second one
    table = {v.name: v for v in CONTROLLER_SETTINGS}
    assert "hybrid" in table["x_resolution"].kinds and "exact" in table["x_resolution"].kinds
    assert table["ramp_rate"].kinds == ("hybrid",) and table["ramp_rate"].unit == "N/s"
    assert "hybrid" in table["in_position_band"].kinds
    assert "in_position" not in names  # its window is always on
    ctl = make_controller(_settings(), T)
    assert ctl.window and ctl.w_band == HYBRID_BAND and ctl.mode == Mode.SETTLED
    assert make_controller(_settings(in_position_band=2e-6), T).w_band == 2e-6


def _held_at(ctl, x: float, x_ref: float, n: int, k0: int = 0) -> list[float]:
    return [ctl.update((k0 + k) * T, x, x_ref) for k in range(n)]


def test_a_ramp_climbs_from_the_force_held_and_is_cut_on_the_first_reliable_move():
    """A table stuck 2 um short of the target inside the window (a noiseless 0.1 um
    encoder): the PID's force is held, the error known outside the tolerance starts a ramp
    (one pulse) that climbs at ramp_rate while the readings do not move, is not cut by a
    move away from the target nor by one count's flicker, and is cut at the first reading
    REACH of the error toward the target: the force drops to CUT_SHARE*f_c_est."""
    ctl = make_controller(_settings(**ARRIVES), T)
    x_ref, e = 1e-3, 2e-6
    k = 0
    while ctl.pulses == 0 and k < 500:
        ctl.update(k * T, x_ref - e, x_ref)
        k += 1
    assert ctl.pulses == 1 and ctl.mode == Mode.PULSE and ctl.phase == 1
    u0 = ctl.u
    climb = _held_at(ctl, x_ref - e, x_ref, 20, k)
    k += 20
    steps = {round(b - a, 9) for a, b in zip([u0, *climb], climb, strict=False)}
    assert steps == {round(ctl.settings.ramp_rate * T, 9)}  # no fast climb: not yet stiff
    assert ctl.mode == Mode.PULSE
    ctl.update(k * T, x_ref - e - 1e-6, x_ref)  # away from the target
    ctl.update((k + 1) * T, x_ref - e + 1e-7, x_ref)  # one count toward it
    assert ctl.mode == Mode.PULSE
    k += 2
    reach = REACH * e
    cut = ctl.update(k * T, x_ref - e + reach + 1e-7, x_ref)
    assert ctl.mode == Mode.WAIT and ctl.phase == 2
    assert cut == pytest.approx(min(climb[-1], CUT_SHARE * ctl.settings.f_c_est))
    assert ctl.pulses == 1


def test_the_force_held_is_the_pids_at_most_the_coulomb_estimate():
    """The PID pushes with more than f_c_est against a table that does not move (its
    integral wound up): the hybrid's window holds f_c_est, below any sliding friction, and
    its first ramp starts there."""
    ctl = make_controller(_settings(**ARRIVES, k_i=1e9), T)
    x_ref = 1e-3
    forces: list[float] = []
    while not ctl.holding and len(forces) < 100:
        forces.append(ctl.update(len(forces) * T, x_ref - 0.9e-6, x_ref))
    assert max(forces[1:]) > ctl.settings.f_c_est and ctl.holding
    assert ctl.u_hold == ctl.settings.f_c_est and forces[-1] == ctl.u_hold
    while ctl.pulses == 0:
        u = ctl.update(len(forces) * T, x_ref - 0.9e-6, x_ref)
        forces.append(u)
        assert ctl.pulses or u == ctl.u_hold
    assert u == pytest.approx(ctl.settings.f_c_est + ctl.settings.ramp_rate * T)


def test_noise_the_rest_detector_measured_sets_the_threshold_not_a_single_count():
    """With 0.2 um of noise measured (2 counts), a single reading 0.5 um toward the target
    (2.5 sigma, five counts, beyond REACH of the 0.6 um error) does not cut the ramp; the
    same move held over the readings that follow does, within a few samples."""
    import random

    rng = random.Random(7)
    ctl = make_controller(_settings(**ARRIVES), T)
    x_ref, e = 1e-3, 6e-7
    k = 0
    while ctl.pulses == 0 and k < 3000:
        ctl.update(k * T, x_ref - e + rng.gauss(0.0, 2e-7), x_ref)
        k += 1
    assert ctl.pulses == 1 and math.sqrt(ctl.rest.sigma2) == pytest.approx(2e-7, rel=0.3)
    assert REACH * e < 5e-7
    ctl.update(k * T, x_ref - e + 5e-7, x_ref)
    assert ctl.mode == Mode.PULSE
    for i in range(1, 40):
        ctl.update((k + i) * T, x_ref - e + 5e-7 + rng.gauss(0.0, 2e-8), x_ref)
        if ctl.mode == Mode.WAIT:
            break
    assert ctl.mode == Mode.WAIT and i <= 8


#: A plant with a Stribeck curve on a 0.1 um encoder without noise.
STRIBECK = {**TABLE_1, "v_s": 1e-3, "x_resolution": 1e-7}


@pytest.mark.parametrize("x_ref", [1e-3, 5e-5])
def test_on_a_known_plant_it_ends_within_one_count_settled_and_holds_there(x_ref):
    """Table 1 with a Stribeck curve through a noiseless 0.1 um encoder: each iteration ends
    settled within one count; every ramp from 1 um or more moved at most its bound
    (1.5*abs(e) + a count, or the table's quantum); after it settled the table did not move
    more than a count in the last 0.5 s (no hunting)."""
    result = run_on_physics(STRIBECK, _settings(), x_ref=x_ref, T=T, duration=2.0,
                            iterations=2)
    bound = PulseBound(STRIBECK, T)
    for trace in result.traces:
        m = summarize(trace, 1e-7)
        assert m["outcome"] == "settled" and abs(m["final_error_m"]) <= 1e-7, m
        assert settled_span(trace) <= 1e-7
        ramps = pulses_of(trace)
        assert ramps and m["pulses"] == len(ramps)
        for p in ramps:
            if abs(p.e) >= 1e-6:
                assert abs(p.d) <= bound.bound(p.e) * (1 + 1e-9), p


def test_each_ramp_is_a_pulse_whose_move_is_read_to_the_next_rest():
    """pulses.csv's reading of a hybrid trace: one pulse per ramp (the ``pulses`` output
    rises), its move from the ramp's first sample to the rest before the next ramp (modes
    pulse, then wait or settled, never coarse between)."""
    result = run_on_physics(STRIBECK, _settings(), x_ref=1e-3, T=T, duration=2.0,
                            iterations=1)
    (trace,) = result.traces
    cols = trace.columns
    ramps = pulses_of(trace)
    assert len(ramps) == cols["pulses"][-1] >= 1
    for p, q in zip(ramps, ramps[1:] + [None], strict=False):
        assert cols["mode"][p.k] == Mode.PULSE
        end = q.k if q is not None else len(trace) - 1
        assert p.end == end and p.d == cols["x"][end] - cols["x"][p.k]
        assert all(cols["mode"][k] != Mode.COARSE for k in range(p.k, end))


def test_on_a_drive_with_a_spring_it_makes_no_ramp():
    """Told a mode (f_mode > 0), the hybrid is the PID with its window: the table follows a
    ramp late, after the spring has taken up force."""
    plant = {**TABLE_1, "m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3}
    result = run_on_physics(plant, _settings(f_mode=20.0), x_ref=1e-3, T=T, duration=1.0,
                            iterations=1)
    assert result.traces[0].columns["pulses"][-1] == 0
    x = result.traces[0].columns["x"]
    assert abs(1e-3 - x[-1]) <= abs(1e-3 - x[0])


readings = st.lists(st.one_of(
    st.floats(-0.05, 0.05), st.floats(-1e-5, 1e-5), st.just(1e-3), st.just(1e-3 - 2e-6),
    st.floats(allow_nan=True, allow_infinity=True)), min_size=1, max_size=300)


@settings(max_examples=150, deadline=None)
@given(xs=readings, x_ref=st.sampled_from([0.01, 1e-3, 5e-5, -2e-4]),
       q=st.sampled_from([0.0, 1e-7]), fast=st.booleans())
def test_no_measurement_sequence_makes_nan_or_a_force_beyond_the_limit(xs, x_ref, q, fast):
    ctl = make_controller(_settings(x_resolution=q, **(ARRIVES if fast else {})), T)
    for k, x in enumerate(xs):
        stopped = ctl.outcome == Outcome.STOPPED
        u = ctl.update(k * T, x, x_ref)
        assert math.isfinite(u) and abs(u) <= F_MAX
        assert ctl.mode in (Mode.COARSE, Mode.PULSE, Mode.WAIT, Mode.SETTLED)
        if not abs(x) <= X_LIMIT:
            assert ctl.outcome == Outcome.STOPPED and u == 0.0 or stopped
    values = [v for w in ctl.state().values() for v in (w if isinstance(w, list) else [w])]
    assert all(math.isfinite(v) for v in values) or not abs(xs[0]) <= X_LIMIT


def test_the_state_restores_the_controller_within_a_ramp():
    import random

    rng = random.Random(3)
    a, b = make_controller(_settings(**ARRIVES), T), make_controller(_settings(**ARRIVES), T)
    xs = [1e-3 - 2e-6 + rng.gauss(0.0, 5e-8) for _ in range(600)]
    k = 0
    while a.pulses == 0 and k < 500:
        a.update(k * T, xs[k], 1e-3)
        k += 1
    assert a.mode == Mode.PULSE
    b.set_state(a.state())
    assert b.state() == a.state()
    rest = [x + 3e-6 * (i > 20) for i, x in enumerate(xs[k:])]
    assert [a.update((k + i) * T, x, 1e-3) for i, x in enumerate(rest)] == [
        b.update((k + i) * T, x, 1e-3) for i, x in enumerate(rest)]
    with pytest.raises(ValueError, match="law.ring holds 3 numbers"):
        b.set_state({**a.state(), "law.ring": [0.0] * 3})
