"""papwc_studies.flexible_scatter: the same pulse from a relaxed flexible drive on a table
whose breakaway is redrawn at every stop."""

from __future__ import annotations

import re
import statistics

from papwc_studies import flexible_scatter as fs


def _params(case: str, spread: float) -> tuple[dict[str, float], float]:
    base, T = fs.drive(case)
    return {**base, "v_s": fs.V_S, "c_t": fs.C_T, "f_s_spread": spread, "seed": 1}, T


def test_the_drive_is_the_monte_carlos_and_a_pulse_moves_the_same_without_spread():
    params, T = _params("flexible_20hz", 0.0)
    assert (params["m"], params["m_d"], params["k_t"], T) == (100.0, 50.0, 7.896e5, 0.01)
    moved = fs.relaxed_pulse(params, 20.0, 145.0, 10, T)
    assert len(moved) == 10 and min(moved) > 1e-6
    assert max(moved) - min(moved) < 1e-12


def test_the_same_pulse_scatters_with_the_breakaway_spread_and_more_for_a_longer_move():
    params, T = _params("flexible_20hz", 0.05)
    short = [d for d in fs.relaxed_pulse(params, 20.0, 141.5, 60, T) if d > fs.MOVED]
    long = [d for d in fs.relaxed_pulse(params, 20.0, 151.5, 60, T) if d > fs.MOVED]
    assert len(short) > 30 and len(long) == 60
    assert statistics.median(long) > 3 * statistics.median(short)
    assert max(long) - min(long) > 5e-6 > max(short) - min(short) > 1e-6
    # a table that does not move within the spring's first peak is read then (0)
    assert fs.relaxed_pulse(params, 20.0, 100.0, 3, T) == [0.0, 0.0, 0.0]


def test_the_report_gives_a_line_per_drive_spread_and_push(capsys):
    fs.main(["--repeats", "5"])
    out = capsys.readouterr().out
    lines = re.findall(r"spread +[0-9.]+ %, push +[0-9.]+ N: moved (\d+) of 5", out)
    assert len(lines) == len(fs.DRIVES) * len(fs.SPREADS) * len(fs.ABOVE)
    for low, med, top, share in re.findall(
            r"([0-9.]+) / +([0-9.]+) / +([0-9.]+) um .*?median \d+ \((\d+) %\)", out):
        assert float(low) <= float(med) <= float(top) and 0 <= int(share) <= 100
