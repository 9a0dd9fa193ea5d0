"""Shared fixtures and hooks of the test suite.

- ``tests/unit/``: fast tests of the model layer, the controllers and estimators,
  settings and scenario validation, and the master with in-process slaves;
- ``tests/integration/``: FMUs built and run (fmpy, libcosim, SSP), the command
  line, batteries and Dask;
- ``tests/studies/``: the studies beside the package (``papwc_studies``), marked ``study``
  and ``slow``: outside the quick loop and outside the default selection (pyproject's
  ``-m "not study and not docs"``); ``pytest -m study`` runs them (CI does, after the suite);
- ``tests/docs/``: the docstrings validated by numpydoc and the built documentation in a
  browser, marked ``docs`` and ``slow``: outside the default selection; CI runs
  ``pytest -m docs`` after building the site (they need the ``docs`` extra).

The project's FMUs are built once per session by :func:`papwc.fmubuild.fmus.build_all`
into a temporary folder (fixture ``fmu_dir``; FrictionPlant is the native FMU, compiled by
zig for every platform once, and the pythonfmu FrictionPlant is built beside it in
``fmu_dir/pythonfmu/``); ``tests/integration/conftest.py`` has
every integration test depend on it, so the FMUs are built before any FMU is loaded
into this process (a loaded pythonfmu FMU puts its bundled ``pythonfmu`` copy into
``sys.modules``, after which building fails).

Tests marked ``libcosim`` or ``dask`` are skipped, not errors, when libcosimpy or dask
is not installed (the ``cosim`` and ``dask`` extras). Every test under ``tests/unit/``
is marked ``unit``, every test under ``tests/integration/`` ``integration``, every test
under ``tests/studies/`` ``study``, every test under ``tests/docs/`` ``docs``.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from papwc.fmubuild.fmus import build_all, build_fmu

TESTS_DIR = Path(__file__).resolve().parent
PROJECT_DIR = TESTS_DIR.parent

#: Marker -> the module an extra provides.
EXTRA_MODULES = {"libcosim": "libcosimpy", "dask": "dask.distributed"}


def module_missing(name: str) -> bool:
    """Whether module ``name`` cannot be imported (checked without importing it)."""
    try:
        return importlib.util.find_spec(name) is None
    except (ImportError, ValueError, AttributeError):  # a parent is missing, or blocked
        return True


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark unit and integration tests by folder; skip tests whose extra is missing.

    Integration tests are slow too (they build FMUs once and run them: seconds), so that
    ``pytest -m "not slow"`` is the quick loop.
    """
    for item in items:
        path = Path(str(item.path)).resolve()
        for folder, marker in (("unit", "unit"), ("integration", "integration"),
                               ("studies", "study"), ("docs", "docs")):
            if (TESTS_DIR / folder) in path.parents:
                item.add_marker(getattr(pytest.mark, marker))
                if folder != "unit":
                    item.add_marker(pytest.mark.slow)
        for marker, module in EXTRA_MODULES.items():
            if item.get_closest_marker(marker) is not None and module_missing(module):
                item.add_marker(pytest.mark.skip(
                    reason=f"needs {module} (install the extra: pip install -e '.[test]')"))


@pytest.fixture(scope="session")
def project_dir() -> Path:
    """Root of the project (the folder holding pyproject.toml)."""
    return PROJECT_DIR


@pytest.fixture(scope="session")
def paper_toml() -> Path:
    """The shipped scenario of the paper."""
    return PROJECT_DIR / "scenarios" / "paper.toml"


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Folder holding FrictionPlant.fmu, PulseController.fmu, PulseControllerPython.fmu and
    PapwcTrivial.fmu.

    Built once per session, all FMUs before any is loaded (see the module docstring).
    """
    out = tmp_path_factory.mktemp("fmus")
    build_all(out)
    build_fmu("FrictionPlant", out / "pythonfmu", backend="pythonfmu")
    return out


@pytest.fixture(scope="session")
def friction_plant_fmu(fmu_dir: Path) -> Path:
    """Path of the built FrictionPlant.fmu (the native one, ``papwc build``'s default)."""
    return fmu_dir / "FrictionPlant.fmu"


@pytest.fixture(scope="session")
def pythonfmu_plant_fmu(fmu_dir: Path) -> Path:
    """Path of FrictionPlant.fmu built with pythonfmu (``papwc build --backend pythonfmu``)."""
    return fmu_dir / "pythonfmu" / "FrictionPlant.fmu"


@pytest.fixture(scope="session")
def pulse_controller_fmu(fmu_dir: Path) -> Path:
    """Path of the built PulseController.fmu (native: the C controller, pwc, papwc, pid)."""
    return fmu_dir / "PulseController.fmu"


@pytest.fixture(scope="session")
def pulse_controller_python_fmu(fmu_dir: Path) -> Path:
    """Path of the built PulseControllerPython.fmu (pythonfmu: every controller kind)."""
    return fmu_dir / "PulseControllerPython.fmu"


@pytest.fixture(scope="session")
def trivial_fmu(fmu_dir: Path) -> Path:
    """Path of the built PapwcTrivial.fmu."""
    return fmu_dir / "PapwcTrivial.fmu"


def _extract(fmu: Path, tmp_path_factory: pytest.TempPathFactory, name: str) -> Path:
    from fmpy import extract

    return Path(extract(str(fmu), str(tmp_path_factory.mktemp(name))))


@pytest.fixture(scope="session")
def friction_plant_unzipped(
    friction_plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """FrictionPlant.fmu extracted once, for tests that create many instances."""
    return _extract(friction_plant_fmu, tmp_path_factory, "plant")


@pytest.fixture(scope="session")
def pythonfmu_plant_unzipped(
    pythonfmu_plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """The pythonfmu FrictionPlant.fmu extracted once."""
    return _extract(pythonfmu_plant_fmu, tmp_path_factory, "pyplant")


@pytest.fixture(scope="session")
def pulse_controller_unzipped(
    pulse_controller_fmu: Path, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """PulseController.fmu extracted once."""
    return _extract(pulse_controller_fmu, tmp_path_factory, "controller")


@pytest.fixture(scope="session")
def pulse_controller_python_unzipped(
    pulse_controller_python_fmu: Path, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """PulseControllerPython.fmu extracted once."""
    return _extract(pulse_controller_python_fmu, tmp_path_factory, "pycontroller")
