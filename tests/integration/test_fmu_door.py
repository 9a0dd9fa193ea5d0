"""Every FMU and SSP papwc opens goes through one door (:mod:`papwc.master.archive`): an
archive that cannot be unpacked, read or loaded -- a Windows-only FMU, a broken or foreign
library, a corrupt, encrypted or unusually compressed member, too many members, a zip bomb,
a member path leaving its folder -- is refused in one line naming the file (and the SSP
component), exit 2, with nothing left in the temporary folder and nothing written into --out,
by ``papwc run --fmu``, ``reproduce --fmu``, ``battery --fmu`` (once, before any run) and
``cosim``."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest
from harness import GOOD
from hostile_archives import KINDS, _corrupt, _patch_headers, damage, rezip

from papwc.cli import main
from papwc.fmubuild.ssp_writer import build_closed_loop_ssp

PROJECT = Path(__file__).resolve().parents[2]
PAPER = PROJECT / "scenarios" / "paper.toml"
BATTERY = GOOD.replace('name = "t"', 'name = "door"') + "[sweep]\n\"plant.m\" = [100.0, 200.0]\n"
#: Made quickly; the 600 MiB zip bomb is exercised by one command only (slow).
FAST_KINDS = [k for k in KINDS if k != "too_large"]


@pytest.fixture()
def private_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A temporary folder of its own for everything the command unpacks."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    monkeypatch.setenv("TMPDIR", str(folder))
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


@pytest.fixture(autouse=True)
def _fmu_stderr_default(monkeypatch) -> None:
    """``papwc cosim`` sets PAPWC_FMU_STDERR=0 in its process; undo it after each test."""
    monkeypatch.setenv("PAPWC_FMU_STDERR", "1")


@pytest.fixture(scope="module")
def good_ssp(friction_plant_fmu: Path, pulse_controller_fmu: Path, tmp_path_factory) -> Path:
    return build_closed_loop_ssp(tmp_path_factory.mktemp("ssp"), PAPER, friction_plant_fmu,
                                 pulse_controller_fmu)


def refused(capsys, argv: list[str], out: Path, private_tmp: Path, code: int = 2) -> str:
    """Run papwc expecting ``code``, one line on stderr, nothing unpacked left, no --out."""
    assert main(argv) == code
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    assert list(private_tmp.iterdir()) == []
    assert not out.exists()
    return lines[0]


def command(name: str, tmp_path: Path, fmu: Path) -> list[str]:
    out = str(tmp_path / "out")
    if name == "run":
        scenario = tmp_path / "good.toml"
        scenario.write_text(GOOD)
        return ["run", str(scenario), "--out", out, "--fmu", str(fmu)]
    if name == "reproduce":
        return ["reproduce", "--out", out, "--fmu", str(fmu)]
    battery = tmp_path / "door.toml"
    battery.write_text(BATTERY)
    return ["battery", str(battery), "--out", out, "--fmu", str(fmu), "--workers", "1",
            "--quiet"]


@pytest.mark.parametrize("kind", FAST_KINDS)
@pytest.mark.parametrize("name", ["run", "reproduce", "battery"])
def test_a_plant_fmu_that_cannot_be_used_is_refused_in_one_line(
        name, kind, friction_plant_fmu, tmp_path, private_tmp, capsys) -> None:
    bad = damage(friction_plant_fmu, kind, tmp_path / f"{kind}.fmu")
    line = refused(capsys, command(name, tmp_path, bad), tmp_path / "out", private_tmp)
    assert line.startswith(f"papwc {name}: error: plant FMU {str(bad)!r}: "), line
    assert KINDS[kind] in line, line
    assert not (tmp_path.parent / "escaped.txt").exists()


@pytest.mark.slow
def test_a_zip_bomb_is_refused_before_anything_is_unpacked(friction_plant_fmu, tmp_path,
                                                           private_tmp, capsys) -> None:
    bad = damage(friction_plant_fmu, "too_large", tmp_path / "bomb.fmu")
    assert bad.stat().st_size < 5 * 1024 * 1024
    with zipfile.ZipFile(bad) as z:  # 600 MiB of zeros and the FMU's own files
        total = sum(info.file_size for info in z.infolist()) / (1 << 20)
    line = refused(capsys, command("run", tmp_path, bad), tmp_path / "out", private_tmp)
    assert f"unpacks to {total:.1f} MiB; at most 512 MiB" in line


def test_the_working_folder_is_kept_when_a_library_does_not_load(
        friction_plant_fmu, tmp_path, private_tmp, capsys, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    bad = damage(friction_plant_fmu, "broken_so", tmp_path / "b.fmu")
    refused(capsys, command("run", tmp_path, bad), tmp_path / "out", private_tmp)
    assert Path.cwd() == tmp_path


@pytest.mark.parametrize("kind", FAST_KINDS)
def test_an_ssp_component_that_cannot_be_used_is_named(kind, good_ssp, friction_plant_fmu,
                                                       tmp_path, private_tmp, capsys) -> None:
    member = "resources/FrictionPlant.fmu"
    bad_fmu = damage(friction_plant_fmu, kind, tmp_path / f"{kind}.fmu")
    bad = rezip(good_ssp, tmp_path / "bad.ssp", replace={member: bad_fmu.read_bytes()})
    out = tmp_path / "out"
    line = refused(capsys, ["cosim", str(bad), "--out", str(out)], out, private_tmp)
    assert line.startswith(f"papwc cosim: error: {bad}: "), line
    assert member in line and KINDS[kind] in line, line
    # found when the FMU is unpacked or loaded, or already when the SSD is checked
    assert (f"component 'plant' ({member})" in line
            or '<ssd:Component name="plant" source="resources/FrictionPlant.fmu"' in line), line


@pytest.mark.parametrize("kind", ["corrupt", "encrypted", "method", "members", "not_a_zip"])
def test_an_ssp_archive_that_cannot_be_read_is_refused(kind, good_ssp, tmp_path, private_tmp,
                                                       capsys) -> None:
    bad = tmp_path / "bad.ssp"
    ssd = "SystemStructure.ssd"
    if kind == "corrupt":
        _corrupt(rezip(good_ssp, bad), ssd)
        want = "cannot read SystemStructure.ssd"
    elif kind == "encrypted":
        _patch_headers(rezip(good_ssp, bad), ssd, flag_or=1)
        want = "member 'SystemStructure.ssd' is encrypted"
    elif kind == "method":
        _patch_headers(rezip(good_ssp, bad), ssd, method=9)
        want = "is compressed with method 9"
    elif kind == "members":
        rezip(good_ssp, bad, extra={f"x/{i}": b"" for i in range(10_001)},
              method=zipfile.ZIP_STORED)
        want = "archive members; at most 10000"
    else:
        bad.write_bytes(b"not a zip")
        want = "not a zip archive"
    out = tmp_path / "out"
    line = refused(capsys, ["cosim", str(bad), "--out", str(out)], out, private_tmp)
    assert line.startswith(f"papwc cosim: error: {bad}"), line
    assert want in line, line


def test_an_ssp_of_too_many_components_is_refused(good_ssp, tmp_path, private_tmp,
                                                  capsys) -> None:
    with zipfile.ZipFile(good_ssp) as z:
        ssd = z.read("SystemStructure.ssd").decode()
    start = ssd.index("<ssd:Component ")
    end = ssd.index("</ssd:Component>", start) + len("</ssd:Component>")
    block = ssd[start:end]
    copies = "".join(block.replace('name="plant"', f'name="p{i}"') for i in range(300))
    bad = rezip(good_ssp, tmp_path / "many.ssp",
                replace={"SystemStructure.ssd": (ssd[:end] + copies + ssd[end:]).encode()})
    out = tmp_path / "out"
    line = refused(capsys, ["cosim", str(bad), "--out", str(out)], out, private_tmp)
    assert "components; at most 256" in line


@pytest.mark.slow
def test_no_traceback_from_a_separate_process(friction_plant_fmu, tmp_path) -> None:
    """The same through the installed entry point, in a process of its own."""
    private = tmp_path / "tmp"
    private.mkdir()
    bad = damage(friction_plant_fmu, "foreign_so", tmp_path / "f.fmu")
    done = subprocess.run([sys.executable, "-m", "papwc.cli", *command("run", tmp_path, bad)],
                          capture_output=True, text=True, env={**_env(), "TMPDIR": str(private)})
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert "undefined symbol: fmi2CancelStep" in done.stderr
    assert list(private.iterdir()) == [] and not (tmp_path / "out").exists()


def _env() -> dict[str, str]:
    import os

    return {**os.environ, "PYTHONPATH": str(PROJECT / "controller")}
