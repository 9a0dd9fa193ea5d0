"""``papwc hostenv``: the line a non-Python FMI host needs for this interpreter; the new
subcommands keep ``papwc --help`` free of fmpy, numpy, matplotlib and pythonfmu."""

from __future__ import annotations

import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from papwc.cli import main
from papwc.errors import PapwcError
from papwc.host_environment import host_environment, libpython


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="LD_PRELOAD is Linux's")
def test_linux_line_names_this_interpreters_libpython(capsys) -> None:
    path = libpython()
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    assert path.is_file() and path.name.startswith(f"libpython{version}.so")
    own = Path(sysconfig.get_config_var("LIBDIR") or "/") / (
        sysconfig.get_config_var("INSTSONAME") or "")
    if own.is_file():
        assert path == own
    assert host_environment() == f"export LD_PRELOAD={path}"
    assert main(["hostenv"]) == 0
    assert capsys.readouterr().out == f"export LD_PRELOAD={path}\n"
    assert main(["hostenv", "--value"]) == 0
    assert capsys.readouterr().out == f"{path}\n"


def test_macos_is_refused_in_one_line() -> None:
    with pytest.raises(PapwcError, match="Linux and Windows only"):
        host_environment("darwin")


def test_help_lists_the_new_commands_and_imports_nothing_heavy() -> None:
    code = ("import sys; from papwc.cli import make_parser; text = make_parser().format_help(); "
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & "
            "{'fmpy', 'numpy', 'matplotlib', 'pythonfmu', 'libcosimpy', 'ecospy'}); "
            "print(heavy, 'cosim' in text, 'hostenv' in text)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, check=True)
    assert done.stdout.strip() == "[] True True"


@pytest.mark.parametrize(("path", "line"), [
    ("/opt/py$x/lib/libpython3.11.so.1.0",
     "export LD_PRELOAD='/opt/py$x/lib/libpython3.11.so.1.0'"),
    ("/opt/my python/libpython3.11.so.1.0", None), ("/opt/a:b/libpython3.11.so.1.0", None)])
def test_a_library_path_the_shell_or_the_loader_would_split_is_quoted_or_refused(
        path, line, monkeypatch, capsys) -> None:
    """Issue 27: a space in the library path printed an unquoted line; LD_PRELOAD itself is
    split at spaces and colons by the loader, quoted or not, so such a path is refused."""
    import papwc.host_environment

    monkeypatch.setattr(papwc.host_environment, "libpython", lambda: Path(path))
    if line is None:
        assert main(["hostenv"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "LD_PRELOAD cannot hold a path with a space or colon" in err[0]
        return
    assert host_environment("linux") == line
    assert main(["hostenv", "--value"]) == 0
    assert capsys.readouterr().out == f"{path}\n"
