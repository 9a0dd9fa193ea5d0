"""The weaker items of issue 27, each through the command line: the resume line after an
interrupted battery runs verbatim (it keeps --max-steps), SIGTERM stops a battery as Ctrl-C
does (no worker traceback), ``papwc build --controller`` is 1-based in its refusals too, and
``reproduce --scenario`` of a scenario without PWC or PAPWC claims only the figures it
wrote.

And those of issue 44 (the third round): ``--scheduler`` pointed at a peer that does not
speak Dask, ``papwc run`` interrupted in its first controller, and the weak answers kept
from earlier rounds.
"""

from __future__ import annotations

import contextlib
import csv
import http.server
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from harness import GOOD, PAPWC_PAPER, scenario_toml

from papwc.cli import main

PROJECT = Path(__file__).resolve().parents[2]
BATTERY = scenario_toml("sig", maneuver={"x_ref": 0.01, "T": 0.01, "duration": 30.0,
                                          "iterations": 20},
                        controllers=[PAPWC_PAPER],
                        tables={"sweep": {"plant.m": [100.0 + 10.0 * k for k in range(8)]}})


def test_the_resume_line_keeps_the_limits_it_needs(tmp_path, friction_plant_fmu, capsys,
                                                   monkeypatch) -> None:
    """Issue 27: the resume line dropped --max-steps, so run verbatim it was refused."""
    import papwc.battery
    from papwc.battery.orchestrate import BatteryInterrupted

    def interrupted(*args, **kwargs):
        raise BatteryInterrupted(1, 8, tmp_path / "out" / "journal.jsonl")

    monkeypatch.setattr(papwc.battery, "run_battery", interrupted)
    battery = tmp_path / "b.toml"
    battery.write_text(BATTERY)
    assert main(["battery", str(battery), "--out", str(tmp_path / "out"), "--fmu",
                 str(friction_plant_fmu), "--max-steps", "5000000", "--max-runs", "50",
                 "--workers", "1", "--quiet"]) == 130
    err = capsys.readouterr().err
    line = err.split("to finish, run: ")[1].splitlines()[0]
    assert line == (f"papwc battery {battery} --out {tmp_path / 'out'} --fmu "
                    f"{friction_plant_fmu} --workers 1 --max-runs 50 --max-steps 5000000 "
                    "--quiet --resume")


@pytest.mark.slow
def test_sigterm_stops_a_battery_as_ctrl_c_does(tmp_path, friction_plant_fmu) -> None:
    battery = tmp_path / "b.toml"
    battery.write_text(BATTERY)
    out = tmp_path / "out"
    err_path = tmp_path / "err.txt"
    with open(err_path, "w") as err:
        process = subprocess.Popen(
            [sys.executable, "-m", "papwc.cli", "battery", str(battery), "--out", str(out),
             "--fmu", str(friction_plant_fmu), "--workers", "2", "--quiet"],
            stdout=subprocess.DEVNULL, stderr=err,
            env={**os.environ, "PYTHONPATH": str(PROJECT / "controller")})
        journal = out / "journal.jsonl"
        deadline = time.monotonic() + 120
        while not (journal.is_file() and journal.read_text().count("\n") >= 2):
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.1)
        process.send_signal(signal.SIGTERM)
        assert process.wait(60) == 143
    time.sleep(2)  # a worker that outlived the battery would write now
    text = err_path.read_text()
    assert "Traceback" not in text, text
    assert "papwc battery: terminated (SIGTERM): " in text and "--resume" in text
    assert "runs are in the journal" in text


