"""The parts of a pulse controller alone (rest detection, trust region, sequencer) and the
controller interface that the slave, PulseController.fmu and the trace read."""

from __future__ import annotations

import json
import math
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from papwc.controllers import (
    CONTROLLER_KINDS,
    OUTPUT_NAMES,
    Controller,
    Mode,
    Outcome,
    PulseControllerBase,
    Reason,
    make_controller,
)
from papwc.controllers.rest import BAND_SIGMAS, NOISE_DWELL, NOISE_WINDOW, RestDetector
from papwc.controllers.sequencer import PulseSequencer
from papwc.controllers.settings import ControllerSettings
from papwc.controllers.trust import TRUST_MIN, TrustRegion
from papwc.master.observers import _CONTROLLER
from papwc.master.slave import CONTROLLER_SLAVE_VARIABLES, ControllerSlave
from papwc.master.trace import TRACE_COLUMNS
from papwc.model.controller_settings import CONTROLLER_OUTPUTS

T = 0.01


# -- rest detection --------------------------------------------------------------------------
def test_a_noisy_rest_is_found_its_noise_measured_and_its_position_averaged():
    """Readings at rest with 0.2 um noise on a 0.1 um encoder: the quiet window finds the
    noise, the band grows to 6 sigma, the dwell to 5 samples, and the mean of the rest's
    readings lies within 3 standard errors of the true position."""
    rest = RestDetector(0.0, 1, True, 0)
    rng = random.Random(3)
    x_true, sigma = 1.234e-3, 2e-7

    def reading() -> float:
        return round((x_true + rng.gauss(0.0, sigma)) / 1e-7) * 1e-7

    x = reading()
    rest.start_run(x)
    found, prev = False, x
    for _ in range(400):
        x = reading()
        at_rest = rest.read(x, True)
        found = rest.force_free(x, x - prev, at_rest) or found
        prev = x
    assert found and rest.noise_rests >= 1
    assert math.sqrt(rest.sigma2) == pytest.approx(math.hypot(sigma, 1e-7 / math.sqrt(12)),
                                                   rel=0.25)
    assert rest.band == BAND_SIGMAS * math.sqrt(rest.sigma2) and rest.dwell == NOISE_DWELL
    assert abs(rest.x_hat() - x_true) <= 3.0 * rest.sigma_mean() + 5e-8
    # the state by name round-trips through JSON
    other = RestDetector(0.0, 1, True, 0)
    other.set_state(json.loads(json.dumps(rest.state())))
    assert other.state() == rest.state() and (other.band, other.dwell) == (rest.band, rest.dwell)


def test_without_noise_equal_readings_are_a_rest_after_the_dwell():
    rest = RestDetector(0.0, 3, True, 0)
    rest.start_run(1e-3)
    assert [rest.read(1e-3, True) for _ in range(4)] == [False, False, True, True]
    assert not rest.read(1.1e-3, True) and rest.n == 1  # a new run where it moved
    assert rest.sigma2 == 0.0 and rest.x_hat() == 1.1e-3


def test_a_moving_mass_is_not_taken_for_noise():
    rest = RestDetector(0.0, 1, True, 0)
    x = 0.0
    rest.start_run(x)
    for k in range(3 * NOISE_WINDOW):
        x_new = 1e-6 * (k + 1)  # creeps one way
        at_rest = rest.read(x_new, True)
        assert not rest.force_free(x_new, x_new - x, at_rest)
        x = x_new
    assert rest.sigma2 == 0.0


