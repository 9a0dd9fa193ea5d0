"""The ``papwc`` command line: run, reproduce, errors without tracebacks, what it imports,
and that it writes only under ``--out`` whatever the current folder."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest
from harness import GOOD, SHORT_PAPER

from papwc.cli import COMMANDS, main
from papwc.fmubuild.fmus import is_current
from papwc.resources import checkout_root


def _write(folder: Path, text: str, name: str = "s.toml") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    return path


def test_cli_run_writes_summary_traces_and_plots(tmp_path, friction_plant_fmu, capsys):
    path = _write(tmp_path, GOOD + '\n[[controller]]\nkind = "pwc"\nt_p_max = 0.03\n')
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--fmu", str(friction_plant_fmu)]) == 0
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    for col in ("controller", "t_p_max", "iteration", "final_error_m", "pulses",
                "settle_time_s", "limit_cycle", "b_hat", "f_c_hat"):
        assert col in rows[0]
    assert len(rows) == 2
    assert {r["status"] for r in rows} == {"ok"}
    assert sorted(p.name for p in out.glob("trace_*.csv")) == [
        "trace_papwc_tpmax_inf_it1.csv", "trace_pwc_tpmax_0.03_it1.csv"]
    for png in ("error.png", "force.png", "estimates.png"):
        assert (out / png).stat().st_size > 1000
    assert "final_error_m" in capsys.readouterr().out


def test_cli_reports_a_bad_scenario_without_a_traceback(tmp_path, capsys):
    path = _write(tmp_path, GOOD.replace("m = 150.0", "m = -1.0"))
    assert main(["run", str(path), "--plant", "physics"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "m = -1.0" in err
    assert err == (f"papwc run: error: {path}: [plant] field 'm': m = -1.0 kg: must satisfy "
                   f"1e-06 <= m <= 1e+09 kg\n")


@pytest.mark.parametrize(
    ("line", "field", "message"),
    [
        ("history = 0", "history", "history = 0: must be a whole number 1 <= history <= 52"),
        ("history = -1", "history", "history = -1: must be a whole number 1 <= history <= 52"),
        ('c_est = "x"', "c_est", "c_est = 'x': must be a number"),
        ("f_s_tol = 0", "f_s_tol", "f_s_tol = 0: must satisfy 0 < f_s_tol <= 1"),
    ],
)
def test_cli_run_reports_a_bad_exact_setting_in_one_line(tmp_path, capsys, line, field,
                                                         message):
    path = _write(tmp_path, GOOD.replace('kind = "papwc"', f'kind = "exact"\n{line}'))
    out = tmp_path / "out"
    assert main(["run", str(path), "--plant", "physics", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert lines == [f"papwc run: error: {path}: [[controller]] #1 field '{field}': {message}"]
    assert "Traceback" not in captured.err and captured.out == ""
    assert not out.exists()


def test_cli_run_as_a_process_exits_2_with_one_line(tmp_path):
    path = _write(tmp_path, GOOD.replace('kind = "papwc"', 'kind = "exact"\nhistory = 0'))
    done = subprocess.run([sys.executable, "-m", "papwc.cli", "run", str(path), "--plant",
                           "physics"], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"papwc run: error: {path}: [[controller]] #1 field 'history': history = 0: must be "
        "a whole number 1 <= history <= 52"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


# -- the current folder is never written ----------------------------------------------------------
def test_run_in_an_empty_folder_writes_only_under_out(tmp_path, empty_cwd, friction_plant_fmu,
                                                      capsys):
    scenario = _write(tmp_path / "in", GOOD)
    out = tmp_path / "out"
    assert main(["run", str(scenario), "--out", str(out), "--fmu", str(friction_plant_fmu)]) == 0
    assert list(empty_cwd.iterdir()) == []
    assert (out / "summary.csv").is_file()
    assert sorted(p.name for p in (tmp_path / "in").iterdir()) == ["s.toml"]
    # a relative --out is under the current folder, and nothing else appears there
    assert main(["run", str(scenario), "--out", "res", "--fmu", str(friction_plant_fmu)]) == 0
    assert [p.name for p in empty_cwd.iterdir()] == ["res"]
    assert (empty_cwd / "res" / "summary.csv").read_text().splitlines()[0] == (
        out / "summary.csv").read_text().splitlines()[0]
    capsys.readouterr()


def test_reproduce_in_an_empty_folder_writes_only_under_out(tmp_path, empty_cwd,
                                                            friction_plant_fmu, capsys):
    scenario = _write(tmp_path / "in", SHORT_PAPER, "short.toml")
    out = tmp_path / "out"
    code = main(["reproduce", "--out", str(out), "--scenario", str(scenario),
                 "--fmu", str(friction_plant_fmu)])
    assert code == 0
    assert list(empty_cwd.iterdir()) == []
    names = {p.name for p in out.iterdir()}
    assert {f"fig{i}.png" for i in (1, 3, 4, 5, 6, 7, 8, 9)} <= names
    assert {"paper_numbers.csv", "report.md", "runs"} <= names
    assert "fig_exact.png" not in names  # the extra scenarios only with the paper's
    assert not (out / "fmu").exists()  # --fmu given: nothing built
    report = (out / "report.md").read_text()
    assert report.startswith("# The paper reproduced") and str(scenario) in report
    assert (out / "runs" / "trace_pwc_tpmax_0.03_it2.csv").is_file()
    assert "wrote" in capsys.readouterr().out


@pytest.mark.slow
def test_reproduce_without_fmu_builds_or_finds_a_current_plant(tmp_path, empty_cwd, capsys):
    """The default scenario (with the extra exact ones) and no --fmu: the plant is the
    checkout's current build/FrictionPlant.fmu, or one built into <out>/fmu/."""
    out = tmp_path / "out"
    assert main(["reproduce", "--out", str(out)]) == 0
    assert list(empty_cwd.iterdir()) == []
    built = out / "fmu" / "FrictionPlant.fmu"
    root = checkout_root()
    checkout_fmu = None if root is None else root / "build" / "FrictionPlant.fmu"
    if checkout_fmu is not None and is_current(checkout_fmu, "FrictionPlant"):
        assert not built.exists()
        used = checkout_fmu
    else:
        assert is_current(built, "FrictionPlant")
        used = built
    stdout = capsys.readouterr().out
    assert f"on {used} ..." in stdout
    assert (out / "fig_exact.png").stat().st_size > 1000
    with open(out / "paper_numbers.csv", newline="") as f:
        numbers = {r["quantity"]: float(r["computed"]) for r in csv.DictReader(f)}
    # PWC with t_p_max = 0.03 s ends in the limit cycle of Eq. (19)
    assert numbers["pwc_tpmax_0.03: limit-cycle peak-to-peak / d_min Eq. (19)"] == (
        pytest.approx(1.0, rel=1e-14))
    assert numbers["papwc_tpmax_0.03: limit cycle in iteration 10 (1 = yes)"] == 0.0


# -- what the command line imports ----------------------------------------------------------------
def test_help_imports_none_of_the_heavy_modules():
    code = ("import sys; from papwc.cli import make_parser; make_parser(); "
            "print(sorted(m for m in ('fmpy','numpy','matplotlib','pythonfmu') "
            "if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_help_lists_every_command(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out
    assert COMMANDS == ("build", "run", "reproduce", "bench", "battery", "spec", "cosim",
                        "hostenv", "identify")


def test_build_command_writes_the_fmus_and_the_ssp(tmp_path, capsys):
    """``papwc build --out DIR`` in a fresh process (building after an FMU was loaded into
    this one would fail): every FMU current, and ClosedLoop.ssp."""
    out = tmp_path / "build"
    done = subprocess.run([sys.executable, "-m", "papwc.cli", "build", "--out", str(out)],
                          cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [str(out / name) for name in (
        "FrictionPlant.fmu", "PulseController.fmu", "PulseControllerPython.fmu",
        "PapwcTrivial.fmu", "ClosedLoop.ssp")]
    for name in ("FrictionPlant", "PulseController", "PulseControllerPython", "PapwcTrivial"):
        assert is_current(out / f"{name}.fmu", name)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["build"]
