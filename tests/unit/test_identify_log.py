"""Bad logs for ``papwc identify``: each refused in one line naming the row, the column and
what is wrong (papwc.identify.log_file, papwc.identify.motion, papwc.identify.fit)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from papwc.identify.excitation import apply_to_plant, design
from papwc.identify.fit import check_log
from papwc.identify.fit_report import write_log
from papwc.identify.log_file import Columns, LogError, check_travel, parse_log, read_log


def _csv(rows: list[tuple[float | str, ...]], header: str = "time,u,x") -> str:
    return header + "\n" + "".join(",".join(str(v) for v in row) + "\n" for row in rows)


def _good_rows(n: int = 12) -> list[list]:
    return [[k * 0.01, 0.0, 0.0] for k in range(n)]


@pytest.fixture(scope="module")
def good_log_text() -> str:
    """A short log of the design's start through the Table 1 plant."""
    u = design(0.01, 300.0, 0.05, 40.0)
    log = apply_to_plant(u, 0.01, {})
    return _csv([(repr(float(t)), repr(float(f)), repr(float(x)))
                 for t, f, x in zip(log.t, log.u, log.x, strict=True)])


def _one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text
    return text


def test_a_good_log_passes_every_check(good_log_text):
    log = parse_log(good_log_text, "good.csv")
    check_travel(log, 0.05)
    check_log(log)
    assert log.h == pytest.approx(0.01)


def test_a_non_numeric_value_names_row_and_column():
    rows = _good_rows()
    rows[4][2] = "abc"
    with pytest.raises(LogError) as info:
        parse_log(_csv(rows), "log.csv")
    assert _one_line(info) == "log.csv, row 5 (line 6), column 'x': 'abc' is not a number"


def test_nan_names_row_and_column():
    rows = _good_rows()
    rows[6][1] = "nan"
    with pytest.raises(LogError) as info:
        parse_log(_csv(rows), "log.csv")
    assert _one_line(info).startswith("log.csv, row 7 (line 8), column 'u': 'nan' is NaN")


def test_an_infinite_value_is_refused():
    rows = _good_rows()
    rows[2][1] = "inf"
    with pytest.raises(LogError) as info:
        parse_log(_csv(rows), "log.csv")
    assert "row 3 (line 4), column 'u': 'inf' is not finite" in _one_line(info)


def test_time_that_does_not_increase_names_the_row():
    rows = _good_rows()
    rows[5][0] = rows[4][0]
    with pytest.raises(LogError) as info:
        parse_log(_csv(rows), "log.csv")
    text = _one_line(info)
    assert text.startswith("log.csv, row 6 (line 7), column 'time': time 0.04 s is not after "
                           "0.04 s of row 5")


def test_uneven_time_names_the_row():
    rows = _good_rows()
    for row in rows[7:]:
        row[0] += 0.005
    with pytest.raises(LogError) as info:
        parse_log(_csv(rows), "log.csv")
    text = _one_line(info)
    assert "row 8 (line 9), column 'time'" in text and "uneven time" in text


def test_too_few_rows_to_contain_a_move():
    with pytest.raises(LogError) as info:
        parse_log(_csv(_good_rows(5)), "log.csv")
    assert "rows 1-5, column 'x': 5 rows are too short to contain a move" in _one_line(info)


def test_a_log_too_short_for_sliding_is_refused():
    # A rest, one short move, a rest: no runs of sliding to fit m and c.
    x = [0.0] * 5 + [1.3e-5, 2.9e-5] + [2.9e-5] * 8
    u = [0.0] * 4 + [200.0] + [0.0] * 10
    rows = [(k * 0.01, u[k], x[k]) for k in range(15)]
    log = parse_log(_csv(rows), "log.csv")
    with pytest.raises(LogError) as info:
        check_log(log)
    assert "column 'x': too short to contain a move" in _one_line(info)


def test_no_motion_at_all_names_the_column_and_the_largest_force():
    rows = _good_rows(30)
    rows[10][1] = 90.0
    with pytest.raises(LogError) as info:
        check_log(parse_log(_csv(rows), "log.csv"))
    text = _one_line(info)
    assert text.startswith("log.csv, rows 1-30, column 'x': no motion at all")
    assert "90.0 N in row 11 (column 'u')" in text


def test_position_beyond_the_travel_names_row_and_column():
    rows = _good_rows(20)
    rows[13][2] = 0.07
    log = parse_log(_csv(rows), "log.csv")
    with pytest.raises(LogError) as info:
        check_travel(log, 0.05)
    assert _one_line(info).startswith("log.csv, row 14 (line 15), column 'x': position 0.07 m "
                                      "is beyond the travel")


def test_a_force_that_never_exceeds_the_breakaway():
    # The table slides in at the start (not from a rest), stops, and the forces after it
    # (below the breakaway) never move it again.
    x = [0.0, 3e-3, 5e-3, 6e-3, 6.4e-3] + [6.4e-3] * 20
    u = [0.0] * 5 + [50.0, 0.0, -80.0, 0.0, 110.0] + [0.0] * 15
    rows = [(k * 0.01, u[k], x[k]) for k in range(25)]
    with pytest.raises(LogError) as info:
        check_log(parse_log(_csv(rows), "log.csv"))
    text = _one_line(info)
    assert text.startswith("log.csv, row 10 (line 11), column 'u': the force never exceeds the "
                           "breakaway")
    assert "110.0 N" in text


def test_a_missing_column_is_named_with_the_columns_there():
    with pytest.raises(LogError) as info:
        parse_log(_csv(_good_rows(), header="t,u,x"), "log.csv")
    assert _one_line(info) == ("log.csv, line 1: no column 'time' (time); the columns are 't', "
                               "'u', 'x'; name the column with the option for the time")


def test_a_short_row_names_the_missing_field():
    text = _csv(_good_rows()).replace("0.03,0.0,0.0", "0.03,0.0")
    with pytest.raises(LogError) as info:
        parse_log(text, "log.csv")
    assert "row 4 (line 5), column 'x': missing" in _one_line(info)


def test_column_names_are_options(good_log_text):
    renamed = good_log_text.replace("time,u,x", "t_s,F,pos", 1)
    log = parse_log(renamed, "log.csv", Columns("t_s", "F", "pos"))
    assert log.x.size > 1000


def test_files_that_are_no_logs(tmp_path: Path):
    with pytest.raises(LogError, match="no such log file"):
        read_log(tmp_path / "missing.csv")
    with pytest.raises(LogError, match="is a folder"):
        read_log(tmp_path)
    binary = tmp_path / "b.csv"
    binary.write_bytes(b"time,u,x\n\0\0")
    with pytest.raises(LogError, match="binary"):
        read_log(binary)
    latin = tmp_path / "l.csv"
    latin.write_bytes(b"time,u,x\n0,0,0\xe9\n")
    with pytest.raises(LogError, match="not UTF-8"):
        read_log(latin)


def test_a_log_written_by_write_log_reads_back(tmp_path: Path):
    u = np.array([0.0, 200.0, 0.0, 0.0])
    log = apply_to_plant(u, 0.01, {})
    write_log(tmp_path / "log.csv", log)
    with pytest.raises(LogError, match="too short"):
        read_log(tmp_path / "log.csv")
