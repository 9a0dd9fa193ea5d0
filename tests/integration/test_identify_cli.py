"""``papwc identify`` on the command line: --design, a log, --fmu with --start-values on the
FrictionPlant.fmu that ``papwc build`` makes; bad logs in one line; nothing written outside
--out; Ctrl-C leaves what was written complete or absent.

Issue 44: logs that lie (a value beyond the model layer's range, a row of too many fields,
a column named twice, time in milliseconds) and --fmu options that cannot work (an input
as the position, start values the FMU refuses) are refused before anything is written;
the plant's own column name x_meas is read by default; --duration's maximum gives a log
that is read back whole; the steps of a fit are shown while they run."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from papwc.cli import main
from papwc.identify.excitation import apply_to_plant, design
from papwc.identify.fit_report import write_log
from papwc.identify.log_file import MAX_LOG_ROWS, read_log
from papwc.scenario import load_scenario

TRUTH = {"m": 120.0, "f_c": 80.0, "f_s": 110.0, "c": 500.0}


def _identified(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "identified.csv", newline="") as f:
        return {row["parameter"]: row for row in csv.DictReader(f)}


def test_design_writes_the_excitation_and_nothing_else(tmp_path, empty_cwd, capsys):
    out = tmp_path / "id"
    assert main(["identify", "--design", "--out", str(out), "--f-p-max", "250",
                 "--travel", "0.03", "--duration", "45"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["excitation.csv"]
    assert list(empty_cwd.iterdir()) == []
    with open(out / "excitation.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4500 and set(rows[0]) == {"time", "u"}
    assert max(abs(float(r["u"])) for r in rows) <= 250.0
    assert "wrote" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("encoder, tolerance", [
    ("", 0.005),
    (",x_resolution=1e-7,noise_std=2e-7,seed=4", 0.03),
], ids=["ideal", "noisy"])
def test_fmu_with_start_values_is_recovered(tmp_path, empty_cwd, friction_plant_fmu, capsys,
                                            encoder, tolerance):
    out = tmp_path / "id"
    start = ",".join(f"{k}={v}" for k, v in TRUTH.items()) + encoder
    assert main(["identify", "--fmu", str(friction_plant_fmu), "--start-values", start,
                 "--out", str(out)]) == 0
    assert list(empty_cwd.iterdir()) == []
    names = {p.name for p in out.iterdir()}
    assert names == {"excitation.csv", "log.csv", "identified.csv", "plant.toml", "report.md",
                     "position.png", "residual.png", "friction.png"}
    rows = _identified(out)
    for name, true in TRUTH.items():
        value = float(rows[name]["estimate"])
        assert abs(value / true - 1.0) < tolerance, (name, value)
        if not encoder:
            assert float(rows[name]["ci_low"]) <= true <= float(rows[name]["ci_high"])
    scenario = load_scenario(out / "plant.toml")
    assert scenario.plant["m"] == pytest.approx(TRUTH["m"], rel=tolerance)
    report = (out / "report.md").read_text()
    assert "## Deviations tried" in report and "Chosen: none" in report
    capsys.readouterr()
    # The identified plant runs as a scenario.
    assert main(["run", str(out / "plant.toml"), "--plant", "physics",
                 "--out", str(tmp_path / "run")]) == 0
    assert (tmp_path / "run" / "summary.csv").is_file()
    capsys.readouterr()


def test_a_log_file_is_identified(tmp_path, empty_cwd, capsys):
    u = design(0.01, 300.0, 0.05, 40.0)
    log = apply_to_plant(u, 0.01, TRUTH)
    path = tmp_path / "machine.csv"
    write_log(path, log)
    text = path.read_text().replace("time,u,x", "t,F,pos", 1)
    path.write_text(text)
    out = tmp_path / "id"
    assert main(["identify", str(path), "--out", str(out), "--deviations", "none",
                 "--time-column", "t", "--force-column", "F", "--position-column", "pos"]) == 0
    assert list(empty_cwd.iterdir()) == []
    rows = _identified(out)
    assert abs(float(rows["c"]["estimate"]) / TRUTH["c"] - 1.0) < 0.005
    assert not (out / "INCOMPLETE").exists()
    # A second run into the folder replaces the first's files, and leaves others alone.
    (out / "mine.txt").write_text("kept")
    assert main(["identify", str(path), "--out", str(out), "--deviations", "none",
                 "--time-column", "t", "--force-column", "F", "--position-column", "pos"]) == 0
    assert (out / "mine.txt").read_text() == "kept"
    capsys.readouterr()


@pytest.mark.parametrize("change, message", [
    (lambda lines: lines.__setitem__(5, "0.04,0.0,x0"), "row 5 (line 6), column 'x': 'x0' is "
                                                        "not a number"),
    (lambda lines: lines.__setitem__(3, "0.02,nan,0.0"), "row 3 (line 4), column 'u': 'nan' "
                                                         "is NaN"),
    (lambda lines: lines.__setitem__(7, "0.05,0.0,0.0"), "row 7 (line 8), column 'time': time "
                                                         "0.05 s is not after"),
])
def test_a_bad_log_is_one_line_and_writes_nothing(tmp_path, empty_cwd, capsys, change, message):
    lines = ["time,u,x"] + [f"{k * 0.01!r},0.0,0.0" for k in range(30)]
    change(lines)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "id"
    assert main(["identify", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not out.exists() and list(empty_cwd.iterdir()) == []


def test_options_that_do_not_go_together_are_refused(tmp_path, capsys, friction_plant_fmu):
    out = tmp_path / "id"
    assert main(["identify", "--design", "--fmu", "p.fmu", "--out", str(out)]) == 2
    assert "give exactly one of LOG.csv, --design and --fmu" in capsys.readouterr().err
    assert main(["identify", "--design", "--out", str(out), "--deviations", "lugre"]) == 2
    assert ("unknown deviation 'lugre'; allowed: stribeck, lag, ripple or none"
            in capsys.readouterr().err)
    assert main(["identify", "--design", "--out", str(out), "--expect", "f_s=50"]) == 2
    assert "--expect: f_s = 50.0 N: must be >= f_c" in capsys.readouterr().err
    assert main(["identify", "--fmu", str(friction_plant_fmu), "--start-values", "mass=3",
                 "--out", str(out)]) == 2
    assert "--start-values: the FMU has no variable 'mass'" in capsys.readouterr().err
    assert main(["identify", "--fmu", str(friction_plant_fmu), "--position-variable", "y",
                 "--out", str(out)]) == 2
    assert "has no Real variable 'y'" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_ctrl_c_leaves_every_file_complete_or_absent(tmp_path, friction_plant_fmu):
    """A real SIGINT while the fit runs: exit 130, INCOMPLETE says what is missing, no
    partial file; every file there reads whole."""
    u = design(0.01, 300.0, 0.05, 60.0)
    log = apply_to_plant(u, 0.01, {"v_s": 1e-3, "x_resolution": 1e-7, "noise_std": 2e-7})
    path = tmp_path / "machine.csv"
    write_log(path, log)
    out = tmp_path / "id"
    papwc = str(Path(sys.executable).with_name("papwc"))
    proc = subprocess.Popen([papwc, "identify", str(path), "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=os.environ.copy(),
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while not (out / "INCOMPLETE").exists() and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.05)
    time.sleep(2.0)  # inside the fit
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err
    names = {p.name for p in out.iterdir()}
    assert "INCOMPLETE" in names
    assert not [n for n in names if ".tmp" in n]
    incomplete = (out / "INCOMPLETE").read_text()
    assert "interrupted" in incomplete and "- report.md" in incomplete
    if "identified.csv" in names:
        assert len(_identified(out)) >= 4


# --- issue 44 -----------------------------------------------------------------------------------


def _machine_log(path: Path, seconds: float = 40.0) -> list[str]:
    """A log of the Table-1-like plant TRUTH under the designed excitation; its lines."""
    u = design(0.01, 300.0, 0.05, seconds)
    write_log(path, apply_to_plant(u, 0.01, TRUTH))
    return path.read_text().splitlines()


def _cells(line: str, **changes: str) -> str:
    cells = dict(zip(("time", "u", "x"), line.split(","), strict=True))
    return ",".join({**cells, **changes}.values())


@pytest.mark.parametrize("change, message", [
    (lambda ls: ls.__setitem__(50, _cells(ls[50], u="1e300")),
     "row 50 (line 51), column 'u': 1e+300 is outside the model layer's range: a force within "
     "-1e+09..1e+09 N (the largest force limit f_p_max of a controller)"),
    (lambda ls: ls.__setitem__(60, _cells(ls[60], x="-2e6")),
     "row 60 (line 61), column 'x': -2000000.0 is outside the model layer's range: a position "
     "of the plant (its x0), -1e+06..1e+06 m"),
    (lambda ls: ls.__setitem__(7, ls[7] + ",1,2"),
     "row 7 (line 8): 5 fields, the header has 3; every row has one value per column"),
    (lambda ls: ls.__setitem__(0, "time,u,x,x"),
     "line 1: column 'x' is named twice (fields 3 and 4); each column needs its own name"),
    (lambda ls: ls.__setitem__(slice(1, None), [
        _cells(line, time=repr(float(line.split(",")[0]) * 1000.0)) for line in ls[1:]]),
     "column 'time': the sample period is 10.0 s, outside the 1e-06..0.1 s of a machine's "
     "log; is the time in milliseconds? (then the period is 0.01 s)"),
], ids=["force", "position", "fields", "named-twice", "milliseconds"])
def test_a_log_that_lies_is_refused_in_one_line(tmp_path, empty_cwd, capsys, change, message):
    """Issue 44: a force of 1e300 N was fitted (f_s = 5e299 N, then plant.toml blamed); a
    row of 5 fields, a header time,u,x,x and time in milliseconds were accepted."""
    path = tmp_path / "machine.csv"
    lines = _machine_log(path)
    change(lines)
    if lines[0] == "time,u,x,x":
        lines[1:] = [line + ",0.0" for line in lines[1:]]
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "id"
    assert main(["identify", str(path), "--out", str(out), "--deviations", "none"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{path}, {message}" in err, err
    assert not out.exists() and list(empty_cwd.iterdir()) == []


def test_the_plants_own_column_name_is_read_by_default(tmp_path, capsys):
    """Issue 44: the default position column was x, while the plant's measured output (and
    --position-variable's default) is x_meas; x still works (test_a_log_file_is_identified)."""
    path = tmp_path / "machine.csv"
    lines = _machine_log(path)
    path.write_text("\n".join(["time,u,x_meas"] + lines[1:]) + "\n")
    out = tmp_path / "id"
    assert main(["identify", str(path), "--out", str(out), "--deviations", "none"]) == 0
    assert abs(float(_identified(out)["m"]["estimate"]) / TRUTH["m"] - 1.0) < 0.005
    capsys.readouterr()


