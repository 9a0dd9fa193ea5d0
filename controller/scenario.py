"""Scenario files: TOML read with tomllib, validated with errors naming file and field.

The schema (public; extend it, don't rename it)::

    name = "paper"
    [plant]          # FrictionPlant parameters: m (kg), f_c (N), f_s (N), c (N.s/m),
                     # and optionally x_resolution (m, encoder; 0 = ideal)
    [maneuver]       # x_ref (m), T (s), duration (s per iteration), iterations,
                     # optionally timing ("immediate" | "delayed"),
                     # noise_std (m, measurement noise) and noise_seed
    [[controller]]   # one table per controller; see papwc.core.settings
    kind = "papwc"   # "pwc", "papwc", ...
    label = "..."    # optional name in results (default: kind and t_p_max)
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from papwc.core import CONTROLLER_KINDS
from papwc.core.settings import ControllerSettings
from papwc.errors import ScenarioError
from papwc.fmu_src import papwc_stickslip as physics
from papwc.master import TIMINGS, Maneuver

PLANT_FIELDS = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0, "x_resolution": 0.0}
MANEUVER_FIELDS = ("x_ref", "T", "duration", "iterations", "timing", "noise_std", "noise_seed")
TOP_LEVEL = ("name", "description", "plant", "maneuver", "controller")


@dataclass
class Scenario:
    """A validated scenario."""

    name: str
    plant: dict[str, float]
    maneuver: Maneuver
    controllers: list[ControllerSettings]
    labels: list[str]
    source: str = ""
    extra: dict = field(default_factory=dict)


def controller_label(settings: ControllerSettings, label: str | None = None) -> str:
    """Name of a controller in results: its label, or kind and t_p_max."""
    if label:
        return label
    t = settings.t_p_max
    return f"{settings.kind}_tpmax_{'inf' if math.isinf(t) else f'{t:g}'}"


def _number(source: str, where: str, key: str, value, integer: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"{source}: {where} field {key!r} = {value!r}: must be a number")
    if integer and (not float(value).is_integer()):
        raise ScenarioError(f"{source}: {where} field {key!r} = {value!r}: must be a whole number")
    return int(value) if integer else float(value)


def load_scenario(path: str | os.PathLike) -> Scenario:
    """Read and validate a scenario file.

    Raises
    ------
    ScenarioError
        With the file, the table and the field that are wrong, and what is allowed.
    """
    return parse_scenario(read_toml(path, "scenario"), str(path))


def read_toml(path: str | os.PathLike, what: str = "scenario") -> dict:
    """Read a TOML file; a missing file or a syntax error is a ScenarioError naming it."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise ScenarioError(f"{path}: no such {what} file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from None


