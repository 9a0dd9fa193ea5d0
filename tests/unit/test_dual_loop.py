"""The dual-loop controller: its motor loop, its pulses on a flexible drive, its refusals."""

from __future__ import annotations

import dataclasses
import math

import pytest
from harness import hard_runaways
from hypothesis import given, settings
from hypothesis import strategies as st

from papwc.controllers import CONTROLLER_KINDS, Outcome, Reason, make_controller
from papwc.controllers.drive_check import DriveCheck
from papwc.controllers.dual_loop import (
    F_MODE_MAX_T,
    PROBE_SHARE,
    PROBE_WAIT_S,
    DualLoopController,
    MotorLoop,
)
from papwc.controllers.mode_id import ModeIdentifier, mode_of
from papwc.controllers.settings import ControllerSettings
from papwc.master import Maneuver, PhysicsSlave, run_controller
from papwc.master.closed_loop import ControllerSlave, run_closed_loop
from papwc.model.controller_settings import settings_problems

T = 0.01
#: realism.toml's flexible drive: a 100 kg table, a 50 kg motor, a 20 Hz mode (table stuck).
DRIVE_20HZ = {"m": 100.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0, "m_d": 50.0, "k_t": 7.896e5,
              "c_t": 251.3}
#: The 10 Hz drive of realism_mc.toml.
DRIVE_10HZ = {**DRIVE_20HZ, "k_t": 1.974e5, "c_t": 125.0}


def dual(**kw) -> ControllerSettings:
    base = {"kind": "dual_loop", "f_p_max": 300.0, "tolerance": 1e-7, "m_est": 150.0,
            "f_c_est": 80.0, "f_mode": 20.0, "m_d_est": 50.0}
    return ControllerSettings(**{**base, **kw})


def plant(params: dict) -> PhysicsSlave:
    slave = PhysicsSlave()
    slave.set_start_values(params)
    slave.initialize()
    return slave


def step(slave: PhysicsSlave, u: float, k: int) -> None:
    slave.u = u
    slave.do_step(k * T, T)


def test_the_kind_reads_the_motor_encoder_and_the_others_do_not() -> None:
    assert CONTROLLER_KINDS["dual_loop"] is DualLoopController
    assert DualLoopController.reads_x_d_meas
    assert [k for k, c in CONTROLLER_KINDS.items() if c.reads_x_d_meas] == ["dual_loop"]


@pytest.mark.parametrize(("params", "f_mode"), [(DRIVE_20HZ, 20.0), (DRIVE_10HZ, 10.0)])
def test_the_motor_loop_brings_a_ringing_drive_to_rest(params: dict, f_mode: float) -> None:
    """One sample of 80 N leaves the drive ringing while the table sticks: free, it still
    rings with more than 10 N after 0.4 s; with the motor loop it is at rest (below 0.01 N of
    ringing) within 11 samples, and the table never moves."""
    rings = {}
    for closed in (False, True):
        slave = plant(params)
        loop = MotorLoop(2.0 * math.pi * f_mode, 50.0, 0.0, T)
        u = 0.0
        amplitude = []
        for k in range(40):
            loop.observe(slave.plant.x_d_meas() - slave.plant.x_meas(), u)
            amplitude.append(loop.amplitude())
            u = 80.0 if k < 1 else (loop.force() if closed else 0.0)
            step(slave, u, k)
            assert slave.x == 0.0  # the table sticks throughout
        rings[closed] = amplitude
    assert min(rings[False][10:]) > 10.0
    assert max(rings[True][12:]) < 0.01 < min(rings[True][:4])
    # the true drive at the end: relaxed (spring force and motor speed)
    assert abs(params["k_t"] * (slave.plant.x_d_now() - slave.x)) < 0.01
    assert abs(slave.plant.v_d) < 1e-6