@pytest.mark.parametrize("n", ["0", "5"])
def test_build_controller_is_one_based_in_its_refusal(n, tmp_path, capsys) -> None:
    out = tmp_path / "build"
    assert main(["build", "--out", str(out), "--controller", n]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--controller {n}: " in err[0]
    assert "has 4 [[controller]] table(s); give 1 to 4 (1-based)" in err[0]
    assert not out.exists()  # refused before anything is built


@pytest.mark.slow
def test_reproduce_of_another_scenario_claims_only_the_figures_it_wrote(
        tmp_path, friction_plant_fmu, capsys) -> None:
    scenario = tmp_path / "exact_only.toml"
    scenario.write_text(GOOD.replace('kind = "papwc"', 'kind = "exact"'))
    out = tmp_path / "out"
    assert main(["reproduce", "--out", str(out), "--scenario", str(scenario), "--fmu",
                 str(friction_plant_fmu)]) == 0
    wrote = next(line for line in capsys.readouterr().out.splitlines()
                 if line.startswith("wrote "))
    figures = sorted(p.name for p in out.glob("*.png"))
    assert figures == ["fig1.png"]
    assert wrote.startswith(f"wrote {out}/fig1.png, paper_numbers.csv")
    assert "fig3" not in wrote and "fig9" not in wrote
    assert "Figures: fig1.png (Eq. (3) and (4)); " in (out / "report.md").read_text()


@pytest.mark.slow
def test_sigterm_stops_a_run_as_ctrl_c_does(tmp_path, friction_plant_fmu) -> None:
    """SIGTERM to ``papwc run``: between two steps, the finished controllers kept, the
    folder marked incomplete, exit 143, no traceback."""
    scenario = tmp_path / "long.toml"
    scenario.write_text(GOOD.replace("duration = 0.5", "duration = 200.0")
                        .replace("iterations = 1", "iterations = 3")
                        + '[[controller]]\nkind = "pwc"\n')
    out = tmp_path / "out"
    process = subprocess.Popen(
        [sys.executable, "-m", "papwc.cli", "run", str(scenario), "--out", str(out), "--fmu",
         str(friction_plant_fmu)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(PROJECT / "controller")})
    deadline = time.monotonic() + 120
    while not (out / "INCOMPLETE").is_file():
        assert process.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(0.5)
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 143, err
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1] == "papwc run: terminated (SIGTERM)"
    assert "terminated (SIGTERM)" in (out / "INCOMPLETE").read_text()


@pytest.mark.parametrize(("command", "hint"), [
    ("run", "--max-steps"), ("reproduce", "--scenario with fewer iterations, --workers"),
    ("battery", "--max-steps, --max-runs, --workers")])
def test_out_of_memory_names_the_flags_of_the_command(command, hint, monkeypatch,
                                                      capsys) -> None:
    import papwc.cli

    parser = papwc.cli.make_parser()
    real = parser.parse_args

    def parse(argv):
        args = real(argv)
        args._run = lambda args: (_ for _ in ()).throw(MemoryError)
        return args

    monkeypatch.setattr(papwc.cli, "make_parser", lambda: parser)
    monkeypatch.setattr(parser, "parse_args", parse)
    argv = {"run": ["run", "x.toml"], "reproduce": ["reproduce"],
            "battery": ["battery", "x.toml"]}[command]
    assert main(argv) == 1
    assert capsys.readouterr().err.strip() == (
        f"papwc {command}: error: out of memory; lower the work asked for (e.g. {hint})")


# --- issue 44 -----------------------------------------------------------------------------------


@contextlib.contextmanager
def foreign_peer(kind: str) -> Iterator[int]:
    """A server on 127.0.0.1 that is not a Dask scheduler (``"http"``: a web server;
    ``"random"``: one that sends random bytes at once); yields its port, stopped after."""
    if kind == "http":
        class Quiet(http.server.BaseHTTPRequestHandler):
            def log_message(self, *args) -> None:
                pass

        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        try:
            yield server.server_address[1]
        finally:
            server.shutdown()
            server.server_close()
            thread.join(10)
        return
    listener = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def serve() -> None:
        listener.settimeout(0.1)
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except OSError:
                continue
            with conn, contextlib.suppress(OSError):
                conn.sendall(os.urandom(4096))
                conn.settimeout(2.0)
                conn.recv(1 << 16)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield listener.getsockname()[1]
    finally:
        stop.set()
        thread.join(10)
        listener.close()