def test_the_longest_duration_gives_a_log_that_is_read_back_whole(tmp_path, capsys):
    """Issue 44: at --duration 1000 (its maximum) the log had 100,001 rows, one more than a
    log could have; the excitation's samples and the log's rows are counted alike now."""
    out = tmp_path / "id"
    assert main(["identify", "--design", "--out", str(out), "--duration", "1000"]) == 0
    with open(out / "excitation.csv", newline="") as f:
        u = [float(row["u"]) for row in csv.DictReader(f)]
    assert len(u) == 100_000
    log = apply_to_plant(u, 0.01, TRUTH)  # what --fmu writes: a sample at each end of a step
    write_log(tmp_path / "log.csv", log)
    assert len(log.t) == MAX_LOG_ROWS == 100_001
    back = read_log(tmp_path / "log.csv")
    assert (back.t == log.t).all() and (back.x == log.x).all()
    assert main(["identify", "--design", "--out", str(out), "--duration", "1000.01"]) == 2
    assert "--duration 1000.01 s: at most 1000 s" in capsys.readouterr().err
    assert main(["identify", "--design", "--out", str(tmp_path / "t"), "--T", "10"]) == 2
    assert "--T 10.0 s: the sample period of a machine's log is 1e-06 to 0.1 s" in (
        capsys.readouterr().err)


