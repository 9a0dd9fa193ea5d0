"""Battery files: the ``[cases]``, ``[sweep]``, ``[monte_carlo]`` and ``[battery]`` tables.

See :mod:`papwc.battery` for the syntax.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from statistics import NormalDist

from papwc.controllers.settings import SETTINGS_BY_NAME, ControllerSettings
from papwc.errors import ScenarioError
from papwc.limits import DEFAULT_RUN_TIMEOUT
from papwc.model.controller_settings import CONTROLLER_SETTINGS
from papwc.model.maneuver import MANEUVER_VARIABLES
from papwc.model.plant import PLANT_PARAMETERS
from papwc.model.variables import by_name
from papwc.scenario import (
    MANEUVER_FIELDS,
    PLANT_FIELDS,
    parse_scenario,
    read_toml,
)

BATTERY_TABLES = ("sweep", "monte_carlo", "battery", "cases")
#: Characters a case name may hold (it is part of run ids).
CASE_NAME_CHARACTERS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_")
#: Fields that cannot be drawn from a distribution (whole numbers, switches or words).
NOT_DRAWABLE = {"plant.seed", "maneuver.iterations", "maneuver.noise_seed", "maneuver.timing",
                "controller.rest_samples", "controller.kind", "controller.label"} | {
    f"controller.{v.name}" for v in CONTROLLER_SETTINGS if v.type != "Real"}
DISTRIBUTIONS = {
    "uniform": (("rel",), ("abs",), ("low", "high")),
    "normal": (("std",), ("rel_std",), ("mean", "std")),
}


# --- battery files ------------------------------------------------------------------------


@dataclass(frozen=True)
class Distribution:
    """How one field is drawn in a Monte Carlo battery (see the module docstring)."""

    path: str
    dist: str
    params: dict[str, float]
    of: str | None = None

    def needs_nominal(self) -> bool:
        """Whether the draw is relative to (or centred on) the field's nominal value."""
        return "rel" in self.params or "abs" in self.params or "rel_std" in self.params or (
            self.dist == "normal" and "mean" not in self.params)

    def value(self, u: float, nominal: float | None, of_value: float | None) -> float:
        """The drawn value for the uniform number ``u`` in (0, 1)."""
        p = self.params
        if self.dist == "uniform":
            if "rel" in p:
                return nominal * (1.0 + p["rel"] * (2.0 * u - 1.0))
            if "abs" in p:
                return nominal + p["abs"] * (2.0 * u - 1.0)
            x = p["low"] + (p["high"] - p["low"]) * u
        else:
            z = NormalDist().inv_cdf(u)
            if "rel_std" in p:
                return nominal * (1.0 + p["rel_std"] * z)
            x = p.get("mean", nominal) + p["std"] * z
        return x * of_value if self.of is not None else x


@dataclass
class Battery:
    """A validated battery file.

    Attributes
    ----------
    name, source : str
        The scenario's name and the file it was read from.
    data : dict
        The file's scenario (the battery tables removed), the nominal run.
    n_controllers : int
        Number of ``[[controller]]`` tables.
    cases : list of (name, overrides)
        The named cases in file order, each a mapping path -> value (empty
        without ``[cases]``).
    sweep : list of (path, values)
        The grid, first path slowest.
    draws : list of Distribution
        The Monte Carlo fields, in file order.
    n : int
        Draws per grid point (1 without ``[monte_carlo]``).
    seed : int
        Seed of the draws.
    success_tolerance : float or None
        Error band of a success, m; ``None``: each controller's tolerance.
    run_timeout : float
        Time limit of one run, s (``[battery] run_timeout``).
    seed_offset : int
        Added to every seed of the runs (``papwc battery --seed-offset``): the draws' ``seed``,
        each run's ``plant.seed`` and ``maneuver.noise_seed`` (0: the file's own).
    identify_first : bool
        ``[battery] identify_first``: each run's table is identified first (the excitation
        applied to it through its encoder, :mod:`papwc.battery.identify_first`) and its
        controllers are given the identified plant in place of their told values.
    """

    name: str
    source: str
    data: dict
    n_controllers: int
    cases: list[tuple[str, dict]] = field(default_factory=list)
    sweep: list[tuple[str, list]] = field(default_factory=list)
    draws: list[Distribution] = field(default_factory=list)
    n: int = 1
    seed: int = 0
    monte_carlo: bool = False
    success_tolerance: float | None = None
    run_timeout: float = DEFAULT_RUN_TIMEOUT
    seed_offset: int = 0
    identify_first: bool = False

    @property
    def grid_points(self) -> int:
        """Points of the sweep's grid (1 without a sweep)."""
        return math.prod(len(values) for _, values in self.sweep)

    @property
    def n_runs(self) -> int:
        """Runs of the battery: cases x grid points x draws."""
        return max(1, len(self.cases)) * self.grid_points * self.n

    @property
    def varied(self) -> list[str]:
        """Paths that differ between runs: the cases' first, then the sweep's, then the draws'."""
        out = list(dict.fromkeys(p for _, overrides in self.cases for p in overrides))
        out += [p for p, _ in self.sweep if p not in out]
        return out + [d.path for d in self.draws if d.path not in out]