@pytest.mark.dask
@pytest.mark.parametrize("kind, words", [
    ("http", "the peer accepted the connection but sent no Dask handshake within 3 s"),
    ("random", "the peer does not speak Dask (its first bytes are b"),
])
def test_a_scheduler_that_is_not_dask_is_refused_within_the_timeout(
        kind, words, tmp_path, friction_plant_fmu, capsys, monkeypatch) -> None:
    """Issue 44: a web server held the battery for ever; random bytes made Dask's reader
    allocate exabytes (an "out of memory" that was not papwc's) or raise a traceback."""
    import papwc.battery.engines

    monkeypatch.setattr(papwc.battery.engines, "CONNECT_TIMEOUT_S", 3.0)
    battery = tmp_path / "b.toml"
    battery.write_text(BATTERY)
    out = tmp_path / "out"
    with foreign_peer(kind) as port:
        address = f"tcp://127.0.0.1:{port}"
        start = time.monotonic()
        code = main(["battery", str(battery), "--out", str(out), "--fmu",
                     str(friction_plant_fmu), "--scheduler", address, "--quiet"])
        seconds = time.monotonic() - start
    err = capsys.readouterr().err
    assert code == 2 and seconds < 3.0 + 5.0, (code, seconds)
    assert err.count("\n") == 1 and err.startswith(f"papwc battery: error: --scheduler {address}: ")
    assert words in err and "out of memory" not in err and "Traceback" not in err
    assert not out.exists()  # refused before anything is written


@pytest.mark.slow
def test_build_says_what_it_compiles_for_which_platform(tmp_path) -> None:
    """Issue 44: ``papwc build`` printed nothing until it was done (minutes on a first
    build). Off a terminal each step is a line on stderr as it starts; the paths on stdout
    come as each file is written. A native FMU takes the binaries compiled when papwc was
    installed, or, where its sources changed since, says what it compiles for which
    platform."""
    done = subprocess.run([sys.executable, "-m", "papwc.cli", "build", "--out",
                           str(tmp_path / "b")], capture_output=True, text=True, timeout=900,
                          env={**os.environ, "PYTHONPATH": str(PROJECT / "controller")})
    assert done.returncode == 0, done.stderr
    err = done.stderr.splitlines()
    for name in ("FrictionPlant", "PulseController"):
        taken = f"papwc build: taking {name}'s binaries compiled when papwc was installed"
        compiled = [f"papwc build: compiling {name}.fmu's C sources for {platform} "
                    f"({target}) with zig" for platform, target in (
                        ("linux64", "x86_64-linux-gnu.2.17"), ("win64", "x86_64-windows-gnu"),
                        ("darwin64", "x86_64-macos.10.13"), ("darwin64", "aarch64-macos.11.0"))]
        assert taken in err or all(line in err for line in compiled), err
    native = ("papwc build: building FrictionPlant.fmu (C: the binaries compiled when papwc "
              "was installed, or by zig if its sources changed since)")
    assert "papwc build: building PulseControllerPython.fmu with pythonfmu" in err
    assert err.index(native) < err.index(
        "papwc build: building PulseControllerPython.fmu with pythonfmu")
    assert done.stdout.splitlines() == [str(tmp_path / "b" / name) for name in (
        "FrictionPlant.fmu", "PulseController.fmu", "PulseControllerPython.fmu",
        "PapwcTrivial.fmu", "ClosedLoop.ssp")]


@pytest.mark.slow
@pytest.mark.parametrize("signum, code, what", [(signal.SIGINT, 130, "interrupted (Ctrl-C)"),
                                                 (signal.SIGTERM, 143, "terminated (SIGTERM)")],
                         ids=["ctrl-c", "sigterm"])
