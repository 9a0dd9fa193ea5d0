"""Batteries: time limits, dead workers, Ctrl-C, journal corruption, rebuilt FMUs (issue 13).

Groups 3 (per-run time limit, worker replaced, Ctrl-C within seconds with a
resume line), 4 (a folder where results.csv should be), 8 (the journal
survives corruption and rebuilds; kill/resume byte-identical) and 9 (warnings
recorded in results.csv).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from harness import PAPWC_PAPER, scenario_toml

import papwc.battery.engines as engines
from papwc.battery import load_battery, run_battery
from papwc.cli import main

pytestmark = pytest.mark.slow

PROJECT = Path(__file__).resolve().parents[2]


def battery_file(folder: Path, extra: str, name: str = "lim") -> Path:
    path = folder / f"{name}.toml"
    text = scenario_toml(name, maneuver={"x_ref": 0.01, "T": 0.01, "duration": 1.0,
                                         "iterations": 2},
                         controllers=[PAPWC_PAPER], tail=textwrap.dedent(extra) + "\n")
    path.write_text(text, encoding="utf-8")
    return path


def rows(out: Path) -> list[dict]:
    import csv

    with open(out / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def faulty_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """FrictionPlant.fmu whose step hangs for m = 123 kg and kills its process for m = 124 kg.

    Built in a new process (a pythonfmu FMU loaded here would shadow the builder).
    """
    folder = tmp_path_factory.mktemp("faulty")
    source = (PROJECT / "fmu_src" / "FrictionPlant" / "FrictionPlant.py").read_text()
    marker = '        u = self.u\n        if not _isfinite(u):'
    assert marker in source
    script = folder / "src" / "FrictionPlant.py"
    script.parent.mkdir()
    script.write_text(source.replace(marker, (
        "        if self.m == 123.0:\n            import time\n            time.sleep(3600)\n"
        "        if self.m == 124.0:\n            import os\n            os._exit(3)\n" + marker)))
    code = textwrap.dedent(f"""
        from pathlib import Path
        from papwc.fmubuild.fmus import PACKAGE_DIR
        from papwc.fmubuild.pythonfmu_build import STATE_OPTIONS, FmuSource, build_pythonfmu
        from papwc.model.plant import PLANT_VARIABLES
        build_pythonfmu(FmuSource(Path({str(script)!r}), PLANT_VARIABLES,
                                  package="papwc_friction_plant",
                                  bundle={{n: PACKAGE_DIR / n for n in ("model", "fmi")}},
                                  options=STATE_OPTIONS),
                        Path({str(folder / 'out')!r}))
    """)
    subprocess.run([sys.executable, "-c", code], check=True, timeout=600)
    return folder / "out" / "FrictionPlant.fmu"


def test_a_run_past_its_time_limit_is_recorded_and_computed_again_on_resume(
        tmp_path: Path, friction_plant_fmu: Path) -> None:
    # (at T = 2 us a run is 1e6 steps: seconds even with the native plant, which takes
    # T = 1e-5 s in under one)
    timed = battery_file(tmp_path, """
        [sweep]
        "maneuver.T" = [0.01, 2e-6]
        [battery]
        run_timeout = 1
        """)
    out = tmp_path / "out"
    outcome = run_battery([load_battery(timed)], out, friction_plant_fmu, workers=2,
                          progress=False)
    assert [(b, r) for b, r, _ in outcome.failed] == [("lim", "s1")]
    message = outcome.failed[0][2]
    assert message.startswith("timed out: the run took longer than 1 s"), message
    assert [r["status"] for r in rows(out)][-1] == "error"
    timed.write_text(timed.read_text().replace("run_timeout = 1", "run_timeout = 600"))
    again = run_battery([load_battery(timed)], out, friction_plant_fmu, workers=2,
                        resume=True, progress=False)
    assert again.computed == 1 and not again.failed


def test_a_worker_stuck_in_a_call_is_killed_replaced_and_its_run_recorded(
        tmp_path: Path, faulty_fmu: Path, monkeypatch) -> None:
    monkeypatch.setattr(engines, "KILL_GRACE", 0.5)
    path = battery_file(tmp_path, """
        [sweep]
        "plant.m" = [150.0, 123.0, 160.0, 170.0]
        [battery]
        run_timeout = 2
        """)
    start = time.monotonic()
    outcome = run_battery([load_battery(path)], tmp_path / "out", faulty_fmu, workers=2,
                          progress=False)
    assert time.monotonic() - start < 60
    assert [(r, m.split(";")[0]) for _, r, m in outcome.failed] == [
        ("s1", "timed out: the run took longer than 2 s (run_timeout) and did not stop")]
    assert "killed and replaced" in outcome.failed[0][2]
    assert [r["status"] for r in rows(tmp_path / "out")].count("ok") == 3 * 2


def test_a_worker_that_dies_is_recorded_and_replaced(tmp_path: Path, faulty_fmu: Path) -> None:
    path = battery_file(tmp_path, """
        [sweep]
        "plant.m" = [124.0, 150.0, 124.0, 160.0]
        """)
    outcome = run_battery([load_battery(path)], tmp_path / "out", faulty_fmu, workers=2,
                          progress=False)
    assert [r for _, r, _ in outcome.failed] == ["s0", "s2"]
    assert all("the worker process running it died (exit code 3" in m
               for _, _, m in outcome.failed)
    assert outcome.runs == 4 and len(outcome.records) == 4


def _sigint_when(cmd: list[str], ready, timeout: float = 300.0) -> tuple[int, str, float]:
    """Run ``cmd``; send SIGINT once ``ready()``; return the exit code, stderr, seconds to exit."""
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + timeout
    while not ready() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err, time.monotonic() - sent


def test_ctrl_c_stops_in_seconds_journals_what_finished_and_resumes_identically(
        tmp_path: Path, friction_plant_fmu: Path) -> None:
    path = battery_file(tmp_path, """
        [monte_carlo]
        n = 60
        seed = 3
        "plant.m" = { dist = "uniform", rel = 0.3 }
        "plant.f_c" = { dist = "uniform", rel = 0.3 }
        """)
    papwc = str(Path(sys.executable).with_name("papwc"))
    clean, cut = tmp_path / "clean", tmp_path / "cut"
    assert main(["battery", str(path), "--out", str(clean), "--fmu", str(friction_plant_fmu),
                 "--workers", "2", "--quiet"]) == 0
    journal = cut / "journal.jsonl"

    def some_done() -> bool:
        return journal.is_file() and journal.read_text().count("\n") >= 6

    code, err, seconds = _sigint_when(
        [papwc, "battery", str(path), "--out", str(cut), "--fmu", str(friction_plant_fmu),
         "--workers", "2", "--quiet"], some_done)
    assert code == 130 and seconds < 5.0, (code, seconds, err)
    assert "Traceback" not in err
    done = journal.read_text().count("\n") - 1
    assert f"interrupted: {done} of 60 runs are in the journal" in err
    resume = err.split("to finish, run: ")[1].split("\n")[0]
    assert resume.endswith("--resume") and "--workers 2" in resume
    assert main(["battery", str(path), "--out", str(cut), "--fmu", str(friction_plant_fmu),
                 "--workers", "2", "--quiet", "--resume"]) == 0
    assert (cut / "results.csv").read_bytes() == (clean / "results.csv").read_bytes()


def test_every_journal_corruption_resumes_to_identical_results(
        tmp_path: Path, friction_plant_fmu: Path, capsys) -> None:
    path = battery_file(tmp_path, """
        [monte_carlo]
        n = 12
        seed = 5
        "plant.c" = { dist = "uniform", rel = 0.3 }
        """)
    out = tmp_path / "out"
    args = ["battery", str(path), "--out", str(out), "--fmu", str(friction_plant_fmu),
            "--workers", "2", "--quiet"]
    assert main(args) == 0
    want = (out / "results.csv").read_bytes()
    journal = out / "journal.jsonl"
    good = journal.read_text().split("\n")

    def corrupt(edit) -> str:
        lines = list(good)
        edit(lines)
        journal.write_text("\n".join(lines))
        assert main(args + ["--resume"]) == 0
        assert (out / "results.csv").read_bytes() == want
        return capsys.readouterr().err

    def shapes(lines):
        rec = json.loads(lines[3])
        rec["controllers"] = {"not": "a list"}
        lines[3] = json.dumps(rec)
        rec = json.loads(lines[5])
        del rec["controllers"][0]["iterations"][0]["pulses"]
        lines[5] = json.dumps(rec)
        lines[7] = "[]"

    err = corrupt(shapes)
    assert err.count("skipped") == 3
    assert "skipped" in corrupt(lambda lines: lines.__setitem__(4, "\x00\x01garbage"))
    corrupt(lambda lines: lines.__setitem__(-2, lines[-2][:30]))          # torn last record
    assert "header" in corrupt(lambda lines: lines.__setitem__(0, "{"))   # unreadable header
    assert "parameters differ" in corrupt(lambda lines: lines.__setitem__(
        2, lines[2].replace('"run_hash": "', '"run_hash": "0')))
    corrupt(lambda lines: lines.insert(3, lines[3]))                      # a duplicate
    corrupt(lambda lines: lines.__setitem__(slice(1, None), []))          # records gone


def test_a_rebuilt_fmu_keeps_the_finished_runs(tmp_path: Path, friction_plant_fmu: Path) -> None:
    rebuilt = tmp_path / "rebuilt"
    subprocess.run([sys.executable, "-c", "from pathlib import Path; "
                    "from papwc.fmubuild.fmus import build_fmu; "
                    f"build_fmu('FrictionPlant', Path({str(rebuilt)!r}))"], check=True,
                   timeout=600)
    again = rebuilt / "FrictionPlant.fmu"
    assert again.read_bytes() == friction_plant_fmu.read_bytes()  # reproducible build
    path = battery_file(tmp_path, """
        [sweep]
        "plant.c" = [500.0, 700.0, 900.0]
        """)
    out = tmp_path / "out"
    run_battery([load_battery(path)], out, friction_plant_fmu, workers=1, progress=False)
    outcome = run_battery([load_battery(path)], out, again, workers=1, resume=True,
                          progress=False)
    assert outcome.computed == 0 and outcome.runs == 3


def test_a_folder_where_results_csv_should_be_is_one_line(
        tmp_path: Path, friction_plant_fmu: Path, capsys) -> None:
    path = battery_file(tmp_path, "")
    (tmp_path / "out" / "results.csv").mkdir(parents=True)
    code = main(["battery", str(path), "--out", str(tmp_path / "out"), "--fmu",
                 str(friction_plant_fmu), "--workers", "1", "--quiet"])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err
    assert err.strip().splitlines()[-1] == (
        f"papwc battery: error: cannot write '{tmp_path / 'out' / 'results.csv'}': a folder "
        "is in the way")
    assert (tmp_path / "out" / "journal.jsonl").read_text().count("\n") == 2


def test_a_battery_warning_is_recorded_in_results_and_printed_once(
        tmp_path: Path, friction_plant_fmu: Path, capsys) -> None:
    path = battery_file(tmp_path, """
        [sweep]
        "controller.f_p_max" = [120.0, 300.0]
        """)
    assert main(["battery", str(path), "--out", str(tmp_path / "out"), "--fmu",
                 str(friction_plant_fmu), "--workers", "1", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: 1 run(s) have warnings") == 1
    assert "lim s0: papwc_tpmax_0.03: f_p_max = 120.0 N <= f_s = 130.0 N" in err
    messages = {r["run_id"]: r["message"] for r in rows(tmp_path / "out")}
    assert messages["s0"].startswith("f_p_max = 120.0 N <= f_s = 130.0 N") and not messages["s1"]


@pytest.mark.dask
def test_a_run_past_its_time_limit_stops_on_dask_too(tmp_path: Path,
                                                      friction_plant_fmu: Path) -> None:
    pytest.importorskip("distributed")
    from papwc.battery import local_dask_cluster

    path = battery_file(tmp_path, """
        [sweep]
        "maneuver.T" = [0.01, 1e-5]
        [battery]
        run_timeout = 1
        """)
    with local_dask_cluster(n_workers=1) as address:
        start = time.monotonic()
        outcome = run_battery([load_battery(path)], tmp_path / "out", friction_plant_fmu,
                              scheduler=address, progress=False)
        assert time.monotonic() - start < 60
    assert [r for _, r, _ in outcome.failed] == ["s1"]
    assert outcome.failed[0][2].startswith("timed out: the run took longer than 1 s")
