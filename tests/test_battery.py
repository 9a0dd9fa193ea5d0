"""Batteries: file validation, resolved runs, failing runs, determinism, kill and resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from papwc.battery import (
    JOURNAL_NAME,
    BatteryError,
    get_field,
    load_battery,
    parse_battery,
    plan_runs,
    read_journal,
    run_battery,
)
from papwc.cli import main
from papwc.errors import ScenarioError

PROJECT = Path(__file__).resolve().parent.parent

#: A small battery: 2 sweep points (the second makes f_s < f_c: an invalid plant)
#: times 3 draws, 2 controllers, 2 short iterations.
SMALL = """\
name = "small"
[plant]
m = 150.0
f_c = 100.0
f_s = 130.0
c = 700.0
[maneuver]
x_ref = 0.01
T = 0.01
duration = 0.6
iterations = 2
[[controller]]
kind = "pwc"
t_p_max = 0.03
K_c = 0.5
tolerance = 0.0
F_inv0 = 1e-5
[[controller]]
kind = "papwc"
t_p_max = 0.03
K_c = 0.8
tolerance = 2e-5
[sweep]
"plant.f_s" = [130.0, 90.0]
[monte_carlo]
n = 3
seed = 7
"plant.m" = { dist = "uniform", rel = 0.3 }
"controller.f_c_est" = { dist = "uniform", low = 0.8, high = 1.2, of = "plant.f_c" }
"""

#: A battery whose runs are all valid, for kill and resume (n draws).
RESUME = """\
name = "resume"
[maneuver]
x_ref = 0.01
duration = 0.5
iterations = 2
[[controller]]
kind = "papwc"
t_p_max = 0.03
K_c = 0.8
[monte_carlo]
n = {n}
seed = 3
"plant.m" = {{ dist = "uniform", rel = 0.3 }}
"plant.f_c" = {{ dist = "normal", rel_std = 0.1 }}
"plant.f_s" = {{ dist = "uniform", low = 1.0, high = 1.6, of = "plant.f_c" }}
"""


def write(tmp_path: Path, text: str, name: str = "battery.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- battery files ----------------------------------------------------------------------------

BASE = 'name = "b"\n[[controller]]\nkind = "papwc"\n'


@pytest.mark.parametrize(
    ("extra", "field"),
    [
        ('[sweep]\n"plant.mass" = [1.0]\n', "plant.mass"),
        ('[sweep]\n"plant.m" = 150.0\n', "plant.m"),
        ('[sweep]\n"plant.m" = []\n', "plant.m"),
        ('[sweep]\n"controller.2.K_c" = [0.5]\n', "controller.2.K_c"),
        ('[sweep]\n"controller.kind" = ["pwc"]\n', "controller.kind"),
        ('[sweep]\n"speed" = [1.0]\n', "speed"),
        ('[monte_carlo]\nseed = 1\n"plant.m" = { dist = "uniform", rel = 0.1 }\n', "'n'"),
        ('[monte_carlo]\nn = 2\nseed = -1\n"plant.m" = { dist = "uniform", rel = 0.1 }\n',
         "'seed'"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "gauss", std = 1.0 }\n', "plant.m"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "uniform", rel = 0.1, abs = 2.0 }\n',
         "plant.m"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "uniform", low = 2.0, high = 1.0 }\n',
         "plant.m"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "normal", std = -1.0 }\n', "plant.m"),
        ('[monte_carlo]\nn = 2\n"maneuver.iterations" = { dist = "normal", std = 1.0 }\n',
         "maneuver.iterations"),
        ('[monte_carlo]\nn = 2\n"plant.f_s" = { dist = "uniform", rel = 0.1, of = "plant.f_c" }\n',
         "plant.f_s"),
        ('[monte_carlo]\nn = 2\n"plant.f_s" = { dist = "uniform", low = 1.0, high = 2.0, '
         'of = "controller.m_est" }\n', "plant.f_s"),
        ('[monte_carlo]\nn = 2\n"plant.m" = 3.0\n', "plant.m"),
        ('[monte_carlo]\nn = 2\n', "[monte_carlo]"),
        ('[battery]\nsuccess_tolerance = -1.0\n', "success_tolerance"),
        ('[battery]\ntolerance = 1.0\n', "tolerance"),
        ('[plant]\nf_s = 50.0\n', "f_s"),
    ],
)
def test_battery_file_errors_name_the_file_and_the_field(tmp_path, extra, field):
    path = write(tmp_path, BASE + extra, "bad_battery.toml")
    with pytest.raises(ScenarioError) as info:
        load_battery(path)
    message = str(info.value)
    assert str(path) in message
    assert field in message


def test_battery_file_errors_stop_the_command_before_any_run(tmp_path, capsys):
    path = write(tmp_path, BASE + '[sweep]\n"plant.mass" = [1.0]\n', "bad.toml")
    assert main(["battery", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "plant.mass" in err
    assert not (tmp_path / "out").exists()


def test_runs_are_resolved_up_front_with_stable_ids_and_draws():
    data = {
        "name": "g",
        "plant": {"m": 150.0, "f_c": 100.0, "f_s": 130.0},
        "controller": [{"kind": "pwc", "m_est": 150.0}, {"kind": "papwc", "m_est": 140.0}],
        "sweep": {"plant.f_c": [80.0, 100.0], "controller.2.K_c": [0.5, 0.8, 1.2]},
        "monte_carlo": {
            "n": 4,
            "seed": 11,
            "plant.m": {"dist": "uniform", "low": 100.0, "high": 200.0},
            "controller.m_est": {"dist": "normal", "rel_std": 0.1},
            "plant.f_s": {"dist": "uniform", "low": 1.0, "high": 1.5, "of": "plant.f_c"},
        },
    }
    battery = parse_battery(data, "g.toml")
    runs = plan_runs([battery])
    assert len(runs) == 2 * 3 * 4
    assert [r.run_id for r in runs[:5]] == ["s0-d000", "s0-d001", "s0-d002", "s0-d003",
                                            "s1-d000"]
    again = plan_runs([parse_battery(data, "g.toml")])
    assert [(r.run_id, r.run_hash, r.data) for r in runs] == [
        (r.run_id, r.run_hash, r.data) for r in again]
    assert len({r.run_hash for r in runs}) == len(runs)
    for r in runs:
        m = get_field(r.data, "plant.m")
        f_c, f_s = get_field(r.data, "plant.f_c"), get_field(r.data, "plant.f_s")
        assert 100.0 <= m <= 200.0
        assert f_c <= f_s <= 1.5 * f_c
        assert f_c == [80.0, 100.0][r.order[1] // 3]
        assert get_field(r.data, "controller.2.K_c") == [0.5, 0.8, 1.2][r.order[1] % 3]
        # one random number per draw for every table: the relative offsets agree
        e1 = get_field(r.data, "controller.m_est", 0) / 150.0
        e2 = get_field(r.data, "controller.m_est", 1) / 140.0
        assert e1 == pytest.approx(e2, rel=1e-12)
        assert not r.error
    # common random numbers: draw d has the same m at every grid point
    by_draw = {}
    for r in runs:
        by_draw.setdefault(r.order[2], set()).add(get_field(r.data, "plant.m"))
    assert all(len(v) == 1 for v in by_draw.values())


def test_read_journal_drops_a_torn_last_line(tmp_path):
    path = tmp_path / "journal.jsonl"
    lines = [json.dumps({"type": "header", "fingerprint": "x"}),
             json.dumps({"type": "run", "battery": "b", "run_id": "d000"})]
    path.write_text("\n".join(lines) + "\n" + '{"type": "run", "batt')
    header, records, good = read_journal(path)
    assert header["fingerprint"] == "x"
    assert [r["run_id"] for r in records] == ["d000"]
    assert good == len("\n".join(lines)) + 1
    path.write_text(lines[0] + "\n{broken\n" + lines[1] + "\n")
    with pytest.raises(BatteryError, match="line 2"):
        read_journal(path)


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

    import csv

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
    path = write(tmp_path, RESUME.format(n=2))
    outcome = run_battery([load_battery(path)], tmp_path / "out", trivial_fmu, workers=1,
                          progress=False)
    assert outcome.runs == 2 and len(outcome.failed) == 2
    assert all("FmuError" in msg or "variable" in msg for _, _, msg in outcome.failed)
    assert "error" in (tmp_path / "out" / "results.csv").read_text()


@pytest.mark.slow
def test_journal_refuses_a_different_battery_without_overwrite(tmp_path, friction_plant_fmu):
    path = write(tmp_path, RESUME.format(n=2))
    out = tmp_path / "out"
    run_battery([load_battery(path)], out, friction_plant_fmu, workers=1, progress=False)
    with pytest.raises(BatteryError, match="--resume"):
        run_battery([load_battery(path)], out, friction_plant_fmu, workers=1, progress=False)
    again = run_battery([load_battery(path)], out, friction_plant_fmu, workers=1,
                        resume=True, progress=False)
    assert again.computed == 0
    other = write(tmp_path, RESUME.format(n=3), "other.toml")
    with pytest.raises(BatteryError, match="cannot resume"):
        run_battery([load_battery(other)], out, friction_plant_fmu, workers=1, resume=True,
                    progress=False)


@pytest.mark.slow
def test_killed_battery_resumes_without_recomputing_or_losing_runs(
    tmp_path, friction_plant_fmu
):
    n = 24
    path = write(tmp_path, RESUME.format(n=n))
    reference = tmp_path / "reference"
    run_battery([load_battery(path)], reference, friction_plant_fmu, workers=2, progress=False)

    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "papwc.cli", "battery", str(path), "--out", str(out),
           "--workers", "1", "--fmu", str(friction_plant_fmu), "--quiet"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    journal = out / JOURNAL_NAME
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


def test_robustness_battery_file_is_valid():
    battery = load_battery(PROJECT / "scenarios" / "robustness.toml")
    runs = plan_runs([battery])
    assert len(runs) == 200 and not any(r.error for r in runs)
    for r in runs:
        plant = r.data["plant"]
        assert plant["f_s"] >= plant["f_c"]
        assert 0.7 * 150.0 <= plant["m"] <= 1.3 * 150.0
        for table in r.data["controller"]:
            assert 0.8 <= table["m_est"] / plant["m"] <= 1.2
            assert 0.8 <= table["f_c_est"] / plant["f_c"] <= 1.2
