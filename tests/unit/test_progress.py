"""What a long command says while it works (issue 44: ``papwc build`` was silent for minutes
on a first build, ``papwc identify`` for two minutes while it tried the deviations).

:class:`papwc.progress.Progress` on a terminal (a status line rewritten in place) and off
one (a line as a step starts, another every PLAIN_PROGRESS_S seconds); the lines of the
native build: what it compiles, for which platform, and once that a first build compiles
zig's C runtimes.
"""

from __future__ import annotations

import io
import time
from pathlib import Path

import pytest

import papwc.progress
from papwc.fmubuild import native_build
from papwc.progress import Progress, doing


@pytest.fixture
def fast(monkeypatch: pytest.MonkeyPatch) -> None:
    """Progress lines every 0.05 s instead of every 10 s (1 s on a terminal)."""
    monkeypatch.setattr(papwc.progress, "PLAIN_PROGRESS_S", 0.05)
    monkeypatch.setattr(papwc.progress, "TERMINAL_REFRESH_S", 0.05)


def wait_for(stream: io.StringIO, text: str, seconds: float = 10.0) -> None:
    deadline = time.monotonic() + seconds
    while text not in stream.getvalue():
        assert time.monotonic() < deadline, stream.getvalue()
        time.sleep(0.01)


def test_off_a_terminal_a_step_is_a_line_and_another_while_it_lasts(fast) -> None:
    stream = io.StringIO()
    with Progress("papwc x", stream=stream, tty=False) as progress:
        doing("compiling a")
        wait_for(stream, "s so far)")
        progress.say("a done")
        progress.done()
        told = stream.getvalue()
        time.sleep(0.2)  # an ended step is not told again
        assert stream.getvalue() == told
    lines = stream.getvalue().splitlines()
    assert lines[0] == "papwc x: compiling a"
    assert lines[1].startswith("papwc x: compiling a (") and lines[1].endswith(" s so far)")
    assert lines[-1] == "papwc x: a done"
    assert "\r" not in stream.getvalue()


def test_on_a_terminal_the_step_is_one_status_line_rewritten(fast) -> None:
    stream = io.StringIO()
    with Progress("papwc x", stream=stream, tty=True) as progress:
        progress.doing("fitting")
        wait_for(stream, "\r\x1b[Kpapwc x: fitting (0 s)\r\x1b[Kpapwc x: fitting (")
        progress.say("tried b")
    text = stream.getvalue()
    assert "\r\x1b[Kpapwc x: tried b\n" in text  # the status line cleared first
    assert text.endswith("\r\x1b[K")  # and cleared at the end
    assert "so far" not in text


def test_without_a_command_listening_nothing_is_said(capsys) -> None:
    doing("compiling")
    papwc.progress.say("done")
    assert capsys.readouterr() == ("", "")


def test_the_native_build_says_what_it_compiles_and_once_that_zig_starts_empty(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiler itself is left out (the steps and what they say are checked): an empty
    zig cache gives the first build's note, once per process."""
    def compile_stub(tree, target, extra, out, name) -> None:
        out.write_bytes(b"\xcf\xfa\xed\xfe\x07\x00\x00\x01\x03\x00\x00\x00" if "macos" in target
                        else b"lib")

    monkeypatch.setattr(native_build, "_compile", compile_stub)
    monkeypatch.setattr(native_build, "zig_cache_dir", lambda: tmp_path / "empty-cache")
    monkeypatch.setattr(papwc.progress, "_NOTED", set())
    stream = io.StringIO()
    with Progress("papwc build", stream=stream, tty=False):
        native_build.compile_binaries(tmp_path / "one", "Plant")
        native_build.compile_binaries(tmp_path / "two", "Plant")
    lines = stream.getvalue().splitlines()
    note = [line for line in lines if "zig's C runtimes" in line]
    assert note == [f"papwc build: the first build compiles zig's C runtimes for linux64, "
                    f"win64, darwin64 into {tmp_path / 'empty-cache'}: a few minutes, once; "
                    "later builds take seconds"]
    for platform, target in (("linux64", "x86_64-linux-gnu.2.17"),
                             ("win64", "x86_64-windows-gnu"), ("darwin64", "x86_64-macos.10.13"),
                             ("darwin64", "aarch64-macos.11.0")):
        assert lines.count(f"papwc build: compiling Plant.fmu's C sources for {platform} "
                           f"({target}) with zig") == 2