def test_the_rate_estimate_is_exact_on_the_model() -> None:
    slave = plant(DRIVE_20HZ)
    loop = MotorLoop(2.0 * math.pi * 20.0, 50.0, 0.0, T)
    u = 0.0
    for k, f in enumerate([50.0, -30.0, 20.0, 0.0, 10.0, 0.0]):
        loop.observe(slave.plant.x_d_meas() - slave.plant.x_meas(), u)
        if k:
            # c_t = 251.3 N.s/m in the plant, 0 in the model (2 % damping): within 5 % of
            # the motor's speed (measured up to 4.4 %)
            assert loop.rate == pytest.approx(slave.plant.v_d, rel=0.05, abs=1e-4)
        u = f
        step(slave, u, k)


def _runs(params: dict, settings: ControllerSettings, targets=(1e-2, 1e-3, 5e-5)):
    out = []
    for x_ref in targets:
        result = run_controller(_slave(params), settings,
                                Maneuver(x_ref=x_ref, T=T, duration=2.0, iterations=3))
        assert not result.error
        out.append((x_ref, result))
    return out


def _slave(params: dict) -> PhysicsSlave:
    slave = PhysicsSlave()
    slave.set_start_values(params)
    return slave


#: The told and identified drives of the tests below: (plant, settings).
TOLD_DRIVES = [
    (DRIVE_20HZ, dual()),
    (DRIVE_20HZ, dual(f_mode=21.0)),  # the mode 5 % off
    # the motor 5 % off, its damping doubled
    (DRIVE_20HZ, dual(m_d_est=52.5, c_t_est=502.6)),
    # the mode not told: identified from the motor encoder's ringing after the probe
    (DRIVE_20HZ, dual(f_mode=0.0, identify_mode=True)),
]


@pytest.mark.parametrize(("params", "settings"), TOLD_DRIVES)
def test_on_a_flexible_drive_it_ends_within_1_um_and_never_farther(params, settings) -> None:
    """The last of three 2 s iterations ends within 1 um of each target; no iteration ends
    farther than it started and none says settled outside its tolerance."""
    for x_ref, result in _runs(params, settings):
        for tr in result.traces:
            e = x_ref - tr.column("x")[-1]
            assert abs(e) < abs(x_ref)
            if tr.column("outcome")[-1] == Outcome.SETTLED:
                assert abs(e) <= settings.tolerance
        last = result.traces[-1]
        assert abs(x_ref - last.column("x")[-1]) <= 1e-6, (x_ref, settings)


@pytest.mark.parametrize(("params", "settings"), TOLD_DRIVES)
def test_on_a_flexible_drive_no_pulse_a_hard_requirement_forbids(params, settings) -> None:
    """No pulse beyond its bound at abs(e) >= 50 um or planned and beyond it at abs(e) >=
    1 um (R4h), none moving more than 20 um at abs(e) < 1 um (R5)."""
    for _, result in _runs(params, settings):
        assert not hard_runaways(result.traces, params, T)


def test_above_a_quarter_of_the_sample_rate_the_mode_is_refused() -> None:
    """f_mode above 0.25/T: a settings problem naming f_mode and the bound, and no
    controller made; at the bound and at 0 (no motor loop) it is made."""
    s = dual(f_mode=40.0)
    problems = settings_problems({**s.to_mapping(with_none=True), "T": T})
    assert problems == [("f_mode", "f_mode = 40.0 Hz: above 0.25/T = 25 Hz (T = 0.01 s), too "
                         "close to the sampling's Nyquist frequency 50 Hz for a controller "
                         "sampling at T (a motor loop cannot damp it, pulses cannot wait it "
                         "out); must be 0 (rigid or unknown) or f_mode <= 0.25/T = 25 Hz (or "
                         "sample faster)")]
    with pytest.raises(ValueError, match=r"f_mode = 40.0 Hz: .* \[0, 25\] Hz"):
        make_controller(s, T)
    assert F_MODE_MAX_T == 0.25
    # (the motor loop is built once the drive check has seen the mode)
    assert make_controller(dual(f_mode=25.0), T).check.f_told == 25.0
    assert make_controller(dual(f_mode=0.0), T).check is None
    # every kind is refused the same (a table-only controller cannot wait such a mode out)
    assert settings_problems({**dataclasses.replace(s, kind="exact").to_mapping(
        with_none=True), "T": T}) == problems


