"""``papwc bench``'s update-time section (R7): what it runs, what it times, its verdict."""

from __future__ import annotations

import math
import time

import pytest

from papwc.bench import Row
from papwc.bench.update_time import FILES, selected_runs, update_rows, update_times
from papwc.cli import main
from papwc.controllers import CONTROLLER_KINDS


def test_every_registered_kind_is_measured_at_its_own_rate() -> None:
    scenarios = selected_runs(FILES, quick=True)
    kinds = {(s.kind, sc.maneuver.T) for sc in scenarios for s in sc.controllers}
    assert {kind for kind, _ in kinds} == set(CONTROLLER_KINDS)
    assert ("pid", 0.001) in kinds and ("pid", 0.01) in kinds and ("hybrid", 0.001) in kinds
    # quick: one target, seed and draw per case; realism.toml has 8 cases
    assert sum(1 for sc in scenarios if sc.name == "realism") == 8
    full = selected_runs(["realism.toml"])
    # 8 cases x 3 targets, and 4 more seeds where a seed draws (stiction, noise)
    assert len(full) == 8 * 3 + 2 * 3 * 4


def test_each_update_is_timed_and_a_slow_one_is_run_again(monkeypatch) -> None:
    """The exact case of realism.toml, 0.3 s: one time per update (30 samples), thread CPU
    time. A run with an update above T/4 is made again and each update keeps its least
    time."""
    (scenario,) = [sc for sc in selected_runs(["realism.toml"], quick=True)
                   if sc.name == "realism" and not any(sc.plant.get(k) for k in (
                       "v_s", "sigma_0", "ripple", "f_s_spread", "tau_u", "m_d",
                       "noise_std"))]
    scenario.maneuver.duration = 0.3
    scenario.maneuver.iterations = 1
    scenario.controllers = scenario.controllers[:1]
    scenario.labels = scenario.labels[:1]
    times = update_times([scenario], plant="physics")
    assert list(times) == [("pwc", 0.01)] and len(times[("pwc", 0.01)]) == 30
    assert all(0 <= t < 5e6 for t in times[("pwc", 0.01)])

    # every update 1 us; a machine that takes 4 ms from the first pass's fifth, never again
    clock = iter(range(10**9))

    def fake_clock() -> int:
        tick = next(clock)  # two ticks per update: its start and its end
        return tick * 1000 + (4_000_000 if tick == 9 else 0)

    monkeypatch.setattr(time, "thread_time_ns", fake_clock)
    timed = update_times([scenario], plant="physics")[("pwc", 0.01)]
    assert len(timed) == 30 and max(timed) == 1000  # the 4 ms were the machine's


def test_the_rows_give_the_verdict_of_r7() -> None:
    rows = update_rows({("exact", 0.01): [1_000_000, 6_000_000, 2_000_000],
                        ("pid", 0.001): [5_000, 7_000]})
    by = {r.label: r for r in rows}
    assert by["exact at T = 10 ms: max"] == Row("exact at T = 10 ms: max", 6.0, "ms")
    assert by["exact at T = 10 ms: median"].value == 2.0
    assert by["exact at T = 10 ms: updates beyond T/2"].value == 1
    assert "exact at T = 10 ms: R7 goal, max at most T/2 (MISSED)" in by
    assert by["pid at T = 1 ms: R7 goal, max at most T/2 (met)"].value == pytest.approx(0.5)
    assert math.isclose(by["pid at T = 1 ms: p99"].value, 0.007)


def test_only_a_section_that_exists_runs(capsys, tmp_path) -> None:
    assert main(["bench", "--fmu-dir", str(tmp_path), "--only", "no such section"]) == 2
    err = capsys.readouterr().err
    assert "--only 'no such section': no section's title holds it" in err
    assert "Controller update time against the sample period" in err
