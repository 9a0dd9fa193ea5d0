"""The paper's controllers, PWC and PAPWC: Eq. (11), the estimators, safeguards, and the
pulse sequencing through the master with the in-process plant.

Closed loops on FrictionPlant.fmu are in tests/integration/test_closed_loops.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from harness import TABLE_1, hard_runaways, run_on_physics, table_1
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from papwc.controllers import CONTROLLER_KINDS, Controller, Mode, make_controller
from papwc.controllers.estimators import Rls2, ScalarRls
from papwc.controllers.papwc import FAR_LESS, PapwcController, creep_prediction, papwc_amplitude
from papwc.controllers.pwc import PwcController
from papwc.controllers.settings import ControllerSettings
from papwc.master import Maneuver, PhysicsSlave, run_controller, run_iteration
from papwc.model.pulse import b_coulomb, pulse_displacement
from papwc.results.summary import summarize

T = 0.01


@pytest.mark.parametrize("f_c", [60.0, 80.0, 100.0, 129.0])
@pytest.mark.parametrize("t_p", [0.004, 0.013, 0.027, 0.0555])
def test_eq11_plans_the_requested_eq4_displacement(f_c, t_p):
    m, f_p = 150.0, 300.0
    n = math.ceil(t_p / T)
    T_x = n * T
    f_star = papwc_amplitude(f_c, f_p, t_p, T_x)
    requested = b_coulomb(f_p, m, f_c) * t_p**2  # Eq. (4) at (f_p, t_p)
    planned = b_coulomb(f_star, m, f_c) * T_x**2  # Eq. (4) at (f_p*, T_x)
    # measured: at most 4.8e-16 relative (a rounding of the square root)
    assert_allclose(planned, requested, rtol=2e-15)
    assert f_star <= f_p


def _regressors(seed, n=12):
    rng = np.random.default_rng(seed)
    f = rng.uniform(140.0, 300.0, n)
    t = rng.integers(1, 10, n) * T
    phi = np.column_stack([f**2 * t**2, -f * t**2])
    a_true = np.array([3.2e-5, 3.4e-3])
    d = phi @ a_true + rng.normal(0.0, 2e-5, n)
    return phi, d


@pytest.mark.parametrize("lam", [1.0, 0.95])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rls_equals_batch_least_squares(lam, seed):
    phi, d = _regressors(seed)
    a0 = np.array([1.0 / (2 * 150 * 80), 1.0 / 300])
    delta_inv = 1e-5
    rls = Rls2(tuple(a0), delta_inv=delta_inv, lam=lam,
               a_bounds=((-math.inf, math.inf), (-math.inf, math.inf)))
    for row, di in zip(phi, d, strict=True):
        rls.update(tuple(row), float(di))
    n = len(d)
    w = lam ** np.arange(n - 1, -1, -1)
    # minimises sum w_i (d_i - a^T phi_i)^2 + lam^n / delta_inv * |a - a0|^2
    prior = lam**n / delta_inv
    A = (phi * w[:, None]).T @ phi + prior * np.eye(2)
    rhs = (phi * w[:, None]).T @ d + prior * a0
    a_batch = np.linalg.solve(A, rhs)
    # measured: at most 2.1e-16 relative (the recursion is exact up to rounding)
    assert_allclose(rls.a, a_batch, rtol=1e-15)


def test_scalar_rls_equals_batch_least_squares():
    rng = np.random.default_rng(3)
    u = rng.uniform(1e-4, 9e-4, 15) * rng.choice([-1.0, 1.0], 15)
    d = 1.9 * u + rng.normal(0.0, 1e-5, 15)
    est = ScalarRls(2.75, F_inv0=1e-5)
    for ui, di in zip(u, d, strict=True):
        est.update(float(ui), float(di))
    b_batch = (1e-5 * 2.75 + np.sum(u * d)) / (1e-5 + np.sum(u * u))
    # measured: 3.5e-16 relative
    assert_allclose(est.b_hat, b_batch, rtol=2e-15)


history = st.lists(
    st.tuples(
        st.integers(1, 50),
        st.floats(-1e6, 1e6, allow_nan=False),
        st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(0.0),
                  st.floats(-1.0, 1.0)),
    ),
    max_size=40,
)


@settings(max_examples=150, deadline=None)
@given(history=history, kind=st.sampled_from(["pwc", "papwc"]))
def test_estimators_stay_finite_on_adversarial_histories(history, kind):
    ctl = make_controller(ControllerSettings(kind=kind, t_p_max=0.05), T)
    for n, f_p, d in history:
        ctl.learn(n, f_p if f_p != 0.0 else 1.0, d)
        est = ctl.estimates()
        assert all(math.isfinite(v) and v > 0.0 for v in est.values()), est
        n_plan, f_plan = ctl.plan_pulse(1e-3)
        assert 1 <= n_plan <= ctl.n_max
        assert math.isfinite(f_plan) and 0.0 < abs(f_plan) <= ctl.settings.f_p_max
    if kind == "papwc":
        p = ctl.estimator.P
        assert p[0][1] == p[1][0]
        assert p[0][0] > 0.0 and p[0][0] * p[1][1] - p[0][1] ** 2 > 0.0


def test_pulse_that_does_not_move_raises_the_floor_and_skips_the_update():
    ctl = PapwcController(ControllerSettings(kind="papwc"), T)
    a_before = list(ctl.estimator.a)
    ctl.learn(1, -120.0, 0.0)
    assert ctl.estimator.a == a_before
    assert ctl.f_p_floor == pytest.approx(120.0 * 1.05)
    ctl.learn(1, 125.0, -1e-6)  # moved the wrong way: not a valid observation either
    assert ctl.estimator.a == a_before


def test_papwc_learns_physical_values_when_c_is_zero():
    # With c = 0 the Coulomb model (4) is exact, so A1, A2 converge to 1/(2 m f_c), 1/(2 m).
    m, f_c = 150.0, 100.0
    ctl = PapwcController(ControllerSettings(kind="papwc", delta_inv=1e4), T)
    for n, f in [(3, 300.0), (1, 250.0), (5, 180.0), (2, 290.0), (4, 140.0), (1, 300.0)]:
        d = pulse_displacement(f, n * T, m, f_c, 0.0)
        ctl.learn(n, f, d)
    # Not exact: the prior delta_inv = 1e4 still weighs in. Measured: 4.6e-8
    # (A1, A2) and 2.4e-8 (f_c_hat) relative.
    assert_allclose(ctl.estimator.a, [1 / (2 * m * f_c), 1 / (2 * m)], rtol=1e-7)
    assert_allclose(ctl.f_c_hat, f_c, rtol=5e-8)


def test_pwc_width_rounding_and_bound():
    ctl = PwcController(ControllerSettings(kind="pwc", t_p_max=0.03, safeguards=False), T)
    b = ctl.estimator.b_hat
    assert ctl.plan_pulse(b * 0.01**2) == (1, 300.0)  # exactly one sample
    assert ctl.plan_pulse(-b * 0.0101**2) == (2, -300.0)  # rounded up
    assert ctl.plan_pulse(1.0)[0] == 3  # bounded by t_p_max


def test_registry_makes_each_kind_and_refuses_an_unknown_one():
    for kind, cls in CONTROLLER_KINDS.items():
        ctl = make_controller(ControllerSettings(kind=kind), T)
        assert type(ctl) is cls and isinstance(ctl, Controller) and ctl.kind == kind
        assert ctl.revision == 0 and ctl.mode == Mode.SETTLED
    with pytest.raises(ValueError, match="controller kind 'lqr' is unknown; known kinds: "
                                         "dual_loop, exact, hybrid, papwc, pid, pwc"):
        make_controller(ControllerSettings(kind="lqr"), T)


@pytest.mark.parametrize("kind", ["pwc", "papwc", "exact"])
def test_revision_counts_the_pulses_learned_from(kind):
    """The revision (an observer re-reads the estimates only when it changes) rises once
    per pulse whose displacement was taken, and the estimates change only then."""
    plant = PhysicsSlave()
    plant.set_start_values(TABLE_1)
    settings = ControllerSettings(kind=kind, t_p_max=0.03, tolerance=1e-7 if kind == "exact"
                                  else 2e-5)
    result = run_controller(plant, settings, Maneuver(duration=1.0, iterations=2))
    assert not result.error
    for tr in result.traces:
        b_hat, pulses, mode = tr.column("b_hat"), tr.column("pulses"), tr.column("mode")
        for k in range(1, len(tr)):
            if b_hat[k] != b_hat[k - 1]:
                # learning happens at the sample that ends a wait (before any new pulse)
                assert mode[k - 1] == Mode.WAIT, k
        assert pulses[-1] > 0


def test_delayed_force_is_not_mistaken_for_a_pulse_that_did_not_move():
    """With the force one sample late, every pulse of PAPWC still moves the mass and the
    amplitude floor is never raised (a pulse that did not move would raise it)."""
    plant = PhysicsSlave()
    plant.set_start_values(TABLE_1)
    settings = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8)
    for timing in ("immediate", "delayed"):
        ctl = make_controller(settings, T)
        floors = []
        learn = ctl.learn

        def spy(n, f_p, d, learn=learn, ctl=ctl, floors=floors):
            learn(n, f_p, d)
            floors.append((d, ctl.f_p_floor))

        ctl.learn = spy
        trace = run_iteration(plant, ctl, Maneuver(duration=2.0, timing=timing))
        assert not trace.error
        assert floors and all(d > 0.0 for d, _ in floors), timing
        assert all(floor == settings.f_c_est for _, floor in floors), timing
        assert abs(summarize(trace, settings.tolerance)["final_error_m"]) <= settings.tolerance


@pytest.mark.parametrize("kind", CONTROLLER_KINDS)
def test_samples_only_counted_give_the_state_of_samples_fully_taken(kind):
    """A settled controller only counts an unchanged reading (``idle_samples``); the state,
    the outputs and what follows a disturbance are those of taking every sample in full
    (a state round trip after each sample makes the controller take the next in full)."""
    s = ControllerSettings(kind=kind, tolerance=1e-6)
    x_ref = 1e-3
    readings = [x_ref] * 60 + [x_ref + 5e-6] * 40 + [x_ref + 5e-6 + 1e-7] * 20
    lazy, full = make_controller(s, 0.01), make_controller(s, 0.01)
    u_lazy, u_full, counted = [], [], 0
    for k, x in enumerate(readings):
        u_lazy.append(lazy.update(k * 0.01, x, x_ref))
        counted = max(counted, lazy.idle_samples)
        u_full.append(full.update(k * 0.01, x, x_ref))
        full.set_state(full.state())
        assert full.idle_samples == 0
    if kind == "hybrid":
        assert counted == 0  # its window holds a force while settled: it takes every sample
    else:
        assert counted >= 40  # the shortcut was taken while settled ...
    assert u_lazy == u_full
    assert lazy.state() == full.state()  # ... and state() counts it in
    assert (lazy.mode, lazy.outcome, lazy.pulses) == (full.mode, full.outcome, full.pulses)


def test_creep_prediction_follows_the_creeps_within_eq4():
    """A one-sample pulse at the floor after two pulses that crept and grew with their
    height: as far as the last creep if no higher, else their growth extrapolated
    geometrically in the height; at least FAR_LESS and at most all of Eq. (4). Without two
    such creeps (one only, or a second that moved less), Eq. (4)."""
    eq4 = 9.5e-5
    assert creep_prediction(196.0, eq4, (0.0, 0.0, 186.7, 4.8e-6)) == eq4
    assert creep_prediction(158.0, eq4, (143.3, 2.67e-6, 150.5, 2.8e-7)) == eq4  # shrank
    two = (177.8, 3.26e-6, 186.7, 4.8e-6)
    assert creep_prediction(180.0, eq4, (177.8, 3.26e-6, 186.7, 3e-5)) == 3e-5  # no higher
    assert creep_prediction(186.7, eq4, two) == FAR_LESS * eq4  # 4.8 um is less than that
    grown = 4.8e-6 * (4.8 / 3.26) ** ((196.0 - 186.7) / (186.7 - 177.8))
    assert creep_prediction(196.0, 1e-4, two) == pytest.approx(max(grown, 2.5e-5))
    assert creep_prediction(196.0, 4e-6, two) == 4e-6  # never more than Eq. (4)
    assert creep_prediction(196.0, 1e-5, two) == pytest.approx(grown)  # above FAR_LESS*1e-5


def test_creep_prediction_without_growth_reads_the_creeps_at_least_as_high():
    """realism_mc_fresh.toml, run rigid-s5-d006: PAPWC's creeps at 205.33 N and 215.59 N moved
    25.2 and 17.8 um (the breakaway drawn anew scatters them: no growth with the height to go
    by). A pulse no higher than a creep moves as far as the farthest creep at least as high,
    at least FAR_LESS of Eq. (4) and at most all of it; above them, Eq. (4)."""
    creeps = (205.33, 2.52e-5, 215.59, 1.78e-5)
    assert creep_prediction(215.59, 1.22e-4, creeps) == pytest.approx(FAR_LESS * 1.22e-4)
    assert creep_prediction(205.33, 6e-5, creeps) == 2.52e-5  # the farther of the two
    assert creep_prediction(205.33, 2e-5, creeps) == 2e-5  # never more than Eq. (4)
    assert creep_prediction(226.37, 1.38e-4, creeps) == 1.38e-4  # above both
    # realism_mc_unknown.toml, a 20 Hz drive not told (run flexible_20hz_unknown-s4-d003):
    # 2.67 um at 143.3 N, then 0.28 um at 150.46 N -- the table read noise while the drive
    # wound up, and a pulse at 150.46 N then moved 167 um: creeps this far apart are no
    # evidence
    assert creep_prediction(150.46, 4.4e-5, (143.3, 2.67e-6, 150.46, 2.83e-7)) == 4.4e-5


def test_papwc_fires_at_a_creeps_height_where_its_floor_may_end_farther():
    """The same run: after those creeps the floor stood at 226.37 N, where Eq. (4) says
    138 um, and the third 50 um maneuver stopped before its first pulse (measured before).
    A creep's own height, which the creeps say moves at most 30 um, is fired instead; the
    floor stays."""
    ctl = PapwcController(ControllerSettings(kind="papwc", m_est=150.0, f_c_est=80.0), T)
    ctl.learn(1, 205.33, 2.52e-5)
    ctl.learn(1, 215.59, 1.78e-5)
    assert ctl.creeps == (205.33, 2.52e-5, 215.59, 1.78e-5)
    assert ctl.f_p_floor == pytest.approx(215.59 * 1.05)
    ctl.seq.e0 = 5e-5
    floor = ctl.f_p_floor
    assert ctl.seq.may_end_farther(5e-5, floor, ctl.reach(1, floor))
    n, f = ctl.plan_pulse(5e-5)
    assert (n, f) == (1, 215.59)
    assert not ctl.seq.may_end_farther(5e-5, f, ctl.reach(n, f))
    assert ctl.f_p_floor == floor
    ctl.seq.e0 = -5e-5  # the same the other way
    assert ctl.plan_pulse(-5e-5) == (1, -215.59)


def test_papwc_does_not_fire_below_its_floor_on_creeps_far_apart():
    """realism_mc_unknown.toml, run flexible_20hz_unknown-s4-d003 (a 20 Hz drive not told):
    creeps of 2.67 and 0.28 um while the drive wound up. Eq. (4) alone says a pulse at the
    second one's height ends no farther, but it moved 167 um there (measured with a version
    that fired it): below the floor only on the creeps' evidence, which these are not."""
    ctl = PapwcController(ControllerSettings(kind="papwc", m_est=150.0, f_c_est=80.0), T)
    ctl.learn(1, 143.3, 2.67e-6)
    ctl.learn(1, 150.46, 2.83e-7)
    ctl.trust.value = 0.45
    ctl.seq.e0 = -5.24e-5
    floor = ctl.f_p_floor
    assert floor == pytest.approx(150.46 * 1.05)
    assert not ctl.seq.may_end_farther(-4.94e-5, -150.46, ctl.predict(1, 150.46))
    assert ctl.plan_pulse(-4.94e-5) == (1, -floor)


