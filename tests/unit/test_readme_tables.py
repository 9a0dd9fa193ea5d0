"""The generated tables are the model layer's: the FMU readmes' are current, and the
documentation's reference pages include the tables made from it at their build."""

from __future__ import annotations

import pytest

from papwc.errors import BuildError
from papwc.fmubuild.docs import docs_tables, readme_tables, sync_readmes, variable_table, with_table
from papwc.fmubuild.fmus import FMUS
from papwc.model.controller_settings import CONTROLLER_SETTINGS
from papwc.model.maneuver import MANEUVER_VARIABLES


def test_every_generated_table_in_the_fmu_readmes_is_current() -> None:
    tags = {(path.parent.name, tag) for path, tag, _ in readme_tables()}
    assert ("FrictionPlant", "variables") in tags
    assert sync_readmes(check=True) == [], "run: python -m papwc.fmubuild.docs"


def test_the_variable_table_lists_every_variable_of_the_recipe_with_its_range() -> None:
    for recipe in FMUS:
        table = variable_table(recipe.variables)
        for var in recipe.variables:
            assert f"| `{var.name}` | {var.causality} | {var.type} |" in table
    plant = next(r for r in FMUS if r.name == "FrictionPlant")
    assert "| `m` | parameter | Real | kg | 150.0 | 1e-06 <= m <= 1e+09 kg | Mass |" in \
        variable_table(plant.variables)


def test_the_documentation_includes_every_table_the_model_layer_makes(project_dir) -> None:
    tables = docs_tables()
    assert set(tables) == {"fields"} | {f"variables-{r.name}" for r in FMUS}
    for var in MANEUVER_VARIABLES + CONTROLLER_SETTINGS:
        assert f"`{var.name}` |" in tables["fields"]
    # a | inside a cell is escaped, so the Markdown table keeps its columns
    v_s = next(line for line in tables["fields"].splitlines() if "`v_s`" in line)
    assert "exp(-(\\|v\\|/v_s)" in v_s
    assert v_s.replace("\\|", "").count("|") == 7
    pages = {"fields": "reference/scenario-fields.md", "variables": "reference/fmu-variables.md"}
    for name in tables:
        page = (project_dir / "docs" / pages[name.split("-")[0]]).read_text(encoding="utf-8")
        assert f"```{{include}} ../_generated/{name}.md\n```" in page, name


def test_a_readme_without_its_markers_is_refused_naming_the_file() -> None:
    with pytest.raises(BuildError, match=r"x\.md: needs one line '<!-- variables: begin -->'"):
        with_table("no markers", "| t |", "variables", "x.md")
    text = "a\n<!-- variables: begin -->\nold\n<!-- variables: end -->\nb"
    assert with_table(text, "new", "variables", "x.md") == \
        "a\n<!-- variables: begin -->\nnew\n<!-- variables: end -->\nb"
