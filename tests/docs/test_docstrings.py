"""The docstrings of the API users call, validated by numpydoc (as python-control's docstring
test does): each public function, class and method has one, its Parameters section documents
the signature's parameters (no more, no fewer, in order), a function that returns something
has a Returns section, and the entry points have Examples (run as doctests by
``tests/unit/test_doctests.py``). Needs the ``docs`` extra (numpydoc)."""

from __future__ import annotations

import importlib
import inspect

import pytest

validate = pytest.importorskip("numpydoc.validate").validate

#: The modules of the API users call: each public function, class and method is validated.
MODULES = (
    "papwc.master.closed_loop",
    "papwc.controllers.interface",
    "papwc.model.dynamics",
    "papwc.scenario",
    "papwc.battery.orchestrate",
    "papwc.identify",
)
#: Further entry points (papwc.identify's own functions live in its modules).
FUNCTIONS = (
    "papwc.identify.fit.identify",
    "papwc.identify.log_file.read_log",
    "papwc.identify.log_file.parse_log",
)
#: The entry points, which must show their use in an Examples section.
WITH_EXAMPLES = (
    "papwc.master.closed_loop.Maneuver",
    "papwc.master.closed_loop.run_closed_loop",
    "papwc.master.closed_loop.run_controller",
    "papwc.controllers.interface.Controller",
    "papwc.model.dynamics.Plant",
    "papwc.model.dynamics.Plant.step",
    "papwc.scenario.load_scenario",
    "papwc.scenario.parse_scenario",
    "papwc.battery.orchestrate.run_battery",
    "papwc.identify",
    "papwc.identify.fit.identify",
    "papwc.identify.log_file.parse_log",
)
#: numpydoc's checks that must pass: a docstring (GL08); the parameters documented are the
#: signature's (PR01 missing, PR02 unknown, PR03 out of order); a summary (SS01).
CHECKS = {"GL08", "PR01", "PR02", "PR03", "SS01"}


def public_objects() -> list[str]:
    """Import paths of every public function, class and method of :data:`MODULES`."""
    paths = list(FUNCTIONS)
    for name in MODULES:
        module = importlib.import_module(name)
        public = getattr(module, "__all__", None)
        if public is None:  # the names the module defines and does not hide
            public = [n for n, v in vars(module).items()
                      if not n.startswith("_") and getattr(v, "__module__", None) == name]
        for member in public:
            obj = getattr(module, member)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue  # constants: documented by their #: comments
            paths.append(f"{name}.{member}")
            if inspect.isclass(obj) and not issubclass(obj, BaseException):
                for attr, value in vars(obj).items():
                    if attr.startswith("_") or not callable(getattr(obj, attr, None)):
                        continue
                    if inspect.isfunction(value) or isinstance(value, (classmethod, staticmethod)):
                        paths.append(f"{name}.{member}.{attr}")
    return paths


def load(path: str) -> object:
    """The object at import path ``path`` (a module, or attributes of one)."""
    parts = path.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(path)


def failures(path: str) -> list[str]:
    """numpydoc's errors of ``path`` among :data:`CHECKS`; RT01 too for a function whose return
    annotation is not None, EX01 too for the entry points."""
    wanted = set(CHECKS)
    if path in WITH_EXAMPLES:
        wanted.add("EX01")
    obj = load(path)
    if inspect.isfunction(obj) or inspect.ismethod(obj):
        returns = inspect.signature(obj).return_annotation
        if returns not in (inspect.Signature.empty, None, "None"):
            wanted.add("RT01")
    return [f"{code}: {message}" for code, message in validate(path)["errors"]
            if code in wanted]


PATHS = [*(m for m in WITH_EXAMPLES if m in MODULES), *public_objects()]


@pytest.mark.parametrize("path", PATHS)
def test_the_docstring_documents_the_signature(path: str) -> None:
    assert failures(path) == []


def test_every_entry_point_is_validated() -> None:
    assert set(WITH_EXAMPLES) <= set(PATHS)
    assert len(PATHS) >= 30


def test_a_missing_parameter_fails_the_validation() -> None:
    """The check can fail: a function whose docstring leaves out a parameter."""
    import types

    module = types.ModuleType("papwc_docstring_probe")

    def probe(a: int, b: int) -> int:
        """Add two numbers.

        Parameters
        ----------
        a : int
            The first.

        Returns
        -------
        int
            The sum.
        """
        return a + b

    probe.__module__ = module.__name__
    module.probe = probe
    import sys

    sys.modules[module.__name__] = module
    try:
        errors = failures("papwc_docstring_probe.probe")
    finally:
        del sys.modules[module.__name__]
    assert any(e.startswith("PR01") and "b" in e for e in errors), errors
