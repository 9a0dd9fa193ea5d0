"""``papwc run``: results on disk as they come, one line per failure, no traceback (issue 13).

Groups 1 (results written as each controller finishes, the folder marked
incomplete, stale files removed), 4 (operating-system errors, input files,
standard output) and 9 (warnings). The plant is the in-process physics, so no
FMU is needed; ``papwc reproduce`` and the FMU plant are covered in
tests/integration/test_reproduce_on_disk.py.
"""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

import papwc.output_files
import papwc.results.folder
import papwc.scenario_run
from papwc.cli import main

SCENARIO = """\
name = "disk"
[maneuver]
x_ref = 0.01
T = 0.01
duration = 0.5
iterations = {iterations}
[[controller]]
kind = "papwc"
label = "first"
t_p_max = 0.03
K_c = 0.8
[[controller]]
kind = "pwc"
label = "second"
t_p_max = 0.03
K_c = 0.5
"""


def scenario_file(tmp_path: Path, iterations: int = 2, text: str = SCENARIO) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(text.format(iterations=iterations), encoding="utf-8")
    return path


def run(tmp_path: Path, capsys, *extra: str, iterations: int = 2) -> tuple[int, str, str]:
    code = main(["run", str(scenario_file(tmp_path, iterations)), "--plant", "physics",
                 "--out", str(tmp_path / "out"), *extra])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err, err
    return lines[-1]


def test_ctrl_c_keeps_the_controllers_that_finished_and_marks_the_folder(
        tmp_path: Path, capsys, monkeypatch) -> None:
    real = papwc.scenario_run.run_controller

    def interrupted(slave, settings, maneuver, label="", observers=(), library=None,
                    stopped=None):
        if label == "second":
            raise KeyboardInterrupt
        return real(slave, settings, maneuver, label, observers, library, stopped)

    monkeypatch.setattr(papwc.scenario_run, "run_controller", interrupted)
    code, _, err = run(tmp_path, capsys)
    out = tmp_path / "out"
    assert code == 130
    assert "kept in" in err and "the results of first; missing: second" in err
    assert sorted(p.name for p in out.iterdir()) == [
        "INCOMPLETE", "pulses.csv", "summary.csv", "trace_first_it1.csv", "trace_first_it2.csv"]
    rows = (out / "summary.csv").read_text().splitlines()
    assert len(rows) == 3 and all(r.startswith("first,") for r in rows[1:])
    marker = (out / "INCOMPLETE").read_text()
    assert "interrupted (Ctrl-C)" in marker and "controller second" in marker
    assert "plot error.png" in marker


def fail_writes(monkeypatch, where, code: int) -> None:
    """Make every atomic write whose destination satisfies ``where`` fail with errno ``code``."""
    real = os.replace

    def failing(src, dst):
        if where(dst):
            raise OSError(code, os.strerror(code))
        return real(src, dst)

    monkeypatch.setattr(papwc.output_files.os, "replace", failing)


@pytest.mark.parametrize("code, reason", [(errno.ENOSPC, "No space left on device"),
                                          (errno.EROFS, "Read-only file system")])
def test_a_write_error_is_one_line_and_keeps_what_was_written(
        tmp_path: Path, capsys, monkeypatch, code, reason) -> None:
    fail_writes(monkeypatch, lambda dst: "second" in str(dst), code)
    exit_code, _, err = run(tmp_path, capsys)
    out = tmp_path / "out"
    assert exit_code == 1
    assert one_line(err) == (f"papwc run: error: cannot write "
                             f"'{out / 'trace_second_it1.csv'}': {reason}")
    names = sorted(p.name for p in out.iterdir())
    assert names == ["INCOMPLETE", "pulses.csv", "summary.csv", "trace_first_it1.csv",
                     "trace_first_it2.csv"]


def test_a_controller_written_in_part_is_said_to_be(tmp_path: Path, capsys, monkeypatch) -> None:
    """pulses.csv cannot be written after the first controller's traces and summary rows
    were: the line and INCOMPLETE say that controller is there in part, not whole."""
    fail_writes(monkeypatch, lambda dst: Path(dst).name == "pulses.csv", errno.ENOSPC)
    exit_code, _, err = run(tmp_path, capsys)
    out = tmp_path / "out"
    assert exit_code == 1
    assert one_line(err) == (f"papwc run: error: cannot write '{out / 'pulses.csv'}': "
                             "No space left on device")
    assert "no finished controller (first in part); missing: first, second" in err
    assert sorted(p.name for p in out.iterdir()) == [
        "INCOMPLETE", "summary.csv", "trace_first_it1.csv", "trace_first_it2.csv"]
    marker = (out / "INCOMPLETE").read_text()
    assert ("- controller first in part: trace_first_it1.csv, trace_first_it2.csv, its rows "
            "of summary.csv") in marker
    assert "- controller first (the rest of its files)" in marker


