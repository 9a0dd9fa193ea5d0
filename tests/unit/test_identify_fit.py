"""``papwc identify``'s fit on logs of its own excitation through plants drawn in Table 1
+-50 %: the parameters, their intervals, the deviations chosen, the replay."""

from __future__ import annotations

import numpy as np
import pytest

from papwc.identify.excitation import apply_to_plant, design
from papwc.identify.fit import identify, regression
from papwc.identify.motion import analyse
from papwc_studies.identify_accuracy import NOISY, TABLE1, draws

H = 0.01


@pytest.fixture(scope="module")
def excitation() -> np.ndarray:
    """The default design (60 s at 100 Hz) for the Table 1 plant."""
    return design(H, 300.0, 0.05, 60.0)


def _errors(ident, truth: dict[str, float]) -> dict[str, float]:
    return {e.name: e.value / truth[e.name] - 1.0 for e in ident.estimates if e.name in truth}


@pytest.mark.parametrize("plant", draws(1, 6), ids=lambda p: f"m{p['m']:.0f}")
def test_ideal_encoder_within_half_a_percent_and_inside_the_intervals(excitation, plant):
    ident = identify(apply_to_plant(excitation, H, plant), deviations=())
    errors = _errors(ident, plant)
    assert set(errors) == {"m", "f_c", "f_s", "c"}
    assert max(abs(e) for e in errors.values()) < 0.005, errors
    for e in ident.estimates:
        if e.name in plant:
            assert e.low <= plant[e.name] <= e.high, e
    assert ident.motion.resolution == 0.0 and ident.motion.noise == 0.0
    assert ident.replay_rms <= ident.replay_bound == 1e-9


@pytest.mark.parametrize("plant", draws(2, 6), ids=lambda p: f"m{p['m']:.0f}")
def test_noisy_encoder_within_three_percent_and_replay_within_three_counts(excitation, plant):
    ident = identify(apply_to_plant(excitation, H, {**plant, **NOISY, "seed": 7}), deviations=())
    errors = _errors(ident, plant)
    assert max(abs(e) for e in errors.values()) < 0.03, errors
    assert ident.motion.resolution == pytest.approx(1e-7, rel=1e-9)
    assert ident.motion.noise == pytest.approx(2e-7, rel=0.1)
    # Replay: 3 counts rms (the noise itself is 2 counts).
    assert ident.replay_rms <= 3e-7


def test_the_regression_is_exact_on_an_ideal_log(excitation):
    log = apply_to_plant(excitation, H, TABLE1)
    start, rows = regression(log, analyse(log))
    assert rows > 500
    for name in ("m", "f_c", "c"):
        assert start[name] == pytest.approx(TABLE1[name], rel=1e-9)


@pytest.mark.slow
def test_no_deviation_is_reported_where_there_is_none(excitation):
    plant = draws(3, 1)[0]
    ident = identify(apply_to_plant(excitation, H, {**plant, **NOISY, "seed": 3}))
    assert ident.chosen == []
    # the deviations are fitted all together first, then each dropped in turn: every one was
    # tried, and the model with all of them was not taken
    together = [t for t in ident.trials if t.label.startswith("+")]
    assert len(together) == 1 and not together[0].chosen
    dropped = {t.label.split("(")[0] for t in ident.trials if t.label.startswith("without")}
    assert {"without Stribeck curve ", "without actuator lag ",
            "without friction ripple "} <= dropped
    errors = _errors(ident, plant)
    # this plant breaks away at 66.7 N, below the first step of every tooth (0.6 times the
    # expected 130 N): no stick is bracketed, so there is no band and f_s is not identified
    assert plant["f_s"] < 0.6 * TABLE1["f_s"] and ident.band is None
    errors.pop("f_s")
    assert max(abs(e) for e in errors.values()) < 0.03, errors


@pytest.mark.slow
def test_a_stribeck_velocity_is_found_within_ten_percent(excitation):
    plant = {**TABLE1, "v_s": 1e-3}
    ident = identify(apply_to_plant(excitation, H, {**plant, **NOISY, "seed": 5}))
    assert ident.chosen == ["stribeck"]
    errors = _errors(ident, plant)
    assert abs(errors.pop("v_s")) < 0.10, errors
    assert max(abs(e) for e in errors.values()) < 0.03, errors
    assert ident.plant["delta_s"] == 2.0


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="measured 2026-12-05: the replay of the whole 60 s log "
                   "on a plant identified within 1 % is 9.4e-7 m rms, beyond its own bound "
                   "(3 counts, 4e-7 m here) and the 3e-7 m of the excitation before issue 46, "
                   "whose pulses each had a mirror image; the walk now goes one way for many "
                   "pulses (not investigated further this round)")
def test_the_replay_of_a_stribeck_table_is_within_its_bound(excitation):
    plant = {**TABLE1, "v_s": 1e-3}
    ident = identify(apply_to_plant(excitation, H, {**plant, **NOISY, "seed": 5}))
    assert ident.replay_rms <= ident.replay_bound
