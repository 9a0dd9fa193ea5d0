"""Running batteries: failing runs, determinism over workers, an FMU that fails, the journal,
kill and resume. Battery files themselves are tested in tests/unit/test_battery_files.py."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from harness import PAPWC_PAPER, PWC_PAPER, TABLE_1, scenario_toml

from papwc.battery import (
    BatteryError,
    load_battery,
    read_journal,
    run_battery,
)
from papwc.cli import main

#: Name of the journal in the output folder (see the epilog of papwc battery).
JOURNAL = "journal.jsonl"

#: A small battery: 2 sweep points (the second makes f_s < f_c: an invalid plant)
#: times 3 draws, 2 controllers, 2 short iterations.
SMALL = scenario_toml(
    "small", plant=TABLE_1, maneuver={"x_ref": 0.01, "T": 0.01, "duration": 0.6, "iterations": 2},
    controllers=[{**PWC_PAPER, "F_inv0": 1e-5}, {**PAPWC_PAPER, "tolerance": 2e-5}],
    tables={"sweep": {"plant.f_s": [130.0, 90.0]},
            "monte_carlo": {"n": 3, "seed": 7, "plant.m": {"dist": "uniform", "rel": 0.3},
                            "controller.f_c_est": {"dist": "uniform", "low": 0.8, "high": 1.2,
                                                   "of": "plant.f_c"}}})

def resume_battery(n: int) -> str:
    """A battery whose runs are all valid, for kill and resume (n draws)."""
    return scenario_toml(
        "resume", maneuver={"x_ref": 0.01, "duration": 0.5, "iterations": 2},
        controllers=[PAPWC_PAPER],
        tables={"monte_carlo": {
            "n": n, "seed": 3, "plant.m": {"dist": "uniform", "rel": 0.3},
            "plant.f_c": {"dist": "normal", "rel_std": 0.1},
            "plant.f_s": {"dist": "uniform", "low": 1.0, "high": 1.6, "of": "plant.f_c"}}})


def write(tmp_path: Path, text: str, name: str = "battery.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


BASE = 'name = "b"\n[[controller]]\nkind = "papwc"\n'


def test_battery_file_errors_stop_the_command_before_any_run(tmp_path, capsys):
    path = write(tmp_path, BASE + '[sweep]\n"plant.mass" = [1.0]\n', "bad.toml")
    assert main(["battery", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "plant.mass" in err
    assert not (tmp_path / "out").exists()



# --- running ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_failing_runs_are_recorded_and_results_do_not_depend_on_workers(
    tmp_path, friction_plant_fmu, capsys
):
    path = write(tmp_path, SMALL)
    outs = {}
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        code = main(["battery", str(path), "--out", str(out), "--workers", str(workers),
                     "--fmu", str(friction_plant_fmu), "--quiet"])
        assert code == 1  # the f_s = 90 N grid point is an invalid plant
        outs[workers] = out
    err = capsys.readouterr().err
    assert "s1-d000" in err and "f_s" in err
    text = (outs[1] / "results.csv").read_text()
    assert text == (outs[2] / "results.csv").read_text()
    assert (outs[1] / "runs.csv").read_text() == (outs[2] / "runs.csv").read_text()

    rows = list(csv.DictReader(text.splitlines()))
    good = [r for r in rows if r["run_id"].startswith("s0")]
    bad = [r for r in rows if r["run_id"].startswith("s1")]
    assert len(good) == 3 * 2 * 2 and all(r["status"] == "ok" for r in good)
    assert len(bad) == 3 * 2 and all(r["status"] == "error" for r in bad)
    assert all("f_s" in r["message"] for r in bad)
    assert {r["controller"] for r in rows} == {"pwc_tpmax_0.03", "papwc_tpmax_0.03"}
    assert [r["run_id"] for r in rows] == sorted(r["run_id"] for r in rows)
    for column in ("plant.f_s", "plant.m", "controller.f_c_est", "final_error_m", "pulses",
                   "settle_time_s", "limit_cycle", "b_hat", "f_c_hat", "success"):
        assert column in rows[0]
    summary = (outs[1] / "summary.md").read_text()
    assert "Success" in summary and "papwc_tpmax_0.03" in summary
    assert (outs[1] / "final_error_small.png").stat().st_size > 1000


@pytest.mark.slow
def test_an_fmu_that_fails_gives_error_runs_not_a_crash(tmp_path, trivial_fmu):
    path = write(tmp_path, resume_battery(2))
    outcome = run_battery([load_battery(path)], tmp_path / "out", trivial_fmu, workers=1,
                          progress=False)
    assert outcome.runs == 2 and len(outcome.failed) == 2
    assert all("FmuError" in msg or "variable" in msg for _, _, msg in outcome.failed)
    assert "error" in (tmp_path / "out" / "results.csv").read_text()


@pytest.mark.slow
def test_journal_refuses_a_different_battery_without_overwrite(tmp_path, friction_plant_fmu):
    path = write(tmp_path, resume_battery(2))
    out = tmp_path / "out"
    run_battery([load_battery(path)], out, friction_plant_fmu, workers=1, progress=False)
    with pytest.raises(BatteryError, match="--resume"):
        run_battery([load_battery(path)], out, friction_plant_fmu, workers=1, progress=False)
    again = run_battery([load_battery(path)], out, friction_plant_fmu, workers=1,
                        resume=True, progress=False)
    assert again.computed == 0
    other = write(tmp_path, resume_battery(3), "other.toml")
    with pytest.raises(BatteryError, match="cannot resume"):
        run_battery([load_battery(other)], out, friction_plant_fmu, workers=1, resume=True,
                    progress=False)


@pytest.mark.slow
def test_killed_battery_resumes_without_recomputing_or_losing_runs(
    tmp_path, friction_plant_fmu
):
    n = 24
    path = write(tmp_path, resume_battery(n))
    reference = tmp_path / "reference"
    run_battery([load_battery(path)], reference, friction_plant_fmu, workers=2, progress=False)

    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "papwc.cli", "battery", str(path), "--out", str(out),
           "--workers", "1", "--fmu", str(friction_plant_fmu), "--quiet"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    journal = out / JOURNAL
    try:
        deadline = time.monotonic() + 60
        finished = 0
        while finished < 4:
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "no run finished within 60 s"
            time.sleep(0.02)
            if journal.exists():
                finished = len(read_journal(journal)[1])
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stderr.close()
    before = read_journal(journal)[1]
    assert 4 <= len(before) < n, "the battery finished before it was killed"
    assert not (out / "results.csv").exists()

    outcome = run_battery([load_battery(path)], out, friction_plant_fmu, workers=2,
                          resume=True, progress=False)
    after = read_journal(journal)[1]
    assert outcome.computed == n - len(before)
    assert len(after) == n and len({r["run_id"] for r in after}) == n
    assert after[: len(before)] == before
    assert (out / "results.csv").read_text() == (reference / "results.csv").read_text()
    assert (out / "runs.csv").read_text() == (reference / "runs.csv").read_text()