# -- trust region ----------------------------------------------------------------------------
def test_a_fooled_fit_shrinks_the_trust_and_good_predictions_restore_it():
    trust = TrustRegion(0.5, guarded=True, flexible=False)
    trust.judge(pred=1e-5, d_along=3e-5, noise=0.0)  # moved 3 times the prediction
    assert trust() == pytest.approx(0.4)  # 1.2/3 of the prediction's worth
    for _ in range(10):
        trust.judge(pred=1e-5, d_along=5e-5, noise=0.0)
    assert trust() >= TRUST_MIN and trust() == pytest.approx(0.24)
    trust.judge(pred=1e-5, d_along=1.1e-5, noise=0.0)
    assert trust() == pytest.approx(0.48)
    trust.judge(pred=1e-5, d_along=0.5e-5, noise=0.0)  # moved less: no reason to shrink
    assert trust() == pytest.approx(0.48)
    trust.judge(pred=0.0, d_along=1.0, noise=0.0)  # no prediction: nothing to judge
    assert trust() == pytest.approx(0.48)
    assert TrustRegion(1.0, guarded=True, flexible=True)() == 0.5
    assert TrustRegion(0.1, guarded=False, flexible=True)() == 1.0


def test_trust0_is_read_once_from_the_settings_of_the_kinds_that_have_it():
    s = ControllerSettings(kind="exact", trust0=0.3)
    assert make_controller(s, T).trust() == 0.3
    for kind in ("pwc", "papwc"):
        assert make_controller(ControllerSettings(kind=kind, trust0=0.3), T).trust() == 1.0


# -- the sequencer ---------------------------------------------------------------------------
class _Law(PulseControllerBase):
    """A control law that plans a fixed pulse and records what it learns."""

    kind = "test"

    def __init__(self, settings: ControllerSettings, pulse: tuple[int, float], pred: float):
        super().__init__(settings, T)
        self.pulse, self.pred, self.learned = pulse, pred, []

    def plan_pulse(self, e):
        n, f = self.pulse
        return n, math.copysign(f, e)

    def predict(self, n, f_p):
        return self.pred

    def learn(self, n, f_p, d):
        self.learned.append((n, f_p, d))


def test_a_creeping_hand_over_releases_the_force_and_pulses_once_at_rest():
    """A coarse move that creeps toward the target inside e_band: the force is released
    once coasting would stop inside e_band, and the first pulse comes only at rest."""
    s = ControllerSettings(kind="papwc", e_band=1e-3, tolerance=1e-7)
    law = _Law(s, (1, 150.0), 1e-5)
    seq = law.seq
    x_ref = 5e-3
    # far (coarse), fast inside e_band (coasting would not stop inside), then creeping at
    # 1 mm/s (coasting stops 1e-6 m on: released), still creeping, stopped
    xs = [0.0, 4.2e-3, 4.21e-3, 4.215e-3]
    forces = [law.update(k * T, x, x_ref) for k, x in enumerate(xs)]
    assert forces[0] == 15000.0 * 5e-3 + 80.0 and forces[1] != 0.0 and forces[2:] == [0.0, 0.0]
    assert seq.released and seq.mode == Mode.COARSE and seq.pulses == 0
    u = law.update(4 * T, 4.215e-3, x_ref)  # stopped: at rest (dwell 1), inside e_band
    assert u == 150.0 and seq.mode == Mode.PULSE and seq.pulses == 1
    assert seq.x_start == 4.215e-3 and seq.e0 == x_ref


def test_a_pulse_that_crept_is_learned_as_what_it_moved():
    """A pulse that moved less than predicted (a creep) is judged when the mass is at rest
    again: the law learns its displacement and the maneuver goes on."""
    s = ControllerSettings(kind="papwc", tolerance=1e-7, max_pulses=5)
    law = _Law(s, (1, 150.0), 1e-5)
    seq = law.seq
    x_ref = 1e-4
    assert law.update(0.0, 0.0, x_ref) == 150.0
    xs = [2e-9, 3e-9, 3e-9, 3e-9]  # crept 3 nm and stopped
    for k, x in enumerate(xs, start=1):
        law.update(k * T, x, x_ref)
    assert law.learned == [(1, 150.0, 3e-9)] and seq.last_d == 3e-9
    assert seq.pulses == 2 and seq.outcome == Outcome.ACTIVE  # the next pulse fired
    assert law.trust.value == 1.0  # moved less than predicted: the trust does not shrink


