"""``papwc identify`` on the command line: --design, a log, --fmu with --start-values on the
FrictionPlant.fmu that ``papwc build`` makes; bad logs in one line; nothing written outside
--out; Ctrl-C leaves what was written complete or absent."""

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
    assert main(["identify", "--design", "--out", str(out), "--deviations", "ripple"]) == 2
    assert "unknown deviation 'ripple'" in capsys.readouterr().err
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
