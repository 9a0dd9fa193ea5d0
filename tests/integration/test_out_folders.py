"""Output folders shared with others (issue 27): ``run`` and ``reproduce`` lock their --out as
batteries do, every file is written through a temporary file created anew (never through a
planted link), and a folder the command fills (``runs/``) is created by it, not followed."""

from __future__ import annotations

from pathlib import Path

import pytest
from harness import GOOD

from papwc.cli import main
from papwc.output_files import LOCK_NAME, lock_folder

PROJECT = Path(__file__).resolve().parents[2]


def one_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    return lines[0]


@pytest.fixture()
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    return path


def test_a_second_run_into_a_folder_in_use_is_refused(scenario, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["run", str(scenario), "--out", str(out), "--plant", "physics"]) == 0
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert LOCK_NAME not in before  # released once the run has finished
    with lock_folder(out, "papwc run"):
        assert main(["run", str(scenario), "--out", str(out), "--plant", "physics"]) == 1
        line = one_line(capsys)
    assert line.startswith(f"papwc run: error: {out}: papwc run (process ")
    assert "is writing into this folder; wait for it to finish or use another --out" in line
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # the other's results


def test_a_battery_and_a_run_exclude_each_other(scenario, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    with lock_folder(out, "papwc battery"):
        assert main(["run", str(scenario), "--out", str(out), "--plant", "physics"]) == 1
        assert "papwc battery (process" in one_line(capsys)
    assert [p.name for p in out.iterdir()] == []


def test_reproduce_into_a_folder_in_use_is_refused(friction_plant_fmu, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    with lock_folder(out, "papwc reproduce"):
        assert main(["reproduce", "--out", str(out), "--fmu", str(friction_plant_fmu)]) == 1
        assert "papwc reproduce (process" in one_line(capsys)
    assert [p.name for p in out.iterdir()] == []


@pytest.mark.parametrize("name", ["summary.csv.tmp", "trace_papwc_it1.csv.tmp", "INCOMPLETE.tmp",
                                  "summary.csv"])
def test_a_link_planted_in_the_run_folder_is_refused_not_followed(
        name, scenario, tmp_path, capsys) -> None:
    out, victim = tmp_path / "out", tmp_path / "victim.txt"
    out.mkdir()
    victim.write_text("keep me")
    (out / name).symlink_to(victim)
    assert main(["run", str(scenario), "--out", str(out), "--plant", "physics"]) == 1
    line = one_line(capsys)
    assert "a symbolic link is in its place" in line and name in line, line
    assert victim.read_text() == "keep me" and (out / name).is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.toml", "out", "victim.txt"]


def test_a_planted_runs_link_is_refused_by_reproduce(friction_plant_fmu, tmp_path,
                                                     capsys) -> None:
    """Issue 27: reproduce deleted and wrote inside a symlinked ``runs/``."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (elsewhere / "summary.csv").write_text("not papwc's")
    (out / "runs").symlink_to(elsewhere)
    assert main(["reproduce", "--out", str(out), "--fmu", str(friction_plant_fmu)]) == 1
    line = one_line(capsys)
    assert f"cannot use folder {str(out / 'runs')!r}: it is a symbolic link" in line, line
    assert [p.name for p in elsewhere.iterdir()] == ["summary.csv"]
    assert (elsewhere / "summary.csv").read_text() == "not papwc's"
    assert LOCK_NAME not in {p.name for p in out.iterdir()}


def test_a_planted_fmu_link_is_refused(tmp_path, scenario, capsys) -> None:
    """``<out>/fmu/`` (where a plant FMU is built when the checkout's is not current) is not
    followed either."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "fmu").symlink_to(elsewhere)
    assert main(["run", str(scenario), "--out", str(out)]) == 1
    assert "a symbolic link is in its place" in one_line(capsys)
    assert list(elsewhere.iterdir()) == []


def test_a_link_planted_as_the_journals_temporary_file_is_refused(tmp_path, capsys) -> None:
    out, victim = tmp_path / "out", tmp_path / "victim.txt"
    out.mkdir()
    victim.write_text("keep me")
    (out / "journal.jsonl.tmp").symlink_to(victim)
    battery = tmp_path / "b.toml"
    battery.write_text(GOOD.replace('name = "t"', 'name = "b"'))
    assert main(["battery", str(battery), "--out", str(out), "--quiet", "--workers", "1"]) == 1
    assert "a symbolic link is in its place" in one_line(capsys)
    assert victim.read_text() == "keep me"
