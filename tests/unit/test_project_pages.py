"""The README and the CHANGELOG keep their form: a short README whose links work in a
checkout, holding the two set-up commands CI runs; a Keep a Changelog file whose top release is
the package's version."""

from __future__ import annotations

import re

import papwc

#: What .ci/run extracts from the README (its sed expression, as a Python pattern).
CI_TEST_COMMAND = re.compile(
    r'^ {4,}(python3 -m venv \.venv && \.venv/bin/pip install -e "\.\[test\]".*)$', re.M)


def test_the_readme_is_short_and_holds_the_set_up_commands(project_dir) -> None:
    readme = (project_dir / "README.md").read_text(encoding="utf-8")
    assert len(readme.encode("utf-8")) <= 8 * 1024
    assert CI_TEST_COMMAND.search(readme) is not None
    assert ("\n    python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/papwc build && "
            ".venv/bin/papwc reproduce --out results/reproduce\n") in readme
    assert "python -m sphinx -W --keep-going -b html docs docs/_build/html" in readme
    assert "|---" not in readme  # result tables live in the documentation's studies


def test_every_relative_link_and_image_of_the_readme_exists(project_dir) -> None:
    readme = (project_dir / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme)
    local = [t for t in targets if "://" not in t]
    assert len(local) >= 10
    missing = [t for t in local if not (project_dir / t).exists()]
    assert missing == []


def test_the_changelog_has_one_unreleased_section_and_the_version_on_top(project_dir) -> None:
    text = (project_dir / "CHANGELOG.md").read_text(encoding="utf-8")
    sections = re.findall(r"^## (.*)$", text, re.M)
    assert sections[0] == "[Unreleased]"
    assert sections.count("[Unreleased]") == 1
    released = [re.fullmatch(r"\[(\d+\.\d+\.\d+)\] - (\d{4}-\d\d-\d\d)", s) for s in sections[1:]]
    assert released and all(released), sections
    assert released[0].group(1) == papwc.__version__
    kinds = set(re.findall(r"^### (.*)$", text, re.M))
    assert kinds <= {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security"}
