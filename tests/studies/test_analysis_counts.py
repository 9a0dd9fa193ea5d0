"""The command line of the analyses that take one count."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from papwc_studies import ceiling, drive_state, flexible_scatter, scatter
from papwc_studies.counts import parse_count


@pytest.mark.parametrize("main, option, high", [
    (scatter.main, "--repeats", scatter.REPEATS_MAX),
    (flexible_scatter.main, "--repeats", flexible_scatter.REPEATS_MAX),
    (drive_state.main, "--moves", drive_state.MOVES_MAX),
    (ceiling.main, "--tables", ceiling.TABLES_MAX),
])
@pytest.mark.parametrize("value, said", [("0", "0 is outside 1..{high}"),
                                         ("2.5", "'2.5' is not a whole number"),
                                         ("{above}", "{above} is outside 1..{high}")])
def test_a_bad_count_is_refused_in_one_line(capsys, main, option, high, value, said):
    value = value.format(above=high + 1)
    with pytest.raises(SystemExit) as stop:
        main([option, value])
    assert stop.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.endswith(f"argument {option}: " + said.format(high=high, above=high + 1))


def test_a_count_in_range_is_taken_and_its_absence_gives_the_default():
    args = ("prog", "what it does", "--n", 7, 10, "things")
    assert parse_count(["--n", "10"], *args) == 10
    assert parse_count([], *args) == 7
    with pytest.raises(SystemExit):
        parse_count(["--other", "1"], *args)


def _interrupted() -> int:
    print("a line before")
    raise KeyboardInterrupt


def test_an_analysis_interrupted_says_so_in_one_line_and_keeps_what_it_printed(capsys):
    from papwc.exit_status import run_command

    assert run_command("python -m papwc_studies.scatter", _interrupted) == 130
    out, err = capsys.readouterr()
    assert out == "a line before\n"
    assert err == "python -m papwc_studies.scatter: interrupted\n"


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_an_analysis_on_a_full_device_says_so_in_one_line():
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "papwc_studies.scatter", "--repeats", "1"],
                              stdout=full, stderr=subprocess.PIPE, text=True, timeout=120)
    assert done.returncode == 1
    assert done.stderr.splitlines() == [
        "python -m papwc_studies.scatter: error: cannot write to standard output: "
        "No space left on device"]
