"""Measured figures printed by ``papwc bench``: a registry of sections.

A section is a function ``f(context) -> list[Row]`` registered with
:func:`register_section`; :func:`run_sections` calls every registered section
in order and prints its rows as a small table. The sections are in
:mod:`.plant_calls`, :mod:`.rodas_products`, :mod:`.native_step`, :mod:`.master_step`,
:mod:`.native_controller`, :mod:`.battery_throughput`, :mod:`.update_time`,
:mod:`.realism_time`,
:mod:`.cosim_memory` and :mod:`.identify_time`; add one by writing such a function in a
module imported by :func:`load_sections` and decorating it::

    @register_section("closed loop")
    def closed_loop(context: BenchContext) -> list[Row]:
        ...
        return [Row("master overhead per step", 12.3, "us")]

The FMUs a section needs are in ``context.fmu_dir`` (built once, before any FMU
is loaded into the process); ``context.quick`` asks for fewer iterations. A
section registered with ``option="NAME"`` runs only when ``NAME`` is in
``context.options`` (``papwc bench --NAME``): for measurements that take minutes.

Timings on a shared machine are noisy, so sections measure the things they
compare in the same run, interleaved, and report medians over rounds.
"""

from __future__ import annotations

import gc
import statistics
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from papwc.errors import PapwcError

__all__ = [
    "SECTIONS",
    "BenchContext",
    "Row",
    "Section",
    "format_rows",
    "gc_paused",
    "median_interleaved",
    "register_section",
    "run_sections",
]


@dataclass(frozen=True)
class Row:
    """One measured figure: what, how much, in which unit."""

    label: str
    value: float
    unit: str


@dataclass
class BenchContext:
    """What every section receives.

    Attributes
    ----------
    fmu_dir : Path
        Folder holding the built FMUs (``FrictionPlant.fmu``, ``PapwcTrivial.fmu``, ...).
    quick : bool
        Fewer iterations (a smoke run; the figures are less precise).
    notes : list of str
        Remarks a section adds; printed under its table.
    options : frozenset of str
        Opt-in sections to run as well (see :func:`register_section`).
    """

    fmu_dir: Path
    quick: bool = False
    notes: list[str] = field(default_factory=list)
    options: frozenset[str] = frozenset()

    def fmu(self, name: str) -> Path:
        """Path of the FMU ``name`` (e.g. ``"FrictionPlant.fmu"``) in :attr:`fmu_dir`.

        Raises
        ------
        PapwcError
            If the FMU is not there.
        """
        path = self.fmu_dir / name
        if not path.is_file():
            raise PapwcError(f"bench: {name} not found in {self.fmu_dir}; run `papwc build` first")
        return path


@dataclass(frozen=True)
class Section:
    """A registered section: its title, the function that measures it, its opt-in option."""

    title: str
    measure: Callable[[BenchContext], list[Row]]
    option: str = ""


#: Registered sections, in the order they run.
SECTIONS: list[Section] = []


def register_section(
    title: str, option: str = ""
) -> Callable[[Callable[[BenchContext], list[Row]]], Callable[[BenchContext], list[Row]]]:
    """Decorator: register ``f(context) -> list[Row]`` as a section titled ``title``.

    With ``option``, the section runs only when the option is in ``context.options``.
    """

    def decorator(
        measure: Callable[[BenchContext], list[Row]],
    ) -> Callable[[BenchContext], list[Row]]:
        SECTIONS.append(Section(title, measure, option))
        return measure

    return decorator


def format_rows(rows: list[Row]) -> str:
    """Format rows as an aligned table, one line per row."""
    width = max((len(r.label) for r in rows), default=0)
    return "\n".join(f"  {r.label:<{width}}  {r.value:>10.4g}  {r.unit}" for r in rows)


def run_sections(
    context: BenchContext, sections: list[Section] | None = None, out: TextIO | None = None
) -> dict[str, list[Row]]:
    """Run sections (default: all registered) in order, printing each table as it is measured.

    Returns
    -------
    dict of str to list of Row
        The rows of each section, by title.
    """
    out = sys.stdout if out is None else out
    results = {}
    for section in SECTIONS if sections is None else sections:
        if section.option and section.option not in context.options:
            continue
        context.notes.clear()
        rows = section.measure(context)
        results[section.title] = rows
        print(f"{section.title}:", file=out)
        print(format_rows(rows), file=out)
        for note in context.notes:
            print(f"  note: {note}", file=out)
        print(file=out, flush=True)
    return results


# --- helpers for sections ------------------------------------------------------------------


@contextmanager
def gc_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector inside a timed region."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def median_interleaved(
    loops: dict[str, Callable[[], float]], rounds: int
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Run every loop once per round, rotating the order; return medians and all rounds.

    Each loop returns its own cost per call (s).
    """
    names = list(loops)
    per_round = []
    for r in range(rounds):
        shift = r % len(names)
        measured = {}
        for name in names[shift:] + names[:shift]:
            measured[name] = loops[name]()
        per_round.append(measured)
    medians = {n: statistics.median(m[n] for m in per_round) for n in names}
    return medians, per_round


#: Modules that register sections, in the order their sections run.
SECTION_MODULES = ("plant_calls", "rodas_products", "native_step", "master_step",
                   "native_controller", "battery_throughput", "update_time", "realism_time",
                   "cosim_memory",
                   "identify_time")


def load_sections() -> list[Section]:
    """Import the modules that register the sections; return the sections in order."""
    import importlib

    for name in SECTION_MODULES:
        importlib.import_module(f"papwc.bench.{name}")
    return list(SECTIONS)