def load_battery(path: str | os.PathLike) -> Battery:
    """Read and validate a battery file.

    Raises
    ------
    ScenarioError
        Naming the file and the field that are wrong.
    """
    return parse_battery(read_toml(path, "battery"), str(path))


def is_number(value: object) -> bool:
    """Whether ``value`` is an int or float (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_path(source: str, table: str, path: str, n_controllers: int, drawn: bool,
                value: object = None) -> None:
    """Raise ScenarioError unless ``path`` names a field a battery can vary (``value``, what
    the file gives it, tells an unquoted dotted key: TOML reads ``plant.m = ...`` as a
    table ``plant`` holding ``m``)."""
    parts = path.split(".")
    where = f"{source}: [{table}] field {path!r}"
    head = parts[0]
    if len(parts) == 1 and head in ("plant", "maneuver", "controller") and isinstance(
            value, dict) and value:
        inner, inner_value = next(iter(value.items()))
        while isinstance(inner_value, dict) and inner_value and "dist" not in inner_value:
            key, inner_value = next(iter(inner_value.items()))
            inner = f"{inner}.{key}"
        raise ScenarioError(f"{where}: TOML read the unquoted key {head}.{inner} as a table "
                            f"{head!r}; quote the path: \"{head}.{inner}\" = ...")
    if head == "plant" and len(parts) == 2:
        if parts[1] not in PLANT_FIELDS:
            raise ScenarioError(f"{where}: [plant] has no field {parts[1]!r}; allowed: "
                                + ", ".join(PLANT_FIELDS))
        name = parts[1]
    elif head == "maneuver" and len(parts) == 2:
        if parts[1] not in MANEUVER_FIELDS:
            raise ScenarioError(f"{where}: [maneuver] has no field {parts[1]!r}; allowed: "
                                + ", ".join(MANEUVER_FIELDS))
        name = parts[1]
    elif head == "controller" and len(parts) in (2, 3):
        name = parts[-1]
        if len(parts) == 3:
            if not parts[1].isdigit() or not 1 <= int(parts[1]) <= n_controllers:
                raise ScenarioError(
                    f"{where}: {parts[1]!r} is not a [[controller]] table number "
                    f"(1 to {n_controllers})")
        allowed = [k for k in ControllerSettings.field_names() if k != "kind"]
        if name not in allowed:
            raise ScenarioError(f"{where}: [[controller]] field {name!r} cannot be varied; "
                                "allowed: " + ", ".join(allowed))
    else:
        raise ScenarioError(
            f"{where}: not a field path; write plant.FIELD, maneuver.FIELD, "
            "controller.FIELD or controller.N.FIELD")
    if drawn and f"{head}.{name}" in NOT_DRAWABLE:
        raise ScenarioError(f"{where}: only floating-point fields can be drawn from a "
                            "distribution; use [sweep] for it")


def parse_battery(data: dict, source: str) -> Battery:
    """Validate a battery given as a mapping (``source`` names it in errors).

    The scenario part is checked by :func:`papwc.scenario.parse_scenario`, the
    ``[sweep]``, ``[monte_carlo]`` and ``[battery]`` tables here.
    """
    nominal = parse_scenario(data, source, allow=BATTERY_TABLES)
    scenario_data = {k: v for k, v in data.items() if k not in BATTERY_TABLES}
    n_ctrl = len(nominal.controllers)
    battery = Battery(nominal.name, source, scenario_data, n_ctrl)

    battery.cases = _parse_cases(source, data.get("cases"), n_ctrl)

    sweep = data.get("sweep", {})
    if not isinstance(sweep, dict):
        raise ScenarioError(f"{source}: [sweep] must be a table of path = [values]")
    for path, values in sweep.items():
        _check_path(source, "sweep", path, n_ctrl, drawn=False, value=values)
        if not isinstance(values, list) or not values:
            raise ScenarioError(f"{source}: [sweep] field {path!r} = {values!r}: must be a "
                                "non-empty array of values")
        var = field_variable(path)
        for v in values:
            if not (is_number(v) or isinstance(v, (str, bool))):
                raise ScenarioError(f"{source}: [sweep] field {path!r}: value {v!r} must be "
                                    "a number, a string, true or false")
            must = var.check(v)
            if must is not None:
                raise ScenarioError(f"{source}: [sweep] field {path!r}: value "
                                    f"{var.message(v, must)}")
        battery.sweep.append((path, list(values)))
    _refuse_set_twice(source, battery.cases, {p for p, _ in battery.sweep}, "[sweep]")

    mc = data.get("monte_carlo")
    if mc is not None:
        if not isinstance(mc, dict):
            raise ScenarioError(f"{source}: [monte_carlo] must be a table")
        battery.monte_carlo = True
        n = mc.get("n")
        if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1):
            raise ScenarioError(f"{source}: [monte_carlo] field 'n' = {n!r}: must be a whole "
                                "number >= 1 (the number of draws)")
        seed = mc.get("seed", 0)
        if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
            raise ScenarioError(f"{source}: [monte_carlo] field 'seed' = {seed!r}: must be a "
                                "whole number >= 0")
        battery.n, battery.seed = n, seed
        for path, spec in mc.items():
            if path in ("n", "seed"):
                continue
            battery.draws.append(_parse_distribution(source, path, spec, n_ctrl))
        ratio_paths = {d.path for d in battery.draws if d.of is not None}
        for d in battery.draws:
            if d.of is not None and d.of in ratio_paths:
                raise ScenarioError(f"{source}: [monte_carlo] field {d.path!r}: of = {d.of!r} "
                                    "is itself drawn as a ratio; ratios cannot be chained")
        if not battery.draws:
            raise ScenarioError(f"{source}: [monte_carlo] draws nothing; add fields such as "
                                "\"plant.m\" = { dist = \"uniform\", rel = 0.3 }")
        _refuse_set_twice(source, battery.cases, {d.path for d in battery.draws},
                          "[monte_carlo]")

    opts = data.get("battery", {})
    if not isinstance(opts, dict):
        raise ScenarioError(f"{source}: [battery] must be a table")
    for key, value in opts.items():
        if key == "identify_first":
            if not isinstance(value, bool):
                raise ScenarioError(f"{source}: [battery] field 'identify_first' = {value!r}: "
                                    "must be true or false")
            battery.identify_first = value
            continue
        if key == "run_timeout":
            if not (is_number(value) and 0.0 < value <= MAX_RUN_TIMEOUT):
                raise ScenarioError(f"{source}: [battery] field 'run_timeout' = {value!r}: "
                                    f"must satisfy 0 < run_timeout <= {MAX_RUN_TIMEOUT:g} s")
            battery.run_timeout = float(value)
            continue
        if key != "success_tolerance":
            raise ScenarioError(f"{source}: [battery] unknown field {key!r}; allowed: "
                                "success_tolerance, run_timeout, identify_first")
        if not (is_number(value) and math.isfinite(value) and 0.0 <= value <= 1.0):
            raise ScenarioError(f"{source}: [battery] field 'success_tolerance' = {value!r}: "
                                "must satisfy 0 <= success_tolerance <= 1 m")
        battery.success_tolerance = float(value)
    return battery


#: Largest ``[battery] run_timeout``, s (a week).
MAX_RUN_TIMEOUT = 7 * 24 * 3600.0
_FIELD_TABLES = {"plant": by_name(PLANT_PARAMETERS), "maneuver": by_name(MANEUVER_VARIABLES),
                 "controller": SETTINGS_BY_NAME}


def field_variable(path: str):
    """The model layer's Variable of a checked field path (``plant.m``, ``controller.1.K_c``)."""
    parts = path.split(".")
    return _FIELD_TABLES[parts[0]][parts[-1]]


