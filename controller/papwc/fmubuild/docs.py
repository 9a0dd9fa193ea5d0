"""The tables of the readmes and of the documentation site, written from the model layer.

Each ``fmu_src/<Model>/readme.md`` holds its FMU's variable table between the
lines ``<!-- variables: begin -->`` and ``<!-- variables: end -->``; the table is
made from the FMU's recipe (:data:`papwc.fmubuild.fmus.FMUS`), so a parameter
added to the model layer appears in the readme as it does in the model
description. ``python -m papwc.fmubuild.docs`` rewrites those tables; ``--check``
only says which file differs (a test runs it).

The documentation site (``docs/``) makes its reference tables at build time from
:func:`docs_tables`: every scenario field (:func:`papwc.scenario.field_table`) and each
FMU's variables.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from papwc.controllers import CONTROLLER_KINDS
from papwc.errors import BuildError
from papwc.fmubuild.fmus import FMUS
from papwc.fmubuild.model_description import xml_number
from papwc.model.variables import Variable

__all__ = ["docs_tables", "escape_cell", "readme_tables", "sync_readmes", "variable_table",
           "with_table"]


def _start(var: Variable) -> str:
    if var.causality == "output" and var.initial == "calculated":
        return "calculated"
    if var.switch:
        return f"{xml_number(var.fmi_start)} (read only if `{var.switch}`)"
    return xml_number(var.fmi_start)


def variable_table(variables: Sequence[Variable], escape_bars: bool = False) -> str:
    """The Markdown table of an FMU's variables: name, causality, type, unit, start, range.

    Parameters
    ----------
    variables : sequence of Variable
        The FMU's variables, in the model description's order.
    escape_bars : bool
        Write a ``|`` inside a cell as ``\\|`` (the documentation site's tables; the
        readmes keep theirs as they are).

    Returns
    -------
    str
        The table, one line per variable after the header.
    """
    lines = ["| name | causality | type | unit | start | allowed | description |",
             "|---|---|---|---|---|---|---|"]
    for var in variables:
        allowed = var.allowed_text() if var.causality == "parameter" else ""
        if var.name == "kind" and var.type == "String":
            allowed = ", ".join(repr(k) for k in sorted(CONTROLLER_KINDS))
        if var.switch:
            allowed += (f"; `{var.switch}` = false selects "
                        + ("the default" if var.optional else "no bound"))
        kinds = f" (kinds: {', '.join(var.kinds)})" if var.kinds else ""
        unit = var.unit if var.unit not in ("", "1") else "–"
        allowed, description = allowed or "–", f"{var.description}{kinds}"
        if escape_bars:
            allowed, description = escape_cell(allowed), escape_cell(description)
        lines.append(f"| `{var.name}` | {var.causality} | {var.type} | {unit} | {_start(var)} "
                     f"| {allowed} | {description} |")
    return "\n".join(lines)


def with_table(text: str, table: str, tag: str, where: str) -> str:
    """``text`` with the lines between ``<!-- tag: begin -->`` and ``<!-- tag: end -->`` new."""
    begin, end = f"<!-- {tag}: begin -->", f"<!-- {tag}: end -->"
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise BuildError(f"{where}: needs one line {begin!r} and, after it, one {end!r}")
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{begin}\n{table}\n{end}{tail}"


def escape_cell(text: str) -> str:
    """``text`` fit for a cell of a Markdown table: every ``|`` written ``\\|``."""
    return text.replace("|", "\\|")


def readme_tables() -> list[tuple[Path, str, str]]:
    """Each FMU readme with a generated table: (path, tag, table)."""
    found, seen = [], set()
    for recipe in FMUS:  # (the two controller builds share one readme and their variables)
        path = recipe.folder / "readme.md"
        if path.is_file() and path not in seen:
            seen.add(path)
            found.append((path, "variables", variable_table(recipe.variables)))
    return found


def docs_tables() -> dict[str, str]:
    """The tables the documentation site includes, by name.

    Returns
    -------
    dict of str to str
        ``"fields"``: every field of a scenario file (:func:`papwc.scenario.field_table`);
        ``"variables-<FMU>"``: the variables of each FMU of :data:`~papwc.fmubuild.fmus.FMUS`.
        Each a Markdown table whose cells escape ``|``.

    Examples
    --------
    >>> tables = docs_tables()
    >>> sorted(tables)[:2]
    ['fields', 'variables-FrictionPlant']
    >>> "| [plant] | `m` | kg | 150.0 |" in tables["fields"]
    True
    """
    from papwc.scenario import field_table

    tables = {"fields": field_table()}
    for recipe in FMUS:
        tables[f"variables-{recipe.name}"] = variable_table(recipe.variables, escape_bars=True)
    return tables


def sync_readmes(check: bool = False) -> list[Path]:
    """Rewrite (or, with ``check``, only compare) every generated table.

    Returns the files whose table differed.
    """
    differ = []
    for path, tag, table in readme_tables():
        text = path.read_text(encoding="utf-8")
        new = with_table(text, table, tag, str(path))
        if new != text:
            differ.append(path)
            if not check:
                path.write_text(new, encoding="utf-8")
    return differ


def main(argv: list[str] | None = None) -> int:
    """Command line: rewrite the tables (or ``--check``); print the files that differed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="only say which file's table differs (exit 1 if one does)")
    args = parser.parse_args(argv)
    try:
        differ = sync_readmes(check=args.check)
    except BuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for path in differ:
        print(f"{path}: {'differs' if args.check else 'rewritten'}")
    return 1 if (differ and args.check) else 0


if __name__ == "__main__":
    sys.exit(main())
