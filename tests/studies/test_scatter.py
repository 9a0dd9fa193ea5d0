"""papwc_studies.scatter: the same pulse on a table whose breakaway is redrawn at every stop."""

from __future__ import annotations

import re
import statistics

from papwc_studies import scatter


def test_the_same_pulse_scatters_on_random_stiction_and_not_without_it():
    base, T = scatter.table()
    stribeck = {**base, "v_s": 5e-3, "seed": 1}
    # Stribeck alone: the same pulse from rest moves the same every time
    plain = scatter.repeated_pulse(stribeck, 150.0, 20, T)
    assert max(plain) > 1e-6 and max(plain) - min(plain) < 1e-12
    # with the breakaway redrawn at every stop it scatters by more than 1.5 about its median
    moved = scatter.repeated_pulse({**stribeck, "f_s_spread": 0.15}, 150.0, 60, T)
    assert all(d > scatter.MOVED for d in moved)
    assert max(moved) > 1.5 * statistics.median(moved) > 1.5 * min(moved)


def test_the_report_gives_a_line_per_case_and_height(capsys):
    scatter.main(["--repeats", "30"])
    out = capsys.readouterr().out
    lines = re.findall(r"moved (\d+) of 30; ([0-9.]+) / ([0-9.]+) / ([0-9.]+) um", out)
    assert len(lines) == len(scatter.CASES) * len(scatter.HEIGHTS)
    for n, low, med, top in lines:
        assert 0 < int(n) <= 30 and float(low) <= float(med) <= float(top)
    assert "safe plan" in out
