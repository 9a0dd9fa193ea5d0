"""What papwc's documentation makes at build time (a local Sphinx extension).

At ``builder-inited``, into ``docs/_generated/`` (git-ignored; the pages include it):

- ``fields.md`` and ``variables-<FMU>.md``: the reference tables, from the model layer
  (:func:`papwc.fmubuild.docs.docs_tables`);
- ``reproduce/``: what ``papwc reproduce --out DIR`` writes, run anew at every build, and
  ``paper-report.md`` / ``paper-figures.md`` made from it for *The paper reproduced*.

At ``build-finished``: every tutorial of the gallery ran in at most ``TUTORIAL_SECONDS_MAX``
seconds (``tutorial_seconds_max`` in conf.py), else the build fails naming it.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from sphinx.application import Sphinx
from sphinx.errors import ExtensionError
from sphinx.util import logging

LOG = logging.getLogger(__name__)

#: The figures of ``papwc reproduce``, each with what it shows (the order of the page).
PAPER_FIGURES = (
    ("fig1.png", "Figure 1: the pulse displacement of Eq. (3) against the model of Eq. (4)"),
    ("fig3.png", "Figure 3: the error of the adaptive PWC, first and last iteration"),
    ("fig4.png", "Figure 4: the error of the adaptive PAPWC"),
    ("fig5.png", "Figure 5: the pulse height f_p of the adaptive PWC"),
    ("fig6.png", "Figure 6: the pulse height f_p of the adaptive PAPWC"),
    ("fig7.png", "Figure 7: b_hat of the adaptive PWC"),
    ("fig8.png", "Figure 8: b_hat of the adaptive PAPWC"),
    ("fig9.png", "Figure 9: f_c_hat of the adaptive PAPWC"),
    ("fig_exact.png", "Beyond the paper: the error of the exact-model controller"),
)


def write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` unless it holds it already (Sphinx then rereads nothing)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def generate_tables(out: Path) -> None:
    """The reference tables from the model layer."""
    from papwc.fmubuild.docs import docs_tables

    for name, table in docs_tables().items():
        write_if_changed(out / f"{name}.md", table + "\n")


def paper_report(report: str) -> str:
    """``report.md`` of ``papwc reproduce`` as a part of a page: its title line and the line
    that names the scenario's path on the build machine left out, its headings one level
    lower, its figure list left to the figures page."""
    lines = report.splitlines()
    kept = []
    for line in lines[1:]:
        if line.startswith("Scenario: ") or line.startswith("Figures: "):
            continue
        kept.append("#" + line if line.startswith("#") else line)
    return "\n".join(kept).strip() + "\n"


def generate_paper(out: Path) -> None:
    """Run ``papwc reproduce --out _generated/reproduce`` and make the paper's page parts."""
    target = out / "reproduce"
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "papwc.cli", "reproduce", "--out", str(target)],
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise ExtensionError(f"papwc reproduce --out {target} failed "
                             f"(exit {done.returncode}): {done.stderr.strip()[-2000:]}")
    LOG.info("papwc reproduce: %.1f s", time.perf_counter() - started)
    report = (target / "report.md").read_text(encoding="utf-8")
    write_if_changed(out / "paper-report.md", paper_report(report))
    figures = []
    for name, caption in PAPER_FIGURES:
        if not (target / name).is_file():
            raise ExtensionError(f"papwc reproduce wrote no {name} into {target}")
        figures.append(f"```{{figure}} /_generated/reproduce/{name}\n"
                       f":alt: {caption}\n:width: 90%\n\n"
                       f"{caption} (`results/reproduce/{name}`)\n```\n")
    write_if_changed(out / "paper-figures.md", "\n".join(figures))


def on_builder_inited(app: Sphinx) -> None:
    """Make ``_generated/`` before any page is read."""
    out = Path(app.srcdir) / "_generated"
    generate_tables(out)
    generate_paper(out)


#: A line of sphinx-gallery's ``sg_execution_times`` with an example's time (mm:ss.fff).
_TIME_LINE = re.compile(r"``(?P<name>[\w.]+\.py)``\)\s*\n\s*-\s*(?P<m>\d+):(?P<s>\d+\.\d+)")


def tutorial_times(text: str) -> dict[str, float]:
    """The seconds each tutorial took, from sphinx-gallery's ``sg_execution_times.rst``."""
    return {m["name"]: int(m["m"]) * 60 + float(m["s"]) for m in _TIME_LINE.finditer(text)}


def on_build_finished(app: Sphinx, exception: Exception | None) -> None:
    """Fail the build when a tutorial ran longer than ``TUTORIAL_SECONDS_MAX``."""
    if exception is not None:
        return
    limit = app.config.tutorial_seconds_max
    for gallery in app.config.sphinx_gallery_conf["gallery_dirs"]:
        times_file = Path(app.srcdir) / gallery / "sg_execution_times.rst"
        if not times_file.is_file():
            continue
        for name, seconds in tutorial_times(times_file.read_text(encoding="utf-8")).items():
            LOG.info("tutorial %s: %.1f s", name, seconds)
            if seconds > limit:
                raise ExtensionError(f"tutorial {gallery}/{name} ran {seconds:.1f} s, "
                                     f"over the {limit:.0f} s a tutorial may take")


def cli_parser() -> argparse.ArgumentParser:
    """``papwc``'s parser (:func:`papwc.cli.make_parser`) for sphinx-argparse.

    Each subcommand's epilog is written for a terminal (examples laid out with spaces, as
    ``RawDescriptionHelpFormatter`` prints them): here it becomes a literal block, the same
    text, so reST keeps its layout. The parser of the command itself is unchanged.
    """
    from papwc.cli import make_parser

    parser = make_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                if sub.epilog:
                    sub.epilog = "::\n\n" + textwrap.indent(sub.epilog.strip("\n"), "    ")
    return parser


def setup(app: Sphinx) -> dict:
    """Register the build-time generation and the tutorials' time check."""
    app.add_config_value("tutorial_seconds_max", 30.0, "env")
    app.connect("builder-inited", on_builder_inited)
    app.connect("build-finished", on_build_finished)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}


__all__ = ["cli_parser", "generate_paper", "generate_tables", "paper_report", "setup",
           "tutorial_times", "write_if_changed"]
