"""The Examples of the API users call run as doctests: what the documentation shows is what
the code does. numpydoc's validation of the same docstrings is ``tests/docs/test_docstrings.py``."""

from __future__ import annotations

import doctest
import importlib

import pytest

#: Modules whose examples run in the quick loop (each takes well under a second).
QUICK = (
    "papwc.master.closed_loop",
    "papwc.controllers.interface",
    "papwc.model.dynamics",
    "papwc.scenario",
    "papwc.identify",
    "papwc.identify.log_file",
    "papwc.fmubuild.docs",
)
#: Modules whose examples identify a 60 s log, build an FMU or run a battery (seconds).
SLOW = ("papwc.identify.fit", "papwc.battery.orchestrate")


def run_examples(name: str) -> doctest.TestResults:
    module = importlib.import_module(name)
    return doctest.testmod(module, optionflags=doctest.ELLIPSIS, verbose=False)


@pytest.mark.parametrize("name", QUICK)
def test_the_examples_of_the_module_hold(name: str) -> None:
    results = run_examples(name)
    assert results.attempted > 0, f"{name} has no example"
    assert results.failed == 0


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW)
def test_the_examples_that_take_seconds_hold(name: str) -> None:
    results = run_examples(name)
    assert results.attempted > 0, f"{name} has no example"
    assert results.failed == 0


def test_a_wrong_example_fails() -> None:
    """The check can fail: an example whose shown output is not what the code gives."""
    import types

    module = types.ModuleType("papwc_doctest_probe")
    module.__doc__ = ">>> 1 + 1\n3\n"
    results = doctest.testmod(module, verbose=False, report=False)
    assert (results.attempted, results.failed) == (1, 1)