def test_without_f_mode_it_is_the_exact_controller_on_the_table_encoder() -> None:
    params = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
    a = run_controller(_slave(params), dual(f_mode=0.0),
                       Maneuver(x_ref=1e-3, T=T, duration=2.0, iterations=2))
    exact = dataclasses.replace(dual(f_mode=0.0), kind="exact")
    b = run_controller(_slave(params), exact,
                       Maneuver(x_ref=1e-3, T=T, duration=2.0, iterations=2))
    for ta, tb in zip(a.traces, b.traces, strict=True):
        assert ta.column("u") == tb.column("u") and ta.column("x") == tb.column("x")


def test_a_motor_reading_that_is_not_finite_stops_it() -> None:
    ctl = make_controller(dual(), T)
    ctl.x_d_meas = 0.0
    assert ctl.update(0.0, 0.0, 1e-3) > 0.0  # the first pulse
    ctl.x_d_meas = math.nan
    assert ctl.update(T, 0.0, 1e-3) == 0.0
    assert ctl.outcome == Outcome.STOPPED and ctl.outcome_reason == Reason.INVALID_MEASUREMENT
    assert ctl.update(2 * T, 0.0, 1e-3) == 0.0


def test_a_drive_that_does_not_relax_stops_it_with_zero_force() -> None:
    """A motor reading that rings on (a drive unlike the model) is never taken as relaxed:
    after RELAX_MAX_S the controller stops (model_rejected) and outputs 0."""
    ctl = make_controller(dual(), T)
    forces = []
    for k in range(150):
        # the motor follows the first pulse, then rings on, undamped
        ctl.x_d_meas = 2e-4 + 1e-4 * math.sin(2.0 * math.pi * 20.0 * k * T) if k else 0.0
        forces.append(ctl.update(k * T, 0.0, 1e-3))
    assert ctl.outcome == Outcome.STOPPED and ctl.outcome_reason == Reason.MODEL_REJECTED
    assert forces[-30:] == [0.0] * 30
    assert all(abs(f) <= 300.0 for f in forces)


@pytest.mark.parametrize(("settings", "split"), [
    (dual(), 37),
    (dual(f_mode=0.0, identify_mode=True), 8),  # identifying
    (dual(f_mode=0.0, identify_mode=True), 37),  # identified
])
def test_its_state_restores_the_run(settings: ControllerSettings, split: int) -> None:
    """state() into a new controller: the same forces from then on, the same state."""
    slave = _slave(DRIVE_20HZ)
    slave.initialize()
    a = make_controller(settings, T)
    for k in range(split):
        a.x_d_meas = slave.plant.x_d_meas()
        step(slave, a.update(k * T, slave.plant.x_meas(), 1e-3), k)
    assert (a.motor is None) == (split == 8 and settings.identify_mode)
    b = make_controller(settings, T)
    b.set_state(a.state())
    assert b.state() == a.state()
    for k in range(split, 120):
        a.x_d_meas = b.x_d_meas = slave.plant.x_d_meas()
        u = a.update(k * T, slave.plant.x_meas(), 1e-3)
        assert b.update(k * T, slave.plant.x_meas(), 1e-3) == u
        step(slave, u, k)
    assert a.state() == b.state()


