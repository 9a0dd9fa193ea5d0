"""The tables of the readmes, written from the model layer.

Each ``fmu_src/<Model>/readme.md`` holds its FMU's variable table between the
lines ``<!-- variables: begin -->`` and ``<!-- variables: end -->``; the table is
made from the FMU's recipe (:data:`papwc.fmubuild.fmus.FMUS`), so a parameter
added to the model layer appears in the readme as it does in the model
description. The project README (in a source checkout) holds the scenario
fields between ``<!-- fields: begin -->`` and ``<!-- fields: end -->``
(:func:`papwc.scenario.field_table`). ``python -m papwc.fmubuild.docs``
rewrites the tables; ``--check`` only says which file differs (a test runs it).
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
from papwc.resources import checkout_root

__all__ = ["readme_tables", "sync_readmes", "variable_table", "with_table"]


def _start(var: Variable) -> str:
    if var.causality == "output" and var.initial == "calculated":
        return "calculated"
    if var.switch:
        return f"{xml_number(var.fmi_start)} (read only if `{var.switch}`)"
    return xml_number(var.fmi_start)


def variable_table(variables: Sequence[Variable]) -> str:
    """The Markdown table of an FMU's variables: name, causality, type, unit, start, range."""
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
        lines.append(f"| `{var.name}` | {var.causality} | {var.type} | {unit} | {_start(var)} "
                     f"| {allowed or '–'} | {var.description}{kinds} |")
    return "\n".join(lines)


def with_table(text: str, table: str, tag: str, where: str) -> str:
    """``text`` with the lines between ``<!-- tag: begin -->`` and ``<!-- tag: end -->`` new."""
    begin, end = f"<!-- {tag}: begin -->", f"<!-- {tag}: end -->"
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise BuildError(f"{where}: needs one line {begin!r} and, after it, one {end!r}")
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{begin}\n{table}\n{end}{tail}"


def readme_tables() -> list[tuple[Path, str, str]]:
    """Each readme with a generated table: (path, tag, table)."""
    from papwc.scenario import field_table

    found, seen = [], set()
    for recipe in FMUS:  # (the two controller builds share one readme and their variables)
        path = recipe.folder / "readme.md"
        if path.is_file() and path not in seen:
            seen.add(path)
            found.append((path, "variables", variable_table(recipe.variables)))
    root = checkout_root()
    if root is not None and (root / "README.md").is_file():
        found.append((root / "README.md", "fields", field_table()))
    return found


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
