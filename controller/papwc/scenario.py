"""Scenario files: TOML read with tomllib, validated with errors naming file, table and field.

The schema (public; extend it, don't rename it)::

    name = "paper"
    [plant]          # FrictionPlant parameters (papwc.model.plant), e.g.
                     # m (kg), f_c (N), f_s (N), c (N.s/m), x_resolution (m)
    [maneuver]       # x_ref (m), T (s), duration (s per iteration), iterations,
                     # timing ("immediate" | "delayed"), noise_std (m), noise_seed
    [[controller]]   # one table per controller; settings of papwc.model.controller_settings
    kind = "papwc"   # "pwc", "papwc", "exact"
    label = "..."    # optional name in results (default: kind and t_p_max)
    [identified]     # only in a plant.toml of papwc identify: intervals and the stiction
                     # band (papwc.identify.plant_model; papwc run --plant-model reads it)

Every field may be left out and takes the default of its table in the model
layer (:mod:`papwc.model.plant`, :mod:`papwc.model.maneuver`,
:mod:`papwc.model.controller_settings`; :func:`field_table` lists them); ``kind`` is
required. ``name`` and ``label`` name files, so they are letters, digits and
``_ . + -`` (:data:`papwc.limits.NAME_PATTERN`); the default name is the file's
stem made so. Rules between tables: ``duration`` is a whole number of samples
``T``, every ``t_p_max >= T``. A controller whose ``f_p_max <= f_s`` cannot
break the mass away: the scenario is accepted with a warning
(``Scenario.warnings``).

A file is read as UTF-8 text of at most :data:`papwc.limits.MAX_INPUT_BYTES`;
a folder, a FIFO, a binary or non-UTF-8 file is refused by name.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from papwc.controllers import CONTROLLER_KINDS
from papwc.controllers.settings import ControllerSettings, settings_for_kind
from papwc.errors import ScenarioError
from papwc.limits import check_name, read_input_text, safe_name
from papwc.master.closed_loop import Maneuver
from papwc.model.controller_settings import CONTROLLER_SETTINGS, settings_problems
from papwc.model.maneuver import MANEUVER_DEFAULTS, MANEUVER_VARIABLES, maneuver_problems
from papwc.model.plant import (
    PLANT_DEFAULTS,
    PLANT_PARAMETERS,
    SCENARIO_PLANT_FIELDS,
    plant_problems,
)

__all__ = [
    "MANEUVER_FIELDS",
    "PLANT_FIELDS",
    "Scenario",
    "controller_label",
    "field_table",
    "load_scenario",
    "parse_scenario",
    "read_toml",
]

#: ``[plant]`` fields and their defaults.
PLANT_FIELDS: dict[str, Any] = {name: PLANT_DEFAULTS[name] for name in SCENARIO_PLANT_FIELDS}
#: ``[maneuver]`` fields.
MANEUVER_FIELDS: tuple[str, ...] = tuple(MANEUVER_DEFAULTS)
#: Top-level fields of a scenario file (``identified``: what ``papwc identify`` found beside
#: the ``[plant]`` values it wrote, :mod:`papwc.identify.plant_model`; a run does not read it).
TOP_LEVEL = ("name", "description", "plant", "maneuver", "controller", "identified")


@dataclass
class Scenario:
    """A validated scenario: what :func:`load_scenario` returns.

    Parameters
    ----------
    name : str
        The scenario's name (names result files).
    plant : dict of str to float
        Every ``[plant]`` field, defaults filled in.
    maneuver : Maneuver
        The ``[maneuver]`` table.
    controllers : list of ControllerSettings
        One per ``[[controller]]`` table, in the file's order.
    labels : list of str
        The controllers' names in results (:func:`controller_label`), one per controller.
    source : str
        The file (or what else the scenario came from), for messages.
    extra : dict
        Further top-level tables the caller allowed (a battery's ``[sweep]``, ...).
    warnings : list of (str, str)
        Inputs that cannot work as meant but are allowed: (label, message).
    """

    name: str
    plant: dict[str, float]
    maneuver: Maneuver
    controllers: list[ControllerSettings]
    labels: list[str]
    source: str = ""
    extra: dict = field(default_factory=dict)
    #: Inputs that cannot work as meant but are allowed: (label, message).
    warnings: list[tuple[str, str]] = field(default_factory=list)

    def warnings_of(self, label: str) -> str:
        """The warnings about one controller.

        Parameters
        ----------
        label : str
            The controller's label.

        Returns
        -------
        str
            Its warnings joined by ``"; "`` (empty if none).
        """
        return "; ".join(message for who, message in self.warnings if who == label)


def controller_label(settings: ControllerSettings, label: str | None = None) -> str:
    """Name of a controller in results.

    Parameters
    ----------
    settings : ControllerSettings
        The controller's settings.
    label : str, optional
        The ``label`` of its table, if it has one.

    Returns
    -------
    str
        ``label``, or ``<kind>_tpmax_<t_p_max>`` (``inf`` for no bound).

    Examples
    --------
    >>> from papwc.controllers.settings import ControllerSettings
    >>> controller_label(ControllerSettings(kind="papwc", t_p_max=0.03))
    'papwc_tpmax_0.03'
    """
    if label:
        return label
    t = settings.t_p_max
    return f"{settings.kind}_tpmax_{'inf' if math.isinf(t) else f'{t:g}'}"


def load_scenario(path: str | os.PathLike) -> Scenario:
    """Read and validate a scenario file.

    Parameters
    ----------
    path : path
        The scenario file (TOML, UTF-8, at most :data:`~papwc.limits.MAX_INPUT_BYTES`).

    Returns
    -------
    Scenario
        Every field with its default filled in, checked against the model layer's ranges
        and the rules between fields.

    Raises
    ------
    ScenarioError
        With the file, the table and the field that are wrong, and what is allowed.

    Examples
    --------
    >>> from papwc.resources import scenario_file
    >>> scenario = load_scenario(scenario_file("paper.toml"))
    >>> scenario.labels
    ['pwc_tpmax_0.03', 'pwc_tpmax_inf', 'papwc_tpmax_0.03', 'papwc_tpmax_inf']
    >>> scenario.maneuver.x_ref, scenario.maneuver.iterations, scenario.plant["f_s"]
    (0.01, 10, 130.0)
    """
    return parse_scenario(read_toml(path, "scenario"), str(path))


def read_toml(path: str | os.PathLike, what: str = "scenario") -> dict:
    """Read a TOML file as UTF-8 text.

    Parameters
    ----------
    path : path
        The file.
    what : str
        What the file is, for messages (``"scenario"``, ``"battery"``).

    Returns
    -------
    dict
        The TOML document.

    Raises
    ------
    ScenarioError
        Naming the file: missing, a folder, a FIFO or device, larger than
        :data:`~papwc.limits.MAX_INPUT_BYTES`, binary (a NUL byte), not UTF-8,
        not readable, or not valid TOML.
    """
    text = read_input_text(path, what, "TOML", ScenarioError)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from None


def _table(source: str, data: dict, key: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise ScenarioError(f"{source}: [{key}] must be a table")
    return value


def _check_fields(source: str, where: str, table: dict, allowed, what: str = "") -> None:
    for key in table:
        if key not in allowed:
            raise ScenarioError(f"{source}: {where} unknown field {key!r}{what}; allowed: "
                                + ", ".join(allowed))


def _first(source: str, where: str, problems: list[tuple[str, str]]) -> None:
    if problems:
        name, message = problems[0]
        raise ScenarioError(f"{source}: {where} field {name!r}: {message}")


def parse_scenario(data: dict, source: str, allow: tuple[str, ...] = ()) -> Scenario:
    """Validate a scenario given as a mapping (a TOML document read).

    Parameters
    ----------
    data : dict
        The top-level tables and fields.
    source : str
        What names the scenario in errors (its file).
    allow : tuple of str
        Further top-level tables that the caller handles (e.g. ``sweep`` and
        ``monte_carlo`` of a battery file); they are returned in ``Scenario.extra``.

    Returns
    -------
    Scenario
        Every field with its default filled in.

    Raises
    ------
    ScenarioError
        Naming ``source``, the table, the field, the value and what is allowed.

    Examples
    --------
    >>> scenario = parse_scenario({"plant": {"m": 120.0},
    ...                            "controller": [{"kind": "exact", "tolerance": 1e-7}]},
    ...                           "example")
    >>> scenario.plant["m"], scenario.plant["c"], scenario.labels
    (120.0, 700.0, ['exact_tpmax_inf'])
    >>> parse_scenario({"plant": {"m": -1.0}, "controller": [{"kind": "exact"}]},
    ...                "bad")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    papwc.errors.ScenarioError: bad: [plant] field 'm': m = -1.0 kg: must satisfy 1e-06 <= m ...
    """
    for key in data:
        if key not in TOP_LEVEL and key not in allow:
            raise ScenarioError(
                f"{source}: unknown top-level field {key!r}; allowed: "
                + ", ".join(TOP_LEVEL + allow)
            )
    if "name" in data:
        name = data["name"]
        if not isinstance(name, str):
            raise ScenarioError(f"{source}: field 'name' = {name!r}: must be a string")
        bad = check_name(name)
        if bad is not None:
            raise ScenarioError(f"{source}: field 'name' = {name!r}: {bad}")
    else:
        name = safe_name(Path(source).stem)
    description = data.get("description", "")
    if not isinstance(description, str):
        raise ScenarioError(f"{source}: field 'description' = {description!r}: must be a string")
    if "identified" in data:
        from papwc.identify.plant_model import check_identified

        check_identified(data["identified"], source)

    plant_in = _table(source, data, "plant")
    _check_fields(source, "[plant]", plant_in, PLANT_FIELDS)
    plant = {**PLANT_FIELDS, **plant_in}
    _first(source, "[plant]", plant_problems(plant))
    plant = {k: int(v) if isinstance(PLANT_FIELDS[k], int) else float(v) for k, v in plant.items()}

    man_in = _table(source, data, "maneuver")
    _check_fields(source, "[maneuver]", man_in, MANEUVER_FIELDS)
    values = {**MANEUVER_DEFAULTS, **man_in}
    _first(source, "[maneuver]", maneuver_problems(values))
    maneuver = Maneuver(**{k: (int(v) if isinstance(MANEUVER_DEFAULTS[k], int)
                               and not isinstance(v, str) else v) for k, v in values.items()})
    maneuver.x_ref, maneuver.T = float(maneuver.x_ref), float(maneuver.T)
    maneuver.duration, maneuver.noise_std = float(maneuver.duration), float(maneuver.noise_std)

    tables = data.get("controller", [])
    if isinstance(tables, dict):
        tables = [tables]
    if not isinstance(tables, list) or not tables:
        raise ScenarioError(f"{source}: needs at least one [[controller]] table")
    controllers, labels = [], []
    for i, table in enumerate(tables, start=1):
        where = f"[[controller]] #{i}"
        if not isinstance(table, dict):
            raise ScenarioError(f"{source}: {where} must be a table")
        kind = table.get("kind")
        if not isinstance(kind, str) or kind not in CONTROLLER_KINDS:
            raise ScenarioError(
                f"{source}: {where} field 'kind' = {kind!r}: must be one of "
                + ", ".join(repr(k) for k in sorted(CONTROLLER_KINDS))
            )
        allowed = settings_for_kind(kind) + ["label"]
        _check_fields(source, where, table, allowed, f" for kind {kind!r}")
        label = table.get("label")
        if label is not None and not isinstance(label, str):
            raise ScenarioError(f"{source}: {where} field 'label' = {label!r}: must be a string")
        if label is not None and check_name(label) is not None:
            raise ScenarioError(f"{source}: {where} field 'label' = {label!r}: "
                                + check_name(label))
        settings = ControllerSettings.from_mapping({k: v for k, v in table.items() if k != "label"})
        _first(source, where, settings.problems(tuple(CONTROLLER_KINDS)))
        # Rules between the settings and the maneuver (t_p_max >= T).
        _first(source, where, settings_problems(
            {**settings.to_mapping(with_none=True), "T": maneuver.T}))
        controllers.append(settings)
        labels.append(controller_label(settings, label))
    if len(set(labels)) != len(labels):
        raise ScenarioError(
            f"{source}: two [[controller]] tables have the same label; give each a 'label'"
        )
    warnings = []
    for settings, label in zip(controllers, labels, strict=True):
        if settings.f_p_max <= plant["f_s"]:
            warnings.append((label, f"f_p_max = {settings.f_p_max!r} N <= f_s = "
                                    f"{plant['f_s']!r} N: no force of this controller breaks "
                                    "the mass away from rest"))
    extra = {k: data[k] for k in allow if k in data}
    return Scenario(name, plant, maneuver, controllers, labels, source, extra, warnings)


def field_table() -> str:
    """Every field of a scenario file with its unit, default and range, as a Markdown table.

    Generated from the model layer's tables (the source of the defaults); a ``|`` inside a
    cell is written ``\\|``. The documentation site's reference includes it.

    Returns
    -------
    str
        Columns ``table, field, unit, default, allowed, description``; one row per field of
        ``[plant]``, ``[maneuver]`` and ``[[controller]]``.
    """
    lines = ["| table | field | unit | default | allowed | description |",
             "|---|---|---|---|---|---|"]

    def row(table: str, var) -> None:
        default = ("computed (see description)" if var.default is None
                   else "required" if var.name == "kind" else repr(var.default))
        allowed = var.allowed_text()
        if var.name == "kind":
            allowed = ", ".join(repr(k) for k in sorted(CONTROLLER_KINDS))
        if var.kinds:
            table += " (" + ", ".join(var.kinds) + ")"
        unit = var.unit if var.unit not in ("", "1") else "-"
        cells = (table, f"`{var.name}`", unit, default, allowed, var.description)
        lines.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")

    for var in PLANT_PARAMETERS:
        if var.name in SCENARIO_PLANT_FIELDS:
            row("[plant]", var)
    for var in MANEUVER_VARIABLES:
        row("[maneuver]", var)
    for var in CONTROLLER_SETTINGS:
        row("[[controller]]", var)
    return "\n".join(lines)
