"""Where the project's data files are: FMU sources and scenario files.

Nothing here depends on the current folder. From a checkout (an editable
install), the files are read in place: ``fmu_src/`` and ``scenarios/`` beside
``controller/``. A wheel carries them as package data, ``papwc/_data/fmu_src/`` and
``papwc/_data/scenarios/`` (copied there by the build, ``setup.py``), read through
:mod:`importlib.resources`.
"""

from __future__ import annotations

from functools import cache
from importlib import resources
from pathlib import Path

from papwc.errors import PapwcError

__all__ = ["checkout_root", "data_root", "fmu_src_dir", "scenario_file", "scenarios_dir"]

#: A file that marks a folder holding the project's data.
_MARKER = Path("fmu_src") / "FrictionPlant" / "FrictionPlant.py"


@cache
def checkout_root() -> Path | None:
    """The project folder when papwc runs from a checkout (controller/papwc/...), else None."""
    root = Path(__file__).resolve().parents[2]
    if (root / _MARKER).is_file() and (root / "pyproject.toml").is_file():
        return root
    return None


@cache
def data_root() -> Path:
    """The folder holding ``fmu_src/`` and ``scenarios/``.

    Raises
    ------
    PapwcError
        If neither a checkout nor an installed copy is found.
    """
    root = checkout_root()
    if root is not None:
        return root
    installed = Path(str(resources.files("papwc") / "_data"))
    if (installed / _MARKER).is_file():
        return installed
    raise PapwcError("the papwc data files (fmu_src/, scenarios/) were not found: not in a "
                     f"checkout, and {installed} does not hold them; reinstall papwc")


def fmu_src_dir() -> Path:
    """Folder of the FMU sources (one sub-folder per model)."""
    return data_root() / "fmu_src"


def scenarios_dir() -> Path:
    """Folder of the shipped scenario files."""
    return data_root() / "scenarios"


def scenario_file(name: str) -> Path:
    """A shipped scenario file by name (``"paper.toml"``)."""
    return scenarios_dir() / name