def test_a_pulse_predicted_to_end_farther_than_the_start_is_not_fired():
    s = ControllerSettings(kind="papwc", tolerance=1e-7)
    law = _Law(s, (1, 150.0), 1e-3)  # would overshoot a 1e-4 m error tenfold
    assert law.update(0.0, 0.0, 1e-4) == 0.0
    assert law.outcome == Outcome.STOPPED and law.outcome_reason == Reason.NO_MOVE_HELPS
    assert law.pulses == 0


def test_the_pulse_budget_stops_the_maneuver():
    s = ControllerSettings(kind="papwc", tolerance=1e-9, max_pulses=2)
    law = _Law(s, (1, 150.0), 1e-6)
    x = 0.0
    for k in range(40):
        if law.update(k * T, x, 1e-4) != 0.0:
            x += 1e-6
    assert law.pulses == 2 and law.outcome_reason == Reason.PULSE_BUDGET


def test_the_sequencer_state_is_a_named_mapping_that_round_trips():
    s = ControllerSettings(kind="papwc")
    law = _Law(s, (1, 150.0), 1e-5)
    law.update(0.0, 0.0, 1e-4)
    state = law.state()
    assert set(state) >= {f"sequencer.{n}" for n in PulseSequencer.FIELDS}
    assert {f"rest.{n}" for n in RestDetector.FIELDS} <= set(state)
    assert state["sequencer.mode"] == Mode.PULSE and state["trust.value"] == 1.0
    other = _Law(s, (1, 150.0), 1e-5)
    other.set_state(json.loads(json.dumps(state)))
    assert other.state() == state


# -- the interface ---------------------------------------------------------------------------
def test_the_outputs_are_declared_once_in_the_model_layer():
    names = tuple(v.name for v in CONTROLLER_OUTPUTS)
    assert OUTPUT_NAMES == tuple(n for n in names if n != "u")
    assert TRACE_COLUMNS[-len(OUTPUT_NAMES):] == OUTPUT_NAMES and _CONTROLLER == OUTPUT_NAMES
    assert {n for n, c in CONTROLLER_SLAVE_VARIABLES.items() if c == "output"} == set(names)
    for kind, cls in CONTROLLER_KINDS.items():
        assert issubclass(cls, Controller)
        ctl = make_controller(ControllerSettings(kind=kind), T)
        assert tuple(ctl.outputs()) == OUTPUT_NAMES
        slave = ControllerSlave(ctl)
        index = slave.watch(list(OUTPUT_NAMES))
        slave.initialize()
        # (repr: NaN estimates compare equal)
        assert [repr(slave.values[i]) for i in index] == [repr(v) for v in ctl.outputs().values()]


# -- any measurements ------------------------------------------------------------------------
readings = st.lists(st.one_of(
    st.floats(-0.05, 0.05), st.floats(-1e-5, 1e-5), st.just(0.0),
    st.floats(allow_nan=True, allow_infinity=True)), min_size=1, max_size=80)


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(sorted(CONTROLLER_KINDS)), xs=readings,
       x_ref=st.sampled_from([0.01, 1e-3, 5e-5, 1e-7]))
def test_no_measurements_make_any_controller_output_nan_or_exceed_its_force(kind, xs, x_ref):
    """Every registered kind: finite forces within f_p_max, finite state, outputs of the
    declared names, whatever it reads."""
    s = ControllerSettings(kind=kind, f_p_max=300.0, m_est=150.0, f_c_est=80.0,
                           tolerance=1e-7)
    ctl = make_controller(s, T)
    for k, x in enumerate(xs):
        u = ctl.update(k * T, x, x_ref)
        assert math.isfinite(u) and abs(u) <= 300.0
        out = ctl.outputs()
        assert tuple(out) == OUTPUT_NAMES
        assert ctl.mode in Mode.NAMES and ctl.outcome in (0, 1, 2)
    values = [q for v in ctl.state().values() for q in (v if isinstance(v, list) else [v])]
    assert all(math.isfinite(v) for v in values) or not abs(xs[0]) <= 1e6