def test_a_motor_encoder_that_does_not_follow_the_first_pulse_stops_it() -> None:
    """The motor reading left at 0 (the input not connected) on the 20 Hz drive: the sample
    after the first pulse's first force shows no motor move, the controller stops
    (invalid_measurement) before its motor loop acts, and the table moves no more than that
    pulse alone moves it."""
    slave = _slave(DRIVE_20HZ)
    slave.initialize()
    ctl = make_controller(dual(), T)
    forces = []
    for k in range(100):
        ctl.x_d_meas = 0.0  # not connected
        u = ctl.update(k * T, slave.plant.x_meas(), 1e-3)
        forces.append(u)
        step(slave, u, k)
    assert ctl.outcome == Outcome.STOPPED and ctl.outcome_reason == Reason.INVALID_MEASUREMENT
    assert forces[0] > 0.0 and forces[1:] == [0.0] * 99
    alone = _slave(DRIVE_20HZ)
    alone.initialize()
    for k in range(100):
        step(alone, forces[0] if k == 0 else 0.0, k)
    assert slave.x == alone.x < 1e-3


# -- the mode identified from the motor encoder (f_mode = 0, identify_mode) ----------------------
@pytest.mark.parametrize(("f", "c_over_m"), [(20.0, 5.026), (10.0, 2.5), (24.9, 1.0)])
def test_the_mode_of_a_free_ringing_is_its_recurrence_inverted(f: float, c_over_m: float):
    """``delta_(k+1) = a_1*delta_k + a_2*delta_(k-1)`` of a ringing of frequency f (Hz) and
    decay c/m (1/s) sampled at T gives them back; real poles or poles outside the unit
    circle give none."""
    sigma = 0.5 * c_over_m
    w = 2.0 * math.pi * f
    w_d = math.sqrt(w * w - sigma * sigma)
    r = math.exp(-sigma * T)
    found = mode_of(2.0 * r * math.cos(w_d * T), -r * r, T)
    assert found == pytest.approx((f, c_over_m), rel=1e-9, abs=1e-9)
    assert mode_of(1.5, -0.5, T) is None  # real poles (0.5 and 1)
    assert mode_of(0.0, -1.21, T) is None  # |z| = 1.1: growing


@pytest.mark.parametrize(("params", "f_true"), [
    (DRIVE_20HZ, 20.0004),
    (DRIVE_10HZ, 10.0002),
    ({**DRIVE_20HZ, "x_resolution": 1e-7, "x_d_resolution": 1e-7, "noise_std": 4e-7,
      "x_d_noise_std": 4e-7, "seed": 3}, 20.0004),
])
def test_the_probe_identifies_the_mode_before_the_first_pulse(params: dict,
                                                             f_true: float) -> None:
    """The probe (one sample of 0.4*f_c_est on the motor) leaves the drive ringing while the
    table sticks; the mode is identified from the motor encoder within 0.2 s (measured: at
    the 18th sample, to 3e-8 relative on ideal encoders, 0.094 % with 0.4 um of noise on
    both), the motor loop is built with it before any pulse, and the table has not moved;
    the loop relaxes the probe's ringing before the maneuver's first pulse."""
    slave = _slave(params)
    slave.initialize()
    ctl = make_controller(dual(f_mode=0.0, identify_mode=True), T)
    forces = []
    for k in range(40):
        ctl.x_d_meas = slave.plant.x_d_meas()
        forces.append(ctl.update(k * T, slave.plant.x_meas(), 1e-3))
        if ctl.motor is not None:
            break
        step(slave, forces[-1], k)
    assert ctl.motor is not None and k <= 20, k
    assert ctl.mode_id.f_mode == pytest.approx(f_true, rel=2e-3 if "noise_std" in params
                                               else 2e-4)
    assert ctl.motor.omega == pytest.approx(2.0 * math.pi * ctl.mode_id.f_mode)
    assert forces[0] == pytest.approx(PROBE_SHARE * 80.0) and set(forces[1:-1]) == {0.0}
    assert ctl.seq.pulses == 0 and slave.x == 0.0
    assert forces[-1] == ctl.u_last != 0.0  # the loop's force: it relaxes the probe's ringing
    step(slave, forces[-1], k)
    for j in range(k + 1, k + 30):  # and only then the maneuver's first pulse
        ctl.x_d_meas = slave.plant.x_d_meas()
        step(slave, ctl.update(j * T, slave.plant.x_meas(), 1e-3), j)
        if ctl.seq.pulses:
            assert ctl.relaxed >= 3 and ctl.motor.amplitude() <= ctl.f_relax
            break
    assert ctl.seq.pulses == 1