def test_papwc_reaches_on_its_creeps_and_forgets_them_when_eq4_holds():
    """One-sample pulses that moved less than Eq. (4) are kept (the last two), and a pulse at
    the floor is expected to move on their evidence (``reach``) while the trust region
    judges Eq. (4) (``predict``); one that moved as far as Eq. (4), or did not move, forgets
    them."""
    ctl = PapwcController(ControllerSettings(kind="papwc", m_est=150.0, f_c_est=80.0), T)
    ctl.learn(1, 177.8, 3.26e-6)  # far less than Eq. (4): the floor rises above it
    ctl.learn(1, 186.7, 4.8e-6)
    assert ctl.creeps == (177.8, 3.26e-6, 186.7, 4.8e-6)
    assert ctl.f_p_floor == pytest.approx(186.7 * 1.05)
    f = ctl.f_p_floor
    assert ctl.reach(1, f) == creep_prediction(f, ctl.predict(1, f), ctl.creeps)
    assert ctl.reach(1, f) < ctl.predict(1, f)
    assert ctl.reach(2, f) == ctl.predict(2, f)  # wider pulses: Eq. (4)
    assert ctl.reach(1, f + 1.0) == ctl.predict(1, f + 1.0)  # above the floor: Eq. (4)
    state = ctl.state()
    other = PapwcController(ControllerSettings(kind="papwc", m_est=150.0, f_c_est=80.0), T)
    other.set_state(state)
    assert other.creeps == ctl.creeps
    ctl.learn(1, -f, -1.01 * ctl.predict(1, f))  # as far as Eq. (4) has it (either side)
    assert ctl.creeps == (0.0, 0.0, 0.0, 0.0) and ctl.reach(1, f) == ctl.predict(1, f)
    other.learn(1, f, 0.0)  # one that did not move: the creeps no longer tell
    assert other.creeps == (0.0, 0.0, 0.0, 0.0)


