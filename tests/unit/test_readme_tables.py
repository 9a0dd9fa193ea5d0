"""The tables of the readmes are the model layer's: regenerated, they do not change."""

from __future__ import annotations

import pytest

from papwc.errors import BuildError
from papwc.fmubuild.docs import readme_tables, sync_readmes, variable_table, with_table
from papwc.fmubuild.fmus import FMUS


def test_every_generated_table_in_the_readmes_is_current() -> None:
    tags = {(path.name, tag) for path, tag, _ in readme_tables()}
    assert ("readme.md", "variables") in tags
    assert ("README.md", "fields") in tags  # the tests run from a checkout
    assert sync_readmes(check=True) == [], "run: python -m papwc.fmubuild.docs"


def test_the_variable_table_lists_every_variable_of_the_recipe_with_its_range() -> None:
    for recipe in FMUS:
        table = variable_table(recipe.variables)
        for var in recipe.variables:
            assert f"| `{var.name}` | {var.causality} | {var.type} |" in table
    plant = next(r for r in FMUS if r.name == "FrictionPlant")
    assert "| `m` | parameter | Real | kg | 150.0 | 1e-06 <= m <= 1e+09 kg | Mass |" in \
        variable_table(plant.variables)


def test_a_readme_without_its_markers_is_refused_naming_the_file() -> None:
    with pytest.raises(BuildError, match=r"x\.md: needs one line '<!-- variables: begin -->'"):
        with_table("no markers", "| t |", "variables", "x.md")
    text = "a\n<!-- variables: begin -->\nold\n<!-- variables: end -->\nb"
    assert with_table(text, "new", "variables", "x.md") == \
        "a\n<!-- variables: begin -->\nnew\n<!-- variables: end -->\nb"
