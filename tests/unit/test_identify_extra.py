"""Identification is papwc's extra ``identify`` (scipy): without scipy, ``papwc identify``
is refused in one line naming the extra, before it writes anything."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from papwc.cli import main
from papwc.identify import IdentifyError, require_scipy


def test_without_scipy_identification_is_refused_naming_the_extra(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    monkeypatch.setitem(sys.modules, "scipy", None)  # import scipy raises ImportError
    with pytest.raises(IdentifyError, match=r"pip install 'papwc\[identify\]'"):
        require_scipy("papwc identify")
    out = tmp_path / "id"
    assert main(["identify", "--design", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "papwc identify needs scipy" in err[0], err
    assert not out.exists()


def test_with_scipy_nothing_is_refused() -> None:
    pytest.importorskip("scipy")
    require_scipy("papwc identify")


def test_without_scipy_a_battery_that_identifies_first_is_refused_naming_its_file(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from papwc.battery.identify_first import check_excitable
    from papwc.errors import ScenarioError

    monkeypatch.setitem(sys.modules, "scipy", None)
    variables = {"u": ("input", "Real"), "x_meas": ("output", "Real")}
    with pytest.raises(ScenarioError, match=r"^mc\.toml: \[battery\] identify_first = true "
                       r"needs scipy.*papwc\[identify\]"):
        check_excitable("mc.toml", variables, {0.01})
