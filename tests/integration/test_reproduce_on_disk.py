"""``papwc reproduce`` and ``papwc run`` on the FMU: results on disk as they come (issue 13).

Group 1: every controller's traces and summary rows are written as it
finishes; Ctrl-C (a real SIGINT) or an error keeps what finished, says so and
leaves the folder marked ``INCOMPLETE``; a completed run leaves no marker.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import papwc.scenario_run
from papwc.cli import main

pytestmark = pytest.mark.slow


def test_reproduce_interrupted_keeps_the_finished_controllers(
        tmp_path: Path, friction_plant_fmu: Path, capsys, monkeypatch) -> None:
    real = papwc.scenario_run.run_controller
    seen: list[str] = []

    def third_interrupted(slave, settings, maneuver, label="", observers=(), library=None):
        seen.append(label)
        if len(seen) == 3:
            raise KeyboardInterrupt
        return real(slave, settings, maneuver, label, observers, library)

    monkeypatch.setattr(papwc.scenario_run, "run_controller", third_interrupted)
    out = tmp_path / "repro"
    (out).mkdir()
    (out / "fig3.png").write_bytes(b"an old figure")
    code = main(["reproduce", "--out", str(out), "--fmu", str(friction_plant_fmu)])
    err = capsys.readouterr().err
    assert code == 130 and "Traceback" not in err
    assert f"kept in {out / 'runs'}: the results of {seen[0]}, {seen[1]}; missing:" in err
    runs = sorted(p.name for p in (out / "runs").iterdir())
    assert runs == ["INCOMPLETE", "summary.csv"] + sorted(
        f"trace_{label}_it{i}.csv" for label in seen[:2] for i in range(1, 11))
    assert sorted(p.name for p in out.iterdir()) == ["INCOMPLETE", "runs"]
    assert "figures, paper_numbers.csv and report.md are missing" in (
        out / "INCOMPLETE").read_text()


def test_reproduce_complete_leaves_no_marker(tmp_path: Path, friction_plant_fmu: Path) -> None:
    out = tmp_path / "repro"
    assert main(["reproduce", "--out", str(out), "--fmu", str(friction_plant_fmu)]) == 0
    assert not (out / "INCOMPLETE").exists() and not (out / "runs" / "INCOMPLETE").exists()
    assert (out / "report.md").is_file() and (out / "fig9.png").is_file()


SCENARIO = """\
name = "sigint"
[maneuver]
x_ref = 0.01
T = 0.01
duration = 2.0
iterations = {iterations}
[[controller]]
kind = "papwc"
label = "quick"
t_p_max = 0.03
K_c = 0.8
[[controller]]
kind = "exact"
label = "slow"
"""


def test_papwc_run_stopped_by_sigint_keeps_what_finished(tmp_path: Path,
                                                          friction_plant_fmu: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.format(iterations=400))
    out = tmp_path / "out"
    papwc = str(Path(sys.executable).with_name("papwc"))
    proc = subprocess.Popen(
        [papwc, "run", str(path), "--out", str(out), "--fmu", str(friction_plant_fmu)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 300
    while not (out / "summary.csv").exists() and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.05)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and time.monotonic() - sent < 5.0, err
    assert "Traceback" not in err and "Fatal" not in err
    assert "kept in" in err and "the results of quick; missing: slow" in err
    assert len(list(out.glob("trace_quick_it*.csv"))) == 400
    incomplete = (out / "INCOMPLETE").read_text()
    assert "controller slow" in incomplete
    # Issue 44: the traces slow computed before the stop are kept (there were none before),
    # each named in INCOMPLETE, the last one cut short; slow has no summary rows.
    slow = sorted(p.name for p in out.glob("trace_slow_*"))
    if slow:  # (none if the stop came before slow's first step)
        line = next(line for line in incomplete.splitlines()
                    if line.startswith("- controller slow in part: "))
        assert all(name in line for name in slow) and "(cut short at t = " in line, line
        assert "; the traces of slow until the stop are kept" in err
    assert "slow," not in (out / "summary.csv").read_text()