def test_without_a_motor_reading_the_probe_identifies_nothing() -> None:
    """The motor encoder not connected (x_d_meas left at 0) or a rigid drive (no deflection):
    no mode after the probe's wait, no motor loop; on the rigid table the maneuver then goes
    on as the exact-model controller's on the table encoder, the probe not moving it."""
    params = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
    for connected, drive in ((False, DRIVE_20HZ), (True, params)):
        slave = _slave(drive)
        slave.initialize()
        ctl = make_controller(dual(f_mode=0.0, identify_mode=True), T)
        wait = int(round(PROBE_WAIT_S / T))
        for k in range(wait + 1):
            ctl.x_d_meas = slave.plant.x_d_meas() if connected else 0.0
            u = ctl.update(k * T, slave.plant.x_meas(), 1e-3)
            step(slave, u, k)
        assert ctl.motor is None and ctl.mode_id.f_mode == 0.0
        assert slave.x == 0.0 and ctl.seq.pulses == 0
    result = run_controller(_slave(params), dual(f_mode=0.0, identify_mode=True),
                            Maneuver(x_ref=1e-3, T=T, duration=2.0, iterations=2))
    assert not result.error
    assert abs(1e-3 - result.traces[-1].column("x")[-1]) <= 1e-7


def test_identification_takes_only_force_free_readings_of_a_stuck_table() -> None:
    """A force, or a table that moved beyond the band, ends a run of readings: no triple
    spans them; the first SETTLE force-free readings after a force are not taken."""
    ident = ModeIdentifier(T)
    for k in range(6):
        ident.observe(1e-6 * k, 0.0, 0.0, 0.0)
    assert ident.triples == 6 - 3 - 2  # 3 settle, 2 to begin the run
    ident.observe(1e-6, 0.0, 5.0, 0.0)  # a force
    assert ident.recent == [] and ident.quiet == 0
    for _ in range(4):
        ident.observe(1e-6, 0.0, 0.0, 0.0)
    assert ident.recent == [1e-6]
    ident.observe(1e-6, 1e-6, 0.0, 0.0)  # the table moved: a new run where it is
    assert ident.recent == [1e-6] and ident.x_run == 1e-6 and ident.triples == 1


# -- the drive check: the model told against the motor encoder's answer to the probe ----------
def _ringing(f: float, m_d: float, c_t: float, probe: float, delay: int, n: int = 60,
             x_d_follows: bool = True) -> list[float]:
    """Deflections read at samples 0..n-1 after one sample of ``probe`` N sent at sample 0
    that acts ``delay`` samples later, on a motor of mass m_d (kg) ringing at f (Hz) with
    damping c_t (N.s/m) against a stuck table (the exact sampled model)."""
    drive = MotorLoop(2.0 * math.pi * f, m_d, c_t, T)
    (p11, p12, p21, p22), (g1, g2) = drive.phi, drive.gamma
    delta = rate = 0.0
    out = []
    for k in range(n):
        out.append(delta if x_d_follows else 0.0)
        u = probe if k == delay else 0.0
        delta, rate = p11 * delta + p12 * rate + g1 * u, p21 * delta + p22 * rate + g2 * u
    return out


def _check(told: float, m_d: float, readings: list[float]) -> DriveCheck:
    check = DriveCheck(T, 0.0, told, m_d, 32.0, int(round(PROBE_WAIT_S / T)))
    for delta in readings:
        if check.observe(delta, 0.0) != DriveCheck.PENDING:
            break
    return check


