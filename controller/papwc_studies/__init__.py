"""The studies behind papwc's open bounds, each runnable as ``python -m papwc_studies.NAME``.

Not part of the installed package: this folder sits beside ``papwc`` in the checkout (an
editable install puts ``controller/`` on the path, so both import there), may import
``papwc``, and is never imported by it. Each study has a page under ``docs/studies/`` with
its question, the command that reproduces it and its result; its tests are in
``tests/studies/`` (marker ``study``). Its scenario variants are in ``scenarios/`` beside
this file (:func:`scenario_path`).

- :mod:`.ringing`: what pulses do to a flexible drive;
- :mod:`.drive_state`: planning pulses from a model of the flexible drive, and how exact it must be;
- :mod:`.scatter`: how far the same pulse moves a table whose breakaway is redrawn at every stop;
- :mod:`.ring_scan`: whether the pulse controllers ever see ringing on rigid tables;
- :mod:`.flexible_scatter`: the same pulse from a relaxed flexible drive;
- :mod:`.ceiling`: planning for the lowest breakaway with the table known, or part of it
  learned;
- :mod:`.one_pulse`: one sample on many candidate stick–slip tables at once, and the candidates
  the pulses leave;
- :mod:`.sliding`: the sliding friction from the slides after wide pulses;
- :mod:`.counts`: the command line these share.
"""

from __future__ import annotations

from pathlib import Path

from papwc.resources import scenario_file

#: The studies' own scenario files (the variants of the shipped ones that the studies run).
SCENARIOS_DIR = Path(__file__).resolve().parent / "scenarios"


def scenario_path(name: str) -> Path:
    """A scenario file by name: the studies' own (:data:`SCENARIOS_DIR`), else the shipped one."""
    own = SCENARIOS_DIR / name
    return own if own.is_file() else scenario_file(name)