def _parse_cases(source: str, cases, n_ctrl: int) -> list[tuple[str, dict]]:
    """The ``[cases]`` table: case name -> table of path = value (see :mod:`papwc.battery`)."""
    if cases is None:
        return []
    if not isinstance(cases, dict) or not cases:
        raise ScenarioError(f"{source}: [cases] must be a non-empty table of case name = "
                            "{ path = value, ... }, e.g. stribeck = { \"plant.v_s\" = 1e-3 }")
    out = []
    for name, overrides in cases.items():
        if not name or not set(name) <= CASE_NAME_CHARACTERS:
            raise ScenarioError(f"{source}: [cases] case name {name!r}: must be made of "
                                "letters, digits and '_' (it is part of the run ids)")
        if not isinstance(overrides, dict):
            raise ScenarioError(f"{source}: [cases] case {name!r} = {overrides!r}: must be a "
                                "table of path = value, e.g. { \"plant.v_s\" = 1e-3 } ({} for "
                                "the file's own values)")
        for path, value in overrides.items():
            _check_path(source, f"cases.{name}", path, n_ctrl, drawn=False, value=value)
            if not (is_number(value) or isinstance(value, str)):
                raise ScenarioError(f"{source}: [cases.{name}] field {path!r} = {value!r}: "
                                    "must be a number or a string")
        out.append((name, dict(overrides)))
    return out


