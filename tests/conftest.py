"""Shared fixtures: the project's FMUs, built once per test session into a temporary folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from papwc.fmubuild.fmus import build_all


@pytest.fixture(scope="session")
def project_dir() -> Path:
    """Root of the project (the folder holding pyproject.toml)."""
    return Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Folder holding FrictionPlant.fmu and PapwcTrivial.fmu, built once per session.

    All FMUs are built here before any is loaded: a pythonfmu FMU loaded into this
    process puts its bundled ``pythonfmu`` copy into ``sys.modules``.
    """
    out = tmp_path_factory.mktemp("fmus")
    build_all(out)
    return out


@pytest.fixture(scope="session")
def friction_plant_fmu(fmu_dir: Path) -> Path:
    """Path of the built FrictionPlant.fmu."""
    return fmu_dir / "FrictionPlant.fmu"


@pytest.fixture(scope="session")
def pulse_controller_fmu(fmu_dir: Path) -> Path:
    """Path of the built PulseController.fmu."""
    return fmu_dir / "PulseController.fmu"


@pytest.fixture(scope="session")
def trivial_fmu(fmu_dir: Path) -> Path:
    """Path of the built PapwcTrivial.fmu."""
    return fmu_dir / "PapwcTrivial.fmu"


@pytest.fixture(scope="session")
def friction_plant_unzipped(
    friction_plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """FrictionPlant.fmu extracted once, for tests that create many instances."""
    from fmpy import extract

    return Path(extract(str(friction_plant_fmu), str(tmp_path_factory.mktemp("plant"))))
