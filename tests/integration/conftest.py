"""Integration tests: every one depends on the session's FMU build (``fmu_dir``), so the
FMUs are built before any test loads an FMU into this process."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _fmus_built_first(fmu_dir: Path) -> None:
    """Build the FMUs (once per session) before the test runs."""


@pytest.fixture
def empty_cwd(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty current folder (nothing may appear in it)."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    return cwd
