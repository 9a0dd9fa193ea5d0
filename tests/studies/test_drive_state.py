"""papwc_studies.drive_state: planning on a model of the flexible drive, carried along."""

from __future__ import annotations

import pytest

from papwc_studies import drive_state


@pytest.mark.slow
def test_an_exact_model_lands_and_a_spring_two_percent_off_does_not():
    exact = drive_state.landings({}, 2)
    assert len(exact) == 2 and max(abs(e) for e in exact) < 1e-8
    # the model's drive rings at another frequency: its spring force, and the breakaway, drift
    stiff = drive_state.landings({"k_t": 1.02}, 2)
    assert max(abs(e) for e in stiff) > 5e-6
