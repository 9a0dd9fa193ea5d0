"""``papwc cosim FILE.ssp``: runs any SSP of FMI 2.0 CS FMUs it can; every SSD problem is one
line naming the SSD element, exit status 2, and nothing written."""

from __future__ import annotations

import csv
import dataclasses
import os
import re
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from papwc.cli import main
from papwc.controllers import make_controller
from papwc.fmubuild.ssp_writer import build_closed_loop_ssp
from papwc.master import PhysicsSlave, run_iteration
from papwc.scenario import load_scenario

PROJECT_DIR = Path(__file__).resolve().parents[2]
PAPER = PROJECT_DIR / "scenarios" / "paper.toml"
PAPWC_BOUNDED = 2


@pytest.fixture(scope="module")
def ssp(friction_plant_fmu: Path, pulse_controller_fmu: Path, tmp_path_factory) -> Path:
    return build_closed_loop_ssp(tmp_path_factory.mktemp("ssp"), PAPER, friction_plant_fmu,
                                 pulse_controller_fmu)


@pytest.fixture(autouse=True)
def _fmu_stderr_default(monkeypatch) -> None:
    """``papwc cosim`` sets PAPWC_FMU_STDERR=0 in its process; undo it after each test."""
    monkeypatch.setenv("PAPWC_FMU_STDERR", "1")


def rewrite(ssp: Path, target: Path, edits: list[tuple[str, str]],
            drop: str | None = None) -> Path:
    """A copy of ``ssp`` with its SSD edited (regular expressions, each must match) and one
    member left out."""
    with zipfile.ZipFile(ssp) as src, zipfile.ZipFile(target, "w") as dst:
        for name in src.namelist():
            if name == drop:
                continue
            data = src.read(name)
            if name == "SystemStructure.ssd":
                text = data.decode()
                for pattern, new in edits:
                    text, n = re.subn(pattern, new, text)
                    assert n, pattern
                data = text.encode()
            dst.writestr(name, data)
    return target


def files_under(folder: Path) -> set[Path]:
    return set(folder.rglob("*"))