def test_papwc_after_pulses_that_crept_starts_the_next_maneuver():
    """A rigid draw of scenarios/realism_mc.toml (seed 1, draw 2: a 4.1 ms actuator lag, a
    Stribeck curve, 0.23 um noise on a 0.1 um encoder): on the 50 um target PAPWC's
    one-sample pulses at its floor crept (0.2 to 8 um, Eq. (4) says 60 to 110 um), so Eq. (4)
    alone said the next one would overshoot past the start; the maneuver stopped 30 to 40 um
    off and the third one did not start (measured before ``reach``). On the evidence of its
    creeps it goes on: every iteration ends within its 20 um, no pulse a hard requirement
    forbids."""
    plant = table_1(v_s=2.035e-3, ripple=0.04567, ripple_period=1.148e-3, f_s_spread=0.01373,
                    tau_u=4.089e-3, noise_std=2.278e-7, seed=1, x_resolution=1e-7)
    settings = ControllerSettings(kind="papwc", f_p_max=300.0, t_p_max=0.03, K_c=0.8,
                                  tolerance=2e-5, m_est=150.0, f_c_est=80.0, delta_inv=1e-5)
    result = run_on_physics(plant, settings, x_ref=5e-5, T=T, duration=2.0, iterations=3)
    assert len(result.traces) == 3
    for trace in result.traces:
        s = summarize(trace, settings.tolerance)
        assert s["outcome"] == "settled" and abs(s["final_error_m"]) <= 2e-5, s
        assert 0 < s["pulses"] <= 20, s
    assert not hard_runaways(result.traces, plant, T)