@pytest.mark.parametrize("delay", [0, 1])
def test_the_drive_check_accepts_the_mode_and_mass_the_ringing_shows(delay: int) -> None:
    """On the 20 Hz drive (50 kg, 251.3 N.s/m): the delay of the force, the mode to 1e-6 and
    the ratio of the amplitude to the model's (the mass told over the true one) to 1e-6; a
    mode told 9 % off is accepted, the loop is built on the mode seen."""
    for told in (20.0, 18.3, 21.8):
        check = _check(told, 50.0, _ringing(20.0, 50.0, 251.3, 32.0, delay))
        assert check.verdict == DriveCheck.ACCEPTED and check.delay == delay
        assert check.f_mode == pytest.approx(20.0, rel=1e-6)
        assert check.mass_ratio == pytest.approx(1.0, rel=1e-6)
        assert check.k <= 20 + delay


@pytest.mark.parametrize(("told", "m_d", "why"), [
    (25.0, 50.0, "mode 25 % high"), (24.0, 50.0, "mode 20 % high"),
    (16.0, 50.0, "mode 20 % low"), (15.0, 50.0, "mode 25 % low"),
    (17.8, 50.0, "mode 11 % low"), (22.2, 50.0, "mode 11 % high"),
    (20.0, 75.0, "motor mass 1.5 times"), (20.0, 35.0, "motor mass 0.7 times"),
])
def test_the_drive_check_contradicts_a_model_the_ringing_does_not_show(told, m_d, why) -> None:
    check = _check(told, m_d, _ringing(20.0, 50.0, 251.3, 32.0, 0))
    assert check.verdict == DriveCheck.CONTRADICTED, why
    assert check.f_mode == pytest.approx(20.0, rel=1e-6)


def test_the_drive_check_without_ringing_or_a_following_encoder() -> None:
    """A motor encoder that does not move after the probe (not connected): not following
    after MAX_DELAY + 1 readings; a deflection that decays without ringing (a real pole):
    no mode within the wait, the mode told not seen."""
    wait = int(round(PROBE_WAIT_S / T))
    check = _check(20.0, 50.0, _ringing(20.0, 50.0, 251.3, 32.0, 0, x_d_follows=False))
    assert check.verdict == DriveCheck.NOT_FOLLOWING and check.k == 3
    check = _check(20.0, 50.0, [0.0] + [3e-5 * 0.8**k for k in range(wait + 5)])
    assert check.verdict == DriveCheck.NOT_SEEN and check.k == wait + 2
    assert check.f_mode == 0.0


@pytest.mark.parametrize("settings", [dual(f_mode=15.0), dual(f_mode=16.0), dual(f_mode=24.0),
                                      dual(f_mode=25.0), dual(m_d_est=100.0)])
def test_a_drive_model_the_ringing_contradicts_is_refused_at_the_first_evidence(settings):
    """Told 15, 16, 24 or 25 Hz (or a motor of twice its mass) on the 20 Hz drive: the probe's
    ringing contradicts it, every maneuver stops ``model_rejected`` before any pulse, the
    output is 0 after the probe and the table never moves (before the check, told 24 and
    25 Hz left it 0.09 m and 0.22 m past a 10 mm target, rc 0, status ok)."""
    for x_ref, result in _runs(DRIVE_20HZ, settings):
        for tr in result.traces:
            assert tr.column("outcome")[-1] == Outcome.STOPPED
            assert tr.column("outcome_reason")[-1] == Reason.MODEL_REJECTED
            assert set(tr.column("x")) == {0.0} and max(tr.column("pulses")) == 0
            u = [f for f in tr.column("u") if f == f]
            assert set(u[1:]) <= {0.0} and abs(u[0]) <= PROBE_SHARE * 80.0, x_ref


@pytest.mark.parametrize(("params", "settings"), [(DRIVE_20HZ, dual()), (DRIVE_10HZ,
                                                                         dual(f_mode=10.0))])
