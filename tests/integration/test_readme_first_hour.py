"""A newcomer's first hour (issue 27): the main job and the examples that take seconds, as
the documentation's *Getting started* page (``docs/getting-started.md``) gives them, run
verbatim, in order, on a fresh copy of the checkout, with the venv's commands on ``PATH`` as
after ``. .venv/bin/activate``. The README gives the same main job.

The copy's ``.venv`` is the venv running the tests (linked; installing one afresh is what CI
does with the README's set-up commands) and ``PYTHONPATH`` points at the copy's package, so
the copy's code runs as its editable install would.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

PROJECT = Path(__file__).resolve().parents[2]
README = (PROJECT / "README.md").read_text(encoding="utf-8")
#: The page the commands are run from.
GETTING_STARTED = (PROJECT / "docs" / "getting-started.md").read_text(encoding="utf-8")
MAIN_JOB = ("python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/papwc build && "
            ".venv/bin/papwc reproduce --out results/reproduce")
#: The examples run, each as the page writes it (checked below), in the page's order.
EXAMPLES = [
    "fmpy simulate build/FrictionPlant.fmu --output-interval 0.01 --stop-time 1 \\\n"
    "    --input-file scenarios/pulse_in.csv --output-file pulse_out.csv",
    "papwc run scenarios/paper.toml --out results/paper",
    "papwc cosim build/ClosedLoop.ssp",
    "ecos simulate --path build/ClosedLoop.ssp --stepSize 0.01 --stopTime 2 "
    "--parameterSet scenario",
]


def fresh_copy(target: Path) -> Path:
    """The checkout's files as a fresh clone has them (no results, no build outputs)."""
    skip = {".git", ".venv", "results", ".setuptools-build", "__pycache__", ".pytest_cache",
            ".ruff_cache", ".hypothesis"}

    def ignore(folder: str, names: list[str]) -> set[str]:
        here = Path(folder)
        out = {n for n in names if n in skip or n.endswith(".egg-info")}
        if here != PROJECT:  # results/ of the checkout's root only (not papwc.results)
            out.discard("results")
        if here == PROJECT / "build":
            out |= {n for n in names if n != ".gitignore"}
        if here == PROJECT / "docs":  # what the documentation's build makes
            out |= {"_build", "_generated", "tutorials"} & set(names)
        if here == PROJECT / "docs" / "reference":
            out |= {"generated"} & set(names)
        return out

    shutil.copytree(PROJECT, target, ignore=ignore, symlinks=True)
    return target


def sh(command: str, cwd: Path, env: dict) -> subprocess.CompletedProcess:
    done = subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900, check=False)
    assert done.returncode == 0, f"{command}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    return done


def test_the_main_job_and_the_examples_run_verbatim_in_order(tmp_path) -> None:
    if sys.prefix == sys.base_prefix:
        pytest.skip("needs the tests to run in a venv (the README's .venv)")
    assert MAIN_JOB in README
    for text in (MAIN_JOB, *EXAMPLES):
        assert f"```bash\n{text}\n```" in GETTING_STARTED, text
    order = [GETTING_STARTED.index(text) for text in (MAIN_JOB, *EXAMPLES)]
    assert order == sorted(order)
    assert ". .venv/bin/activate" in GETTING_STARTED
    copy = fresh_copy(tmp_path / "papwc")
    (copy / ".venv").symlink_to(sys.prefix, target_is_directory=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PAPWC_FMU_STDERR", "PYTHONPATH")}
    env["PYTHONPATH"] = str(copy / "controller")
    env["PATH"] = f"{copy / '.venv' / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["VIRTUAL_ENV"] = str(copy / ".venv")

    # the main job, after its two set-up commands (the venv and its install)
    steps = MAIN_JOB.split(" && ")
    assert steps[:2] == ["python3 -m venv .venv", ".venv/bin/pip install -e ."]
    for step in steps[2:]:
        sh(step, copy, env)
    assert (copy / "build" / "FrictionPlant.fmu").is_file()
    assert (copy / "results" / "reproduce" / "report.md").is_file()
    assert not (copy / "results" / "reproduce" / "fmu").exists()  # it used build/

    # fmpy on the plant: the rows the page shows
    sh(EXAMPLES[0].replace("\\\n", " "), copy, env)
    block = GETTING_STARTED[GETTING_STARTED.index(EXAMPLES[0]):].split("writes\n\n```text\n", 1)[1]
    shown = block.split("\n```", 1)[0].splitlines()
    assert (copy / "pulse_out.csv").read_text().splitlines()[:len(shown)] == shown

    sh(EXAMPLES[1], copy, env)
    assert (copy / "results" / "paper" / "summary.csv").is_file()
    done = sh(EXAMPLES[2], copy, env)
    assert (copy / "results" / "cosim" / "ClosedLoop.csv").is_file(), done.stdout

    # ecos: the venv's console script (papwc.host_environment:ecos_main), after a fresh install
    if shutil.which("ecos", path=env["PATH"]) is None:
        if os.environ.get("CI") == "true":
            pytest.fail("no ecos on PATH after the test install")
        pytest.skip("this venv was installed before papwc's ecos console script existed")
    command = EXAMPLES[3].replace("\n", "; ")
    sh(command, copy, env)