def _refuse_set_twice(source: str, cases: list[tuple[str, dict]], paths: set[str],
                      table: str) -> None:
    """Raise ScenarioError if a case sets a path that ``table`` varies too."""
    for name, overrides in cases:
        for path in overrides:
            if path in paths:
                raise ScenarioError(f"{source}: [cases.{name}] field {path!r} is also varied "
                                    f"by {table}; a field is set by the cases or by {table}, "
                                    "not by both")


def _parse_distribution(source: str, path: str, spec, n_ctrl: int) -> Distribution:
    where = f"{source}: [monte_carlo] field {path!r}"
    _check_path(source, "monte_carlo", path, n_ctrl, drawn=True,
                value=spec if isinstance(spec, dict) and "dist" not in spec else None)
    if not isinstance(spec, dict):
        raise ScenarioError(f"{where} = {spec!r}: must be a table such as "
                            "{ dist = \"uniform\", rel = 0.3 }")
    dist = spec.get("dist")
    if dist not in DISTRIBUTIONS:
        raise ScenarioError(f"{where}: dist = {dist!r}: must be one of "
                            + ", ".join(repr(d) for d in DISTRIBUTIONS))
    of = spec.get("of")
    params = {k: v for k, v in spec.items() if k not in ("dist", "of")}
    forms = DISTRIBUTIONS[dist]
    if of is not None:
        forms = forms[-1:]
    form = next((f for f in forms if set(params) == set(f)), None)
    if form is None and dist == "normal" and of is None and set(params) == {"std"}:
        form = ("std",)
    if form is None:
        allowed = " or ".join("{" + ", ".join(f) + "}" for f in forms)
        raise ScenarioError(f"{where}: a {dist} distribution{' with of' if of else ''} takes "
                            f"{allowed}; got {{{', '.join(params)}}}")
    for key, value in params.items():
        if not (is_number(value) and math.isfinite(value)):
            raise ScenarioError(f"{where}: {key} = {value!r}: must be a finite number")
        if key in ("rel", "abs", "std", "rel_std") and value < 0.0:
            raise ScenarioError(f"{where}: {key} = {value!r}: must be >= 0")
    if "low" in params and not params["low"] <= params["high"]:
        raise ScenarioError(f"{where}: low = {params['low']!r} must be <= high = "
                            f"{params['high']!r}")
    if of is not None:
        if not isinstance(of, str) or of.split(".")[0] not in ("plant", "maneuver"):
            raise ScenarioError(f"{where}: of = {of!r}: must be a plant.FIELD or "
                                "maneuver.FIELD path")
        _check_path(source, "monte_carlo", of, n_ctrl, drawn=True)
        if of == path:
            raise ScenarioError(f"{where}: of = {of!r} names the field itself")
    return Distribution(path, dist, {k: float(v) for k, v in params.items()}, of)