def refused(capsys, tmp_path: Path, path: Path, *extra: str) -> str:
    """Run ``papwc cosim`` expecting exit 2, one stderr line and nothing written; the line."""
    before = files_under(tmp_path)
    out = tmp_path / "out"
    assert main(["cosim", str(path), "--out", str(out), *extra]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert captured.out == ""
    assert not out.exists() and files_under(tmp_path) == before
    return lines[0]


def test_a_binding_to_a_variable_the_fmu_lacks(ssp, tmp_path, capsys) -> None:
    bad = rewrite(ssp, tmp_path / "bad.ssp", [('<ssv:Parameter name="m">',
                                                '<ssv:Parameter name="mass">')])
    line = refused(capsys, tmp_path, bad)
    assert line.startswith("papwc cosim: error: ")
    assert str(bad) in line and "SystemStructure.ssd" in line
    assert '<ssd:Component name="plant" source="resources/FrictionPlant.fmu"' in line
    assert '<ssv:Parameter name="mass">' in line and "has no variable 'mass'" in line


def test_a_connection_of_mismatched_types(ssp, tmp_path, capsys) -> None:
    bad = rewrite(ssp, tmp_path / "bad.ssp", [('startConnector="x_meas"',
                                                'startConnector="stuck"')])
    line = refused(capsys, tmp_path, bad)
    assert ('<ssd:Connection startElement="plant" startConnector="stuck" '
            'endElement="controller" endConnector="x_meas">') in line
    assert "plant.stuck is a Boolean, controller.x_meas a Real" in line


def test_a_missing_fmu(ssp, tmp_path, capsys) -> None:
    bad = rewrite(ssp, tmp_path / "bad.ssp", [], drop="resources/PulseController.fmu")
    line = refused(capsys, tmp_path, bad)
    assert '<ssd:Component name="controller" source="resources/PulseController.fmu"' in line
    assert "the archive has no resources/PulseController.fmu" in line


def test_a_string_binding_that_contradicts_kind_code_is_refused(ssp, tmp_path, capsys) -> None:
    bad = rewrite(ssp, tmp_path / "bad.ssp", [(
        '<ssv:Parameter name="kind_code">',
        '<ssv:Parameter name="kind"><ssv:String value="pwc" /></ssv:Parameter>'
        '<ssv:Parameter name="kind_code">')])
    line = refused(capsys, tmp_path, bad)
    assert "parameter kind = 'pwc' and kind_code = 2 ('papwc') name different controllers" in line


def test_invalid_parameters_and_options_are_one_line(ssp, tmp_path, capsys) -> None:
    bad = rewrite(ssp, tmp_path / "bad.ssp", [(r'(<ssv:Parameter name="m">\s*<ssv:Real) '
                                                r'value="150.0"', r'\1 value="-1.0"')])
    line = refused(capsys, tmp_path, bad)
    assert "m = -1.0 kg: must satisfy 1e-06 <= m <= 1e+09 kg" in line
    assert "has no variable" in refused(capsys, tmp_path, ssp, "--variables", "plant.nope")
    assert "step = -0.01 s: must be > 0" in refused(capsys, tmp_path, ssp, "--step", "-0.01")
    no_step = rewrite(ssp, tmp_path / "nostep.ssp", [("osp:FixedStepAlgorithm", "osp:Other"),
                                                      ("oms:FixedStepMaster", "oms:Other")])
    assert "give --step" in refused(capsys, tmp_path, no_step)
    assert "no such SSP file" in refused(capsys, tmp_path, tmp_path / "none.ssp")


@pytest.mark.slow
def test_a_string_binding_selects_the_kind(ssp, tmp_path, capsys) -> None:
    """Strings are bound too: ``kind = "pwc"`` instead of ``kind_code`` runs the PWC with
    the table's other settings, as the master does."""
    pwc = rewrite(ssp, tmp_path / "pwc.ssp", [(
        r'<ssv:Parameter name="kind_code">\s*<ssv:Integer value="2" />',
        '<ssv:Parameter name="kind"><ssv:String value="pwc" />')])
    out = tmp_path / "out"
    assert main(["cosim", str(pwc), "--out", str(out), "--variables", "plant.x"]) == 0
    rows = list(csv.reader((out / "pwc.csv").read_text().splitlines()))
    paper = load_scenario(PAPER)
    settings = dataclasses.replace(paper.controllers[PAPWC_BOUNDED], kind="pwc")
    maneuver = dataclasses.replace(paper.maneuver, iterations=1, timing="delayed")
    plant = PhysicsSlave()
    plant.set_start_values(paper.plant)
    trace = run_iteration(plant, make_controller(settings, maneuver.T), maneuver)
    xs = [float(r[1]) for r in rows[1:]]
    assert max(abs(a - b) for a, b in zip(xs, trace.columns["x"], strict=True)) <= 1e-12


@pytest.mark.slow
def test_writes_the_chosen_variables_and_a_plot(ssp, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["cosim", str(ssp), "--out", str(out), "--variables", "plant.x",
                 "controller.u", "controller.pulses", "plant.stuck"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["ClosedLoop.csv", "ClosedLoop.png"]
    assert "200 steps of 0.01 s, 4 variables" in capsys.readouterr().out
    rows = list(csv.reader((out / "ClosedLoop.csv").read_text().splitlines()))
    assert rows[0] == ["time", "plant.x", "controller.u", "controller.pulses", "plant.stuck"]
    assert len(rows) == 202 and rows[1] == ["0.0", "0.0", "0.0", "0", "True"]
    assert float(rows[-1][0]) == pytest.approx(2.0) and int(rows[-1][3]) > 3
    assert (out / "ClosedLoop.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_a_refused_step_keeps_the_rows_before_it(ssp, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["cosim", str(ssp), "--out", str(out), "--step", "0.02"]) == 1
    err = capsys.readouterr().err
    assert "differs from the sample period T = 0.01 s" in err
    rows = list(csv.reader((out / "ClosedLoop.csv").read_text().splitlines()))
    assert len(rows) == 2 and rows[1][0] == "0.0"  # the values after initialization


@pytest.mark.parametrize(("name", "value", "want"), [
    ("max_pulses", "4294967297",
     "controller.max_pulses = 4294967297: must satisfy 1 <= max_pulses <= 1000000 (the FMU's "
     "declared range)"),
    ("seed", "99999999999999999999",
     "plant.seed = 99999999999999999999: must satisfy 0 <= seed <= 2147483647 (the FMU's "
     "declared range)"),
    ("seed", "-1", "plant.seed = -1: must satisfy 0 <= seed <= 2147483647"),
])
def test_an_integer_binding_outside_its_range_is_refused_not_wrapped(
        name, value, want, ssp, tmp_path, capsys) -> None:
    """Issue 27: an Integer does not wrap modulo 2**32 (max_pulses = 4294967297 ran with 1)."""
    bad = rewrite(ssp, tmp_path / "bad.ssp", [(
        rf'(<ssv:Parameter name="{name}">\s*<ssv:Integer) value="[0-9]+"',
        rf'\1 value="{value}"')])
    line = refused(capsys, tmp_path, bad)
    assert f'<ssv:Parameter name="{name}">' in line and want in line, line


@pytest.mark.parametrize(("attribute", "value"), [
    ("stopTime", "1.7e308"), ("startTime", "-1.7e308"), ("stopTime", "inf"),
    ("startTime", "nan")])
def test_default_experiment_times_are_checked_before_arithmetic(attribute, value, ssp,
                                                                tmp_path, capsys) -> None:
    """Issue 27: times of +-1.7e308 gave an OverflowError traceback."""
    bad = rewrite(ssp, tmp_path / "bad.ssp", [(rf'{attribute}="[0-9.]+"',
                                               f'{attribute}="{value}"')])
    line = refused(capsys, tmp_path, bad)
    assert "<ssd:DefaultExperiment>" in line
    assert f"{attribute} = '{value}' s: must be a finite number within -1e+09..1e+09 s" in line


def test_a_stop_and_step_of_overflowing_steps_are_refused(ssp, tmp_path, capsys) -> None:
    line = refused(capsys, tmp_path, ssp, "--stop", "1e308", "--step", "1e-300")
    assert "= inf steps; at most 10000000" in line, line


def _cosim_process(ssp: Path, out: Path, tmp: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(PROJECT_DIR / "controller"), "TMPDIR": str(tmp)}
    return subprocess.Popen([sys.executable, "-m", "papwc.cli", "cosim", str(ssp), "--out",
                             str(out), "--stop", "5000", "--variables", "plant.x",
                             "controller.pulses"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


@pytest.mark.slow
@pytest.mark.parametrize(("signum", "code", "word"), [
    (signal.SIGINT, 130, "interrupted (Ctrl-C)"), (signal.SIGTERM, 143, "terminated (SIGTERM)")])
def test_an_interrupted_cosim_keeps_every_row_with_an_incomplete_marker(
        signum, code, word, ssp, tmp_path) -> None:
    """Issue 27: Ctrl-C or SIGTERM after a while left no output folder; now the rows streamed
    so far are in the CSV, INCOMPLETE says so, nothing is left in the temporary folder."""
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    tmp.mkdir()
    process = _cosim_process(ssp, out, tmp)
    partial = out / "ClosedLoop.csv.tmp"
    deadline = time.monotonic() + 120
    while not (partial.exists() and partial.stat().st_size > 200_000):
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.05)
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    assert process.returncode == code, err
    assert "Traceback" not in err
    rows = list(csv.reader((out / "ClosedLoop.csv").read_text().splitlines()))
    assert rows[0] == ["time", "plant.x", "controller.pulses"]
    times = [float(r[0]) for r in rows[1:]]
    assert len(times) > 1000
    assert times == [k * 0.01 for k in range(len(times))]  # every row, none torn
    kept = re.search(r"kept (\d+) of 500000 steps", err)
    assert kept and int(kept.group(1)) == len(times) - 1, err
    marker = (out / "INCOMPLETE").read_text()
    assert word in marker and f"{len(times)} rows" in marker
    assert not partial.exists() and not (out / "ClosedLoop.png").exists()
    assert list(tmp.iterdir()) == []


def test_two_cosims_into_one_folder_the_second_is_refused(ssp, tmp_path, capsys) -> None:
    from papwc.output_files import lock_folder

    out = tmp_path / "out"
    out.mkdir()
    with lock_folder(out, "papwc run"):
        assert main(["cosim", str(ssp), "--out", str(out)]) == 1
        assert sorted(p.name for p in out.iterdir()) == [".papwc.lock"]  # (the other's)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "papwc run (process" in err[0], err
    assert "is writing into this folder" in err[0]
    assert list(out.iterdir()) == []


def test_a_link_planted_as_the_csvs_temporary_file_is_refused(ssp, tmp_path, capsys) -> None:
    """Issue 27: cosim wrote through a planted ``<file>.tmp`` symlink, outside --out."""
    out, victim = tmp_path / "out", tmp_path / "victim.txt"
    out.mkdir()
    victim.write_text("keep me")
    (out / "ClosedLoop.csv.tmp").symlink_to(victim)
    assert main(["cosim", str(ssp), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a symbolic link is in its place" in err[0], err
    assert victim.read_text() == "keep me"


def test_out_of_memory_names_the_flags_cosim_has(ssp, tmp_path, capsys, monkeypatch) -> None:
    import papwc.results.cosim_stream

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(papwc.results.cosim_stream, "cosim", no_memory)
    assert main(["cosim", str(ssp), "--out", str(tmp_path / "out")]) == 1
    line = capsys.readouterr().err.strip()
    assert line == ("papwc cosim: error: out of memory; lower the work asked for (e.g. --stop, "
                    "--variables)")


@pytest.mark.slow
def test_cosim_memory_does_not_grow_with_the_runs_length(ssp, tmp_path) -> None:
    """Peak RSS of 2e5 steps (every output recorded) is within 10 MB of that of 4e4 steps
    (both beyond the rows the plot keeps); ``papwc bench`` measures 1e6 steps against the
    200 MB goal."""
    from papwc.bench.cosim_memory import cosim_peak_mb

    short = cosim_peak_mb(ssp, tmp_path / "short", 400.0)
    long = cosim_peak_mb(ssp, tmp_path / "long", 2000.0)
    assert long - short < 10.0, (short, long)
    assert long < 200.0


# --- issue 44: the weak answers kept from earlier rounds ----------------------------------------


@pytest.mark.parametrize("kind, words", [
    ("folder", "is a folder, not a file; give an SSP archive (a .ssp zip file)"),
    ("fifo", "is not a regular file (a FIFO, device or socket); give an SSP archive (a .ssp "
             "zip file)"),
])
def test_an_ssp_path_that_is_not_a_file_says_what_it_is(kind, tmp_path, capsys, words) -> None:
    """Issue 44: a folder or a FIFO was 'no such SSP file'."""
    path = tmp_path / f"a_{kind}.ssp"
    path.mkdir() if kind == "folder" else os.mkfifo(path)
    assert refused(capsys, tmp_path, path) == f"papwc cosim: error: {path}: {words}"


def test_a_component_name_with_a_dot_is_refused_where_it_is(ssp, tmp_path, capsys) -> None:
    """Issue 44: a component pl.ant was blamed on a --variables option not given."""
    bad = rewrite(ssp, tmp_path / "bad.ssp", [('name="plant"', 'name="pl.ant"'),
                                               ('Element="plant"', 'Element="pl.ant"')])
    line = refused(capsys, tmp_path, bad)
    assert '<ssd:Component name="pl.ant" source="resources/FrictionPlant.fmu"' in line
    assert "a component name cannot hold '.'" in line and "--variables" not in line


def test_a_huge_integer_is_shortened_in_its_message(ssp, tmp_path, capsys) -> None:
    """Issue 44: a 5,000-digit Integer was quoted whole (and called not a whole number)."""
    bad = rewrite(ssp, tmp_path / "bad.ssp", [(r'<ssv:Integer value="0" />',
                                               '<ssv:Integer value="' + "7" * 5000 + '" />')])
    line = refused(capsys, tmp_path, bad)
    assert "'7777777777777777777777777777777777777777'... (5000 characters): must satisfy " \
           "-2147483648 <= value <= 2147483647 (an FMI 2.0 Integer)" in line
    assert len(line) < 400


@pytest.mark.parametrize("connection, words", [
    ('<ssd:Connection startElement="controller" startConnector="b_hat" endElement="plant" '
     'endConnector="u" />', 'plant.u has a connection already, <ssd:Connection '
     'startElement="controller" startConnector="u" endElement="plant" endConnector="u">; an '
     'input takes one connection'),
    ('<ssd:Connection startElement="plant" startConnector="x" endElement="plant" '
     'endConnector="u" />', "connects component 'plant' to itself; a connection joins two "
                            "components"),
], ids=["two-into-one", "self-loop"])
def test_connections_an_input_cannot_take_are_refused(connection, words, ssp, tmp_path,
                                                      capsys) -> None:
    """Issue 44: two connections into one input, and a self-loop, were accepted."""
    end = '<ssd:Connection startElement="controller" startConnector="u" endElement="plant" ' \
          'endConnector="u" />'
    bad = rewrite(ssp, tmp_path / "bad.ssp", [(re.escape(end), end + connection)])
    line = refused(capsys, tmp_path, bad)
    assert words in line and "SystemStructure.ssd <ssd:Connection " in line, line


def test_two_fixed_steps_that_differ_are_reported(ssp, tmp_path, capsys) -> None:
    """Issue 44: oms: 0.005 s beside osp: 0.01 s ran at 0.01 s without a word."""
    bad = rewrite(ssp, tmp_path / "bad.ssp", [('stepSize="0.01"', 'stepSize="0.005"')])
    line = refused(capsys, tmp_path, bad)
    assert ("the fixed step is given twice and differently, osp:FixedStepAlgorithm "
            "baseStepSize = 0.01 s and oms:FixedStepMaster stepSize = 0.005 s; make them equal "
            "or give --step") in line
    out = tmp_path / "out"
    assert main(["cosim", str(bad), "--out", str(out), "--step", "0.01", "--stop", "0.05",
                 "--variables", "plant.x"]) == 0  # --step decides
    capsys.readouterr()


def test_the_dual_loop_without_the_motor_encoder_says_so_at_load(
        friction_plant_fmu, pulse_controller_fmu, tmp_path, capsys) -> None:
    """Issue 44: the dual loop in an SSP without its x_d_meas connection stopped safely
    but said nothing. ClosedLoop.ssp of a dual-loop scenario has the connection; without
    it the SSP is refused in one line."""
    text = (PROJECT_DIR / "scenarios" / "flexible_dual.toml").read_text()
    scenario = tmp_path / "dual.toml"
    scenario.write_text(text[:text.index("[cases]")])
    good = build_closed_loop_ssp(tmp_path / "b", scenario, friction_plant_fmu,
                                 pulse_controller_fmu)
    with zipfile.ZipFile(good) as z:
        ssd = z.read("SystemStructure.ssd").decode()
    wire = ('<ssd:Connection startElement="plant" startConnector="x_d_meas" '
            'endElement="controller" endConnector="x_d_meas" />')
    assert wire in ssd
    bad = rewrite(good, tmp_path / "bad.ssp", [(re.escape(wire), "")])
    line = refused(capsys, tmp_path, bad)
    assert ('<ssd:Component name="controller" source="resources/PulseControllerPython.fmu" '
            'type="application/x-fmu-sharedlibrary">: kind \'dual_loop\' reads the motor '
            "encoder, but controller.x_d_meas has no ssd:Connection (it would read 0 m); "
            "connect the plant's x_d_meas to controller.x_d_meas") in line, line