def test_a_file_in_the_way_of_the_output_folder_is_one_line(tmp_path: Path, capsys) -> None:
    (tmp_path / "out").write_text("not a folder")
    code, _, err = run(tmp_path, capsys)
    assert code == 1
    assert one_line(err) == (f"papwc run: error: cannot create folder '{tmp_path / 'out'}': "
                             "a file is in the way")


def test_a_folder_where_summary_csv_should_be_is_one_line(tmp_path: Path, capsys) -> None:
    (tmp_path / "out" / "summary.csv").mkdir(parents=True)
    code, _, err = run(tmp_path, capsys)
    assert code == 1
    assert one_line(err).endswith("summary.csv': a folder is in the way")
    assert (tmp_path / "out" / "trace_first_it2.csv").is_file()
    assert (tmp_path / "out" / "INCOMPLETE").is_file()


@pytest.mark.slow
def test_a_new_run_removes_its_own_stale_files_and_nothing_else(tmp_path: Path, capsys) -> None:
    assert run(tmp_path, capsys, iterations=3)[0] == 0
    out = tmp_path / "out"
    (out / "notes.txt").write_text("mine")
    (out / "trace_gone_it7.csv").write_text("an old controller")
    assert run(tmp_path, capsys, iterations=2)[0] == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "error.png", "estimates.png", "force.png", "notes.txt", "pulses.csv", "summary.csv",
        "trace_first_it1.csv", "trace_first_it2.csv", "trace_second_it1.csv",
        "trace_second_it2.csv"]