def test_a_run_stopped_in_its_first_controller_keeps_its_trace(
        signum, code, what, tmp_path, friction_plant_fmu) -> None:
    """Issue 44: Ctrl-C during the first controller of ``papwc run`` kept nothing of it
    although seconds of trace had been computed (cosim keeps every row it computed). The
    trace is kept, cut short where the run stopped, and INCOMPLETE says so."""
    scenario = tmp_path / "long.toml"
    scenario.write_text(scenario_toml("long", maneuver={"x_ref": 0.01, "T": 0.01,
                                                         "duration": 5000.0, "iterations": 1},
                                      controllers=[{"kind": "pwc", "label": "pwc",
                                                    "tolerance": 0.0}]))
    out = tmp_path / "out"
    process = subprocess.Popen(
        [sys.executable, "-m", "papwc.cli", "run", str(scenario), "--out", str(out), "--fmu",
         str(friction_plant_fmu), "--max-steps", "1000000"], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(PROJECT / "controller")},
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while not (out / "INCOMPLETE").is_file():
        assert process.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(1.5)  # into the first (and only) controller's steps
    process.send_signal(signum)
    _, err = process.communicate(timeout=120)
    assert process.returncode == code, err
    assert "Traceback" not in err
    trace = out / "trace_pwc_it1.csv"
    with open(trace, newline="") as f:
        rows = list(csv.DictReader(f))
    t_cut = float(rows[-1]["t"])
    assert 0.0 < t_cut < 5000.0 and len(rows) == round(t_cut / 0.01) + 1
    assert [float(r["t"]) for r in rows[:3]] == [0.0, 0.01, 0.02]
    assert rows[-1]["u"] == "nan"  # the state reached last, as a finished trace ends
    incomplete = (out / "INCOMPLETE").read_text()
    assert (f"- controller pwc in part: trace_pwc_it1.csv (cut short at t = {t_cut!r} s: "
            f"{what})") in incomplete, incomplete
    assert "missing: pwc; the traces of pwc until the stop are kept" in err
    assert not (out / "summary.csv").exists()


def test_a_controller_fmu_given_as_the_plant_is_refused_up_front(
        tmp_path, pulse_controller_fmu, capsys) -> None:
    """Issue 44: PulseController.fmu as a battery's --fmu was not checked up front: every
    run failed."""
    battery = tmp_path / "b.toml"
    battery.write_text(BATTERY)
    out = tmp_path / "out"
    assert main(["battery", str(battery), "--out", str(out), "--fmu", str(pulse_controller_fmu),
                 "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert (f"papwc battery: error: plant FMU {str(pulse_controller_fmu)!r}: not a plant FMU: "
            "it has no Real u (input), x (output), v (output), x_meas (output) (the model is "
            "PulseController); give FrictionPlant.fmu") in err, err
    assert not out.exists()


def test_an_fmu_given_with_the_physics_plant_is_refused(tmp_path, capsys) -> None:
    """Issue 44: run --plant physics --fmu /nope.fmu ran (rc 0), --fmu silently ignored."""
    scenario = tmp_path / "s.toml"
    scenario.write_text(GOOD)
    out = tmp_path / "out"
    assert main(["run", str(scenario), "--plant", "physics", "--fmu", "/nope.fmu", "--out",
                 str(out)]) == 2
    assert capsys.readouterr().err == (
        "papwc run: error: --fmu /nope.fmu: --plant physics runs the in-process physics and "
        "loads no FMU; give --fmu with --plant fmu (the default) only\n")
    assert not out.exists()


def test_a_closed_standard_output_is_an_error_not_a_silent_success() -> None:
    """Issue 44: ``papwc hostenv >&-`` gave rc 0 having written nothing (Python sets
    sys.stdout to None and print() then writes nothing)."""
    done = subprocess.run([sys.executable, "-m", "papwc.cli", "hostenv"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          timeout=120, preexec_fn=lambda: os.close(1),
                          env={**os.environ, "PYTHONPATH": str(PROJECT / "controller")})
    assert done.returncode == 1
    assert done.stderr == ("papwc hostenv: error: cannot write to standard output: it is closed "
                           "(the command was started with >&-)\n")
