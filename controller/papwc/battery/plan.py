"""Resolving a battery into runs: the cases, the grid, the draws, one validated scenario per run."""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import random
from dataclasses import dataclass

from papwc.battery.schema import Battery, is_number
from papwc.controllers.settings import ControllerSettings
from papwc.errors import ScenarioError
from papwc.limits import MAX_RUNS, MAX_STEPS, check_steps
from papwc.master import Maneuver
from papwc.model.maneuver import MANEUVER_VARIABLES
from papwc.model.plant import PLANT_PARAMETERS
from papwc.model.variables import by_name
from papwc.scenario import (
    PLANT_FIELDS,
    parse_scenario,
)

# --- resolving runs -------------------------------------------------------------------------

#: The model layer's variables of the seeds a seed offset shifts.
_SEED_VARIABLES = {"plant.seed": by_name(PLANT_PARAMETERS)["seed"],
                   "maneuver.noise_seed": by_name(MANEUVER_VARIABLES)["noise_seed"]}


@dataclass
class RunSpec:
    """One resolved run of a battery.

    Attributes
    ----------
    battery : str
        Name of the battery it belongs to.
    run_id : str
        Stable id within the battery (from its case, grid point and draw).
    order : tuple of int
        (battery number, grid point, draw); runs are listed case by case, each
        case in this order.
    data : dict
        The scenario of this run, every varied field replaced.
    run_hash : str
        First 12 hex digits of the SHA-256 of ``data`` as canonical JSON.
    error : str
        Why ``data`` is not a valid scenario ("" if it is).
    case : str
        Name of the run's case ("" without ``[cases]``).
    """

    battery: str
    run_id: str
    order: tuple[int, int, int]
    data: dict
    run_hash: str
    error: str = ""
    case: str = ""

    def task(self, source: str) -> dict:
        """What a worker needs to run it (picklable)."""
        return {"battery": self.battery, "run_id": self.run_id, "run_hash": self.run_hash,
                "source": source, "data": self.data}


def controller_tables(data: dict) -> list[dict]:
    """The ``[[controller]]`` tables of a scenario mapping, as a list."""
    tables = data.get("controller", [])
    return [tables] if isinstance(tables, dict) else list(tables)


def _default(head: str, name: str):
    if head == "plant":
        return PLANT_FIELDS[name]
    if head == "maneuver":
        return getattr(Maneuver(), name)
    return ControllerSettings().get(name)


def get_field(data: dict, path: str, table: int | None = None) -> object:
    """Value of ``path`` in a scenario mapping (its default if absent).

    ``table`` (0-based) picks the ``[[controller]]`` table of a ``controller.F``
    path; ``controller.N.F`` names its table itself.
    """
    parts = path.split(".")
    if parts[0] in ("plant", "maneuver"):
        return data.get(parts[0], {}).get(parts[1], _default(parts[0], parts[1]))
    if len(parts) == 3:
        table = int(parts[1]) - 1
    tables = controller_tables(data)
    if table is None or not 0 <= table < len(tables):
        return None
    return tables[table].get(parts[-1], _default("controller", parts[-1]))


def _set_field(data: dict, path: str, value, table: int | None = None) -> None:
    parts = path.split(".")
    if parts[0] in ("plant", "maneuver"):
        data.setdefault(parts[0], {})[parts[1]] = value
        return
    if isinstance(data.get("controller"), dict):
        data["controller"] = [data["controller"]]
    tables = data["controller"]
    if len(parts) == 3:
        tables[int(parts[1]) - 1][parts[2]] = value
    elif table is not None:
        tables[table][parts[1]] = value
    else:
        for t in tables:
            t[parts[1]] = value


def _uniform(seed: int, draw: int, path: str) -> float:
    """The number in (0, 1) of field ``path`` in draw ``draw``."""
    u = random.Random(f"papwc-battery:{seed}:{draw}:{path}").random()
    return u if u > 0.0 else 2.0**-60


def _hash(data: dict) -> str:
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def _apply_draws(battery: Battery, data: dict, draw: int) -> None:
    """Replace the drawn fields of ``data`` (one grid point) for draw ``draw`` (from the seed
    of the draws plus the battery's seed offset)."""
    ordered = [d for d in battery.draws if d.of is None] + [d for d in battery.draws if d.of]
    for d in ordered:
        u = _uniform(battery.seed + battery.seed_offset, draw, d.path)
        of_value = None
        if d.of is not None:
            of_value = get_field(data, d.of)
            if not is_number(of_value):
                raise ScenarioError(f"{battery.source}: [monte_carlo] field {d.path!r}: "
                                    f"of = {d.of!r} is {of_value!r}, not a number")
        parts = d.path.split(".")
        if parts[0] == "controller" and len(parts) == 2:
            targets = list(range(battery.n_controllers))
        else:
            targets = [None]
        for table in targets:
            nominal = get_field(data, d.path, table)
            if d.needs_nominal() and not is_number(nominal):
                raise ScenarioError(
                    f"{battery.source}: [monte_carlo] field {d.path!r}: the nominal value "
                    f"is {nominal!r}; give it in the file or use low/high or mean/std")
            _set_field(data, d.path, d.value(u, nominal, of_value), table)


#: The seeds of a run that ``--seed-offset`` shifts (beside the draws' seed).
SHIFTED_SEEDS = ("plant.seed", "maneuver.noise_seed")


