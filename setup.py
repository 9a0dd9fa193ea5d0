"""The build step pyproject.toml cannot declare: data and native binaries into the package.

When papwc is installed (a wheel, or an editable install of a checkout), ``build_py`` also

- copies ``fmu_src/`` and ``scenarios/`` into the package as ``papwc/_data/`` (a wheel only:
  a checkout reads them in place), read through ``importlib.resources``
  (:mod:`papwc.resources`);
- compiles the native FMUs' binaries with zig (``ziglang``, a build requirement) into
  ``papwc/_native/`` (:mod:`papwc.fmubuild.prebuilt`), so that ``papwc build`` runs no compiler
  unless the FMU sources change. In an editable install they go into the checkout's
  ``controller/papwc/_native/`` (not tracked by git).
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
#: The top-level folders a wheel carries as package data under papwc/_data/.
DATA = ("fmu_src", "scenarios")


class BuildPy(build_py):
    """``build_py`` that adds papwc's data files and compiles its native FMUs' binaries."""

    def run(self) -> None:
        super().run()
        editable = getattr(self, "editable_mode", False)
        package = (ROOT / "controller" / "papwc") if editable else Path(self.build_lib) / "papwc"
        if not editable:
            for name in DATA:
                target = package / "_data" / name
                shutil.rmtree(target, ignore_errors=True)
                shutil.copytree(ROOT / name, target,
                                ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        sys.path.insert(0, str(ROOT / "controller"))
        try:
            from papwc.fmubuild.prebuilt import compile_all

            compile_all(package / "_native", log=lambda line: print(line, flush=True))
        finally:
            sys.path.remove(str(ROOT / "controller"))


setup(cmdclass={"build_py": BuildPy})