@pytest.mark.parametrize("options, message", [
    (["--position-variable", "u"], "--position-variable u: u is an input of the FMU; the "
                                   "position is a Real output (e.g. x_meas)"),
    (["--force-variable", "x_meas"], "--force-variable x_meas: x_meas is an output of the "
                                     "FMU; the force is a Real input (e.g. u)"),
    (["--start-values", "m=-1"], "--start-values: the FMU refused them: "),
    (["--start-values", "x=0.5"], "--start-values: x is an output of the FMU; start values "
                                  "are for its parameters (and inputs)"),
], ids=["position-input", "force-output", "refused-value", "output-start"])
def test_fmu_options_that_cannot_work_are_refused_before_any_work(
        tmp_path, empty_cwd, capsys, friction_plant_fmu, options, message):
    """Issue 44: --position-variable u (an input) was accepted; start values were checked
    only by name, so the excitation was written before the FMU refused them."""
    out = tmp_path / "id"
    assert main(["identify", "--fmu", str(friction_plant_fmu), "--out", str(out),
                 *options]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    if "m=-1" in options:
        assert "parameter m = -1.0 kg: must satisfy 1e-06 <= m <= 1e+09 kg" in err
    assert not out.exists() and list(empty_cwd.iterdir()) == []


def test_the_fit_says_what_it_tries_while_it_runs(tmp_path, capsys, monkeypatch):
    """Issue 44: identify was silent for two minutes while it tried the deviations. Off a
    terminal each step is a line as it starts and another every PLAIN_PROGRESS_S seconds."""
    import papwc.progress

    monkeypatch.setattr(papwc.progress, "PLAIN_PROGRESS_S", 0.05)
    path = tmp_path / "machine.csv"
    _machine_log(path)
    assert main(["identify", str(path), "--out", str(tmp_path / "id"), "--deviations",
                 "stribeck"]) == 0
    err = capsys.readouterr().err.splitlines()
    for name in ("stribeck",):
        start = err.index(next(line for line in err
                               if line.startswith("papwc identify: fitting every deviation "
                                                  f"tried at once: {name}")))
        end = err.index(next(line for line in err
                             if line.startswith(f"papwc identify: tested {name}: ")))
        assert start < end
    assert any(line.endswith("s so far)") for line in err), err
    assert "\r" not in "".join(err)  # no terminal status line off a terminal