@pytest.mark.slow
def test_pulses_csv_lists_every_pulse_of_every_iteration_with_its_ratio(
        tmp_path: Path, capsys) -> None:
    """One row per pulse: as many per controller and iteration as summary.csv counts."""
    import csv
    from collections import Counter

    assert run(tmp_path, capsys)[0] == 0
    out = tmp_path / "out"
    with open(out / "summary.csv", newline="") as f:
        counts = {(r["controller"], r["iteration"]): int(r["pulses"]) for r in csv.DictReader(f)}
    with open(out / "pulses.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == papwc.results.folder.PULSE_COLUMNS
    listed = Counter((r["controller"], r["iteration"]) for r in rows)
    assert sum(counts.values()) > 0
    assert {k: listed.get(k, 0) for k in counts} == counts
    for r in rows:
        assert float(r["ratio"]) == pytest.approx(abs(float(r["d_m"])) / float(r["bound_m"]))
        assert int(r["samples"]) >= 1


class BrokenStdout:
    """A standard output whose reader has gone."""

    def write(self, text: str) -> int:
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")

    def flush(self) -> None:
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")


@pytest.mark.slow
def test_a_closed_stdout_is_one_line_and_the_results_stay(tmp_path: Path, capsys,
                                                          monkeypatch) -> None:
    monkeypatch.setattr(sys, "stdout", BrokenStdout())
    code = main(["run", str(scenario_file(tmp_path)), "--plant", "physics", "--out",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 1
    assert one_line(err) == "papwc run: error: cannot write to standard output: Broken pipe"
    assert (tmp_path / "out" / "summary.csv").is_file()


@pytest.mark.slow
def test_a_full_stdout_is_one_line_not_a_traceback(tmp_path: Path) -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    papwc = Path(sys.executable).with_name("papwc")
    with open("/dev/full", "w") as full:
        done = subprocess.run([str(papwc), "run", str(scenario_file(tmp_path)), "--plant",
                               "physics", "--out", str(tmp_path / "out")], stdout=full,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    assert done.returncode == 1
    assert done.stderr.strip() == ("papwc run: error: cannot write to standard output: "
                                   "No space left on device")
    assert (tmp_path / "out" / "summary.csv").is_file()


@pytest.mark.parametrize("make, words", [
    (lambda p: p.mkdir(), "is a folder, not a file"),
    (lambda p: os.mkfifo(p), "is not a regular file (a FIFO, device or socket)"),
    (lambda p: p.write_bytes(b"name = 'x'\n\x00\x01\x02"), "a binary file (it holds NUL"),
    (lambda p: p.write_bytes(b"name = 'x'\n# caf\xe9\n"), "not UTF-8 text: byte 0xe9 at "
                                                         "line 2"),
    (lambda p: p.write_bytes(b"# " + b"x" * (17 * 1024 * 1024)), "larger than 16 MB"),
    (lambda p: None, "no such scenario file"),
])
def test_input_files_that_are_not_toml_text_are_refused_by_name(
        tmp_path: Path, capsys, make, words) -> None:
    path = tmp_path / "in.toml"
    make(path)
    code = main(["run", str(path), "--plant", "physics", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert one_line(err).startswith(f"papwc run: error: {path}: {words}"), err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_f_p_max_at_or_below_f_s_is_warned_once_and_recorded(tmp_path: Path, capsys) -> None:
    text = SCENARIO.replace('label = "first"\n', 'label = "first"\nf_p_max = 120.0\n')
    main(["run", str(scenario_file(tmp_path, text=text)), "--plant", "physics", "--out",
          str(tmp_path / "out")])
    err = capsys.readouterr().err
    warning = ("f_p_max = 120.0 N <= f_s = 130.0 N: no force of this controller breaks the "
               "mass away from rest")
    assert err.count(warning) == 1 and f"papwc run: warning: {tmp_path / 's.toml'}: first: " \
        f"{warning}" in err
    rows = (tmp_path / "out" / "summary.csv").read_text().splitlines()[1:]
    assert all(r.endswith(f",ok,{warning}") for r in rows if r.startswith("first,"))
    assert all(r.endswith(",ok,") for r in rows if r.startswith("second,"))


def test_a_run_beyond_the_step_limit_is_refused_before_anything(tmp_path: Path, capsys) -> None:
    code, _, err = run(tmp_path, capsys, "--max-steps", "150", iterations=2)
    assert code == 2
    assert "2 controller(s) x 2 iteration(s) x 50 steps" in err and "--max-steps 200" in err
    assert not (tmp_path / "out").exists()


def test_a_scheduler_that_is_not_an_address_is_a_named_error(tmp_path: Path, capsys) -> None:
    code = main(["battery", str(scenario_file(tmp_path)), "--scheduler", "notaurl"])
    assert code == 2
    assert one_line(capsys.readouterr().err) == (
        "papwc battery: error: --scheduler 'notaurl': not a Dask scheduler address; write "
        "tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786)")


def test_ctrl_c_is_raised_between_two_steps_not_inside_the_plant(monkeypatch) -> None:
    """A KeyboardInterrupt inside a pythonfmu FMU's code would become fmi2Fatal."""
    import signal

    from papwc.master import PhysicsSlave

    inside: list[bool] = []

    class Plant(PhysicsSlave):
        def do_step(self, t: float, h: float) -> None:
            if len(inside) == 3:
                os.kill(os.getpid(), signal.SIGINT)  # arrives "inside the FMU"
            inside.append(True)
            super().do_step(t, h)  # completes: no exception in here
            inside[-1] = False

    monkeypatch.setattr(papwc.scenario_run, "make_plant", lambda *a, **k: Plant())
    from papwc.scenario import parse_scenario

    scenario = parse_scenario({"name": "x", "controller": [{"kind": "papwc"}]}, "x.toml")
    with pytest.raises(KeyboardInterrupt):
        papwc.scenario_run.run_scenario(scenario, "physics")
    assert len(inside) == 4 and not any(inside)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_worker_count_beyond_the_cores_is_a_named_error(tmp_path: Path, capsys) -> None:
    code = main(["battery", str(scenario_file(tmp_path)), "--workers", "100000"])
    assert code == 2
    assert "papwc battery: error: --workers 100000: must be from 1 to" in capsys.readouterr().err


def test_max_runs_is_checked_from_the_command_line(tmp_path: Path, capsys) -> None:
    path = tmp_path / "b.toml"
    path.write_text(SCENARIO.format(iterations=1) + '[monte_carlo]\nn = 50\n'
                    '"plant.m" = { dist = "uniform", rel = 0.1 }\n')
    code = main(["battery", str(path), "--max-runs", "20", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "= 50 runs, over the limit of 20 runs; pass --max-runs 50" in err
    assert not (tmp_path / "out").exists()  # refused before the FMU is built