def test_under_delayed_timing_the_delay_is_part_of_its_model(params, settings) -> None:
    """``timing = "delayed"`` (the force one sample late, as libcosim, ecos and papwc cosim
    step): the probe finds the delay, the motor loop acts on the state the force already
    sent leaves; no maneuver farther, and on the 20 Hz drive no pulse a hard requirement
    forbids and each target within 1 um in the last iteration (before: stopped after one
    pulse, 9.76 mm short, naming invalid_measurement). The 10 Hz drive's pulses are not
    held to the bound yet, with either timing (see docs/_incoming/43-dual-loop.md)."""
    for x_ref in (1e-2, 1e-3, 5e-5):
        maneuver = Maneuver(x_ref=x_ref, T=T, duration=2.0, iterations=3, timing="delayed")
        controller = make_controller(settings, T)
        result = run_closed_loop(_slave(params), ControllerSlave(controller), maneuver,
                                 settings)
        assert not result.error and controller.delay == 1
        for tr in result.traces:
            assert abs(x_ref - tr.column("x")[-1]) <= x_ref
            assert tr.column("outcome_reason")[-1] != Reason.INVALID_MEASUREMENT
        if params is DRIVE_20HZ:
            assert abs(x_ref - result.traces[-1].column("x")[-1]) <= 1e-6, x_ref
            assert not hard_runaways(result.traces, params, T)


def test_a_loop_that_feeds_the_drive_stops_it_for_good() -> None:
    """A motor loop that feeds the drive instead of relaxing it (the check passed, then the
    drive changed: here a loop with four times the gain): model_rejected at the sample
    its ringing has doubled, 0 after it, and every later maneuver refused."""
    slave = _slave(DRIVE_20HZ)
    slave.initialize()
    ctl = make_controller(dual(), T)
    k = 0
    while ctl.motor is None:
        ctl.x_d_meas = slave.plant.x_d_meas()
        step(slave, ctl.update(k * T, slave.plant.x_meas(), 1e-3), k)
        k += 1
    ctl.motor.gain = tuple(4.0 * g for g in ctl.motor.gain)
    forces = []
    for j in range(k, k + 60):
        ctl.x_d_meas = slave.plant.x_d_meas()
        forces.append(ctl.update(j * T, slave.plant.x_meas(), 1e-3))
        step(slave, forces[-1], j)
        if ctl.outcome == Outcome.STOPPED:
            break
    assert ctl.outcome_reason == Reason.MODEL_REJECTED and ctl.refused
    assert ctl.update((j + 1) * T, slave.plant.x_meas(), 1e-3) == 0.0
    ctl.reset()
    assert ctl.update(0.0, slave.plant.x_meas(), 1e-3) == 0.0
    assert ctl.outcome == Outcome.STOPPED and ctl.outcome_reason == Reason.MODEL_REJECTED


#: Readings inside sane bounds: the table within 20 mm of its start, the spring's deflection
#: within 1 mm (800 N on the 20 Hz drive), both on or off the 0.1 um grid.
_READINGS = st.lists(st.tuples(st.floats(-0.02, 0.02, allow_nan=False),
                               st.floats(-1e-3, 1e-3, allow_nan=False)),
                     min_size=1, max_size=60)


@settings(max_examples=60, deadline=None)
@given(start=st.integers(0, 150), readings=_READINGS, delayed=st.booleans())
def test_no_measurement_sequence_makes_it_output_nan_or_beyond_f_p_max(start, readings,
                                                                        delayed) -> None:
    """The controller runs on the 20 Hz drive for ``start`` samples (the check, the loop,
    pulses), then takes any readings drawn inside sane bounds: every force is finite and
    within f_p_max."""
    slave = _slave(DRIVE_20HZ)
    slave.initialize()
    ctl = make_controller(dual(), T)
    sent = 0.0
    for k in range(start):
        ctl.x_d_meas = slave.plant.x_d_meas()
        u = ctl.update(k * T, slave.plant.x_meas(), 1e-3)
        assert math.isfinite(u) and abs(u) <= 300.0
        step(slave, sent if delayed else u, k)
        sent = u
    for j, (x, delta) in enumerate(readings, start):
        ctl.x_d_meas = x + delta
        u = ctl.update(j * T, x, 1e-3)
        assert math.isfinite(u) and abs(u) <= 300.0, (j, x, delta, u)