def _shift_seeds(battery: Battery, data: dict, where: str) -> None:
    """Add the battery's seed offset to every seed of one run's ``data``.

    Raises
    ------
    ScenarioError
        If a shifted seed leaves its range (the model layer's).
    """
    offset = battery.seed_offset
    for path in SHIFTED_SEEDS:
        head, name = path.split(".")
        variable = _SEED_VARIABLES[path]
        seed = get_field(data, path)
        if not (isinstance(seed, int) and not isinstance(seed, bool)):
            continue  # an invalid seed is the run's own error (parse_scenario names it)
        shifted = seed + offset
        if not variable.min <= shifted <= variable.max:
            raise ScenarioError(f"--seed-offset {offset}: {where}: {path} = {seed} becomes "
                                f"{shifted}, outside {variable.min}..{variable.max}; give a "
                                "smaller offset")
        data.setdefault(head, {})[name] = shifted


def _run_hash(battery: Battery, data: dict) -> str:
    """The run's hash: of its data, and of the seed offset and identify_first when set."""
    if not battery.seed_offset and not battery.identify_first:
        return _hash(data)
    extra: dict = {"data": data}
    if battery.seed_offset:
        extra["seed_offset"] = battery.seed_offset
    if battery.identify_first:
        extra["identify_first"] = True
    return _hash(extra)


def check_size(batteries: list[Battery], max_runs: int = MAX_RUNS) -> None:
    """Raise ScenarioError if the batteries have more runs (or grid points) than ``max_runs``.

    Checked from the tables alone, before any run is resolved.
    """
    total = 0
    for battery in batteries:
        grid, runs = battery.grid_points, battery.n_runs
        if grid > max_runs:
            sizes = " x ".join(str(len(v)) for _, v in battery.sweep)
            raise ScenarioError(f"{battery.source}: [sweep] has {sizes} = {grid} grid points, "
                                f"over the limit of {max_runs} runs; pass --max-runs {grid} "
                                "to allow it")
        if runs > max_runs:
            cases = f"{len(battery.cases)} case(s) x " if battery.cases else ""
            raise ScenarioError(f"{battery.source}: {cases}{grid} grid point(s) x {battery.n} "
                                f"draw(s) = {runs} runs, over the limit of {max_runs} runs; "
                                f"pass --max-runs {runs} to allow it")
        total += runs
    if total > max_runs:
        raise ScenarioError(f"the batteries have {total} runs together, over the limit of "
                            f"{max_runs} runs; pass --max-runs {total} to allow it")


def plan_runs(batteries: list[Battery], max_runs: int = MAX_RUNS,
              max_steps: int = MAX_STEPS) -> list[RunSpec]:
    """Every run of the batteries, resolved and validated, in result order.

    A run whose parameters are invalid gets ``error`` (it is recorded, not run).

    Raises
    ------
    ScenarioError
        If two batteries have the same name, a draw cannot be resolved, the
        batteries have more than ``max_runs`` runs, a valid run would take more
        than ``max_steps`` communication steps, or every run of a battery is
        invalid.
    """
    names = [b.name for b in batteries]
    for name in names:
        if names.count(name) > 1:
            sources = [b.source for b in batteries if b.name == name]
            raise ScenarioError(f"{sources[1]}: field 'name' = {name!r} is also the name of "
                                f"{sources[0]}; battery names must differ")
    check_size(batteries, max_runs)
    runs = []
    for bi, battery in enumerate(batteries):
        first = len(runs)
        grid = list(itertools.product(*(values for _, values in battery.sweep)))
        gw = max(1, len(str(len(grid) - 1)))
        dw = max(3, len(str(battery.n - 1)))
        cases = battery.cases or [("", {})]
        for case, overrides in cases:
            case_data = copy.deepcopy(battery.data)
            for path, value in overrides.items():
                _set_field(case_data, path, value)
            for gi, point in enumerate(grid):
                point_data = copy.deepcopy(case_data)
                for (path, _), value in zip(battery.sweep, point, strict=True):
                    _set_field(point_data, path, value)
                for di in range(battery.n):
                    data = copy.deepcopy(point_data)
                    if battery.monte_carlo:
                        _apply_draws(battery, data, di)
                    ids = ([case] if case else []) + (
                        [f"s{gi:0{gw}d}"] if battery.sweep else []) + (
                        [f"d{di:0{dw}d}"] if battery.monte_carlo else [])
                    run_id = "-".join(ids) or "nominal"
                    where = f"{battery.source} run {run_id}"
                    if battery.seed_offset:
                        _shift_seeds(battery, data, where)
                    spec = RunSpec(battery.name, run_id, (bi, gi, di), data,
                                   _run_hash(battery, data), case=case)
                    try:
                        scenario = parse_scenario(data, where)
                    except ScenarioError as exc:
                        spec.error = str(exc)
                    else:
                        m = scenario.maneuver
                        check_steps(where, len(scenario.controllers), m.iterations,
                                    m.duration, m.T, max_steps)
                    runs.append(spec)
        mine = runs[first:]
        if mine and all(spec.error for spec in mine):
            raise ScenarioError(f"every run of the battery ({len(mine)}) is invalid; the "
                                f"first: {mine[0].error}")
    return runs