def parse_scenario(data: dict, source: str, allow: tuple[str, ...] = ()) -> Scenario:
    """Validate a scenario given as a mapping (``source`` names it in errors).

    ``allow`` lists further top-level tables that the caller handles (e.g.
    ``sweep`` and ``monte_carlo`` of a battery file); they are returned in
    ``Scenario.extra``.
    """
    for key in data:
        if key not in TOP_LEVEL and key not in allow:
            raise ScenarioError(
                f"{source}: unknown top-level field {key!r}; allowed: "
                + ", ".join(TOP_LEVEL + allow)
            )
    name = data.get("name", Path(source).stem)
    if not isinstance(name, str):
        raise ScenarioError(f"{source}: field 'name' = {name!r}: must be a string")

    plant_in = data.get("plant", {})
    if not isinstance(plant_in, dict):
        raise ScenarioError(f"{source}: [plant] must be a table")
    plant = dict(PLANT_FIELDS)
    for key, value in plant_in.items():
        if key not in PLANT_FIELDS:
            raise ScenarioError(
                f"{source}: [plant] unknown field {key!r}; allowed: {', '.join(PLANT_FIELDS)}"
            )
        plant[key] = _number(source, "[plant]", key, value)
    problems = physics.check_parameters(plant["m"], plant["f_c"], plant["f_s"], plant["c"])
    if not (math.isfinite(plant["x_resolution"]) and plant["x_resolution"] >= 0.0):
        problems.append(f"parameter x_resolution = {plant['x_resolution']!r} m must be >= 0")
    if problems:
        raise ScenarioError(f"{source}: [plant] " + problems[0].replace("parameter ", "field "))

    man_in = data.get("maneuver", {})
    if not isinstance(man_in, dict):
        raise ScenarioError(f"{source}: [maneuver] must be a table")
    kwargs: dict = {}
    for key, value in man_in.items():
        if key not in MANEUVER_FIELDS:
            raise ScenarioError(
                f"{source}: [maneuver] unknown field {key!r}; allowed: "
                + ", ".join(MANEUVER_FIELDS)
            )
        if key == "timing":
            if value not in TIMINGS:
                raise ScenarioError(
                    f"{source}: [maneuver] field 'timing' = {value!r}: must be one of "
                    + ", ".join(repr(t) for t in TIMINGS)
                )
            kwargs[key] = value
        else:
            kwargs[key] = _number(source, "[maneuver]", key, value,
                                  integer=key in ("iterations", "noise_seed"))
    maneuver = Maneuver(**kwargs)
    checks = [
        ("x_ref", math.isfinite(maneuver.x_ref), "must be finite (m)"),
        ("T", math.isfinite(maneuver.T) and maneuver.T > 0.0, "must be > 0 s"),
        ("duration", math.isfinite(maneuver.duration) and maneuver.duration >= maneuver.T,
         f"must be >= T = {maneuver.T!r} s"),
        ("iterations", maneuver.iterations >= 1, "must be >= 1"),
        ("noise_std", math.isfinite(maneuver.noise_std) and maneuver.noise_std >= 0.0,
         "must be >= 0 m"),
    ]
    for key, ok, msg in checks:
        if not ok:
            raise ScenarioError(
                f"{source}: [maneuver] field {key!r} = {getattr(maneuver, key)!r}: {msg}"
            )

    tables = data.get("controller", [])
    if isinstance(tables, dict):
        tables = [tables]
    if not isinstance(tables, list) or not tables:
        raise ScenarioError(f"{source}: needs at least one [[controller]] table")
    controllers, labels = [], []
    known = set(ControllerSettings.field_names()) | {"label"}
    for i, table in enumerate(tables, start=1):
        where = f"[[controller]] #{i}"
        if not isinstance(table, dict):
            raise ScenarioError(f"{source}: {where} must be a table")
        kind = table.get("kind")
        if kind not in CONTROLLER_KINDS:
            raise ScenarioError(
                f"{source}: {where} field 'kind' = {kind!r}: must be one of "
                + ", ".join(repr(k) for k in sorted(CONTROLLER_KINDS))
            )
        allowed = known | set(getattr(CONTROLLER_KINDS[kind], "EXTRA_KEYS", ()))
        for key in table:
            if key not in allowed:
                raise ScenarioError(
                    f"{source}: {where} unknown field {key!r} for kind {kind!r}; allowed: "
                    + ", ".join(sorted(allowed))
                )
        label = table.get("label")
        if label is not None and not isinstance(label, str):
            raise ScenarioError(f"{source}: {where} field 'label' = {label!r}: must be a string")
        settings = ControllerSettings.from_mapping({k: v for k, v in table.items() if k != "label"})
        problems = settings.problems(tuple(CONTROLLER_KINDS))
        if problems:
            key, msg = problems[0]
            raise ScenarioError(f"{source}: {where} field {key!r}: {msg}")
        controllers.append(settings)
        labels.append(controller_label(settings, label))
    if len(set(labels)) != len(labels):
        raise ScenarioError(
            f"{source}: two [[controller]] tables have the same label; give each a 'label'"
        )
    extra = {k: data[k] for k in allow if k in data}
    return Scenario(name, plant, maneuver, controllers, labels, source, extra)
