"""Scenario batteries: parameter sweeps and Monte Carlo draws of a scenario, run in parallel.

A battery file is a scenario file (see :mod:`papwc.scenario`) with up to three
more top-level tables. Every run of the battery is the scenario with some fields
replaced; a field is named by a dotted path:

- ``plant.F`` -- a ``[plant]`` field (``m``, ``f_c``, ``f_s``, ``c``, ``x_resolution``);
- ``maneuver.F`` -- a ``[maneuver]`` field;
- ``controller.F`` -- field ``F`` of every ``[[controller]]`` table;
- ``controller.N.F`` -- field ``F`` of the N-th ``[[controller]]`` table (N from 1).

``[sweep]``: a grid. Each key is a path, each value the list of values it takes;
the runs cover every combination (the first key varies slowest)::

    [sweep]
    "plant.f_c" = [80.0, 100.0, 120.0]
    "controller.t_p_max" = [0.03, inf]

``[monte_carlo]``: ``n`` draws (required, >= 1) from ``seed`` (integer >= 0,
default 0); every other key is a path with its distribution, an inline table::

    [monte_carlo]
    n = 200
    seed = 1
    "plant.m"   = { dist = "uniform", rel = 0.3 }            # nominal * U(0.7, 1.3)
    "plant.c"   = { dist = "uniform", abs = 50.0 }           # nominal + U(-50, 50)
    "plant.f_c" = { dist = "uniform", low = 70.0, high = 130.0 }
    "maneuver.x_ref" = { dist = "normal", std = 1e-3 }       # nominal + N(0, std^2)
    "controller.K_c" = { dist = "normal", rel_std = 0.05 }   # nominal * (1 + N(0, 0.05^2))
    "controller.1.tolerance" = { dist = "normal", mean = 2e-5, std = 5e-6 }
    # ratio to another field of the same run (after its own sweep and draw):
    "plant.f_s" = { dist = "uniform", low = 1.0, high = 1.6, of = "plant.f_c" }
    "controller.m_est" = { dist = "uniform", low = 0.8, high = 1.2, of = "plant.m" }

Distributions: ``uniform`` takes exactly one of ``rel`` (relative half-width),
``abs`` (absolute half-width) or ``low`` and ``high``; ``normal`` takes ``std``
(around the nominal value, or around ``mean`` if given) or ``rel_std``. The
nominal value is the field's value in the file at that grid point (its default
if the file leaves it out). With ``of = "plant.F"`` or ``"maneuver.F"`` the
drawn number is a factor applied to that field's value in the run, and only the
``low``/``high`` and ``mean``/``std`` forms are allowed. Such a ratio is the
way to keep a pair ordered, e.g. ``f_s >= f_c``: sampling ``f_s`` on its own
can give ``f_s < f_c``, which is an invalid plant. Ratios are resolved after
every other field. Only floating-point fields can be drawn (not
``maneuver.iterations``, ``noise_seed``, ``timing`` or ``controller.rest_samples``).

Randomness: each field of draw ``d`` gets its own stream, seeded by ``seed``,
``d`` and the path (stdlib :class:`random.Random`, stable across Python
versions); a ``controller.F`` path uses one number for every table, and grid
points reuse the same numbers (common random numbers). All runs are drawn up
front, so the results do not depend on the number of workers, the engine or the
order in which runs finish.

``[battery]``: options of the report. ``success_tolerance`` (m): the error band
used to call a run a success (default: each controller's own ``tolerance``).

A grid and draws combine: every grid point gets all ``n`` draws. Each run has
an id (``s<grid point>``, ``d<draw>``, ``s<grid point>-d<draw>``, or
``nominal``), a hash of its fully resolved parameters, and is validated by
:func:`papwc.scenario.parse_scenario`; a run whose parameters are invalid (e.g. a
sweep value ``f_s < f_c``) is recorded with status ``error`` and the message.

Outputs of :func:`run_battery` in the output folder:

- ``journal.jsonl`` -- one JSON line per finished run, flushed and fsync'ed as it
  finishes (a header line first); ``--resume`` reads it back and runs only what is
  missing. A torn last line (the process was killed while writing) is dropped.
  ``journal.jsonl.lock`` keeps two batteries from writing into one folder.
- ``results.csv`` -- one row per run, controller and iteration, sorted by
  battery, run id, controller and iteration: the varied fields (one column per
  path; a ``controller.F`` column holds the row's controller's value), the
  metrics of :func:`papwc.recording.summarize`, ``success``, ``status`` and
  ``message``; ``last_iteration`` marks each controller's final row.
- ``runs.csv`` -- one row per run with its status and every resolved parameter.
- ``summary.md`` -- per battery and controller: success rate, median, 95th
  percentile and maximum of |final error|, pulses and settle time, in the last
  iteration.
- ``final_error_<battery>.png`` -- distribution (empirical CDF) of |final error|
  per controller on a log axis.
"""

from __future__ import annotations

import contextlib
import copy
import fcntl
import hashlib
import itertools
import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from statistics import NormalDist

from papwc.controllers.settings import ControllerSettings
from papwc.errors import PapwcError, ScenarioError
from papwc.master import Maneuver
from papwc.scenario import (
    MANEUVER_FIELDS,
    PLANT_FIELDS,
    controller_label,
    parse_scenario,
    read_toml,
)

__all__ = [
    "METRICS",
    "Battery",
    "BatteryError",
    "BatteryOutcome",
    "Distribution",
    "RunSpec",
    "default_workers",
    "execute_run",
    "get_field",
    "load_battery",
    "local_dask_cluster",
    "parse_battery",
    "plan_runs",
    "read_journal",
    "result_rows",
    "run_battery",
    "summary_markdown",
    "write_outputs",
]

#: Extra top-level tables of a battery file.
BATTERY_TABLES = ("sweep", "monte_carlo", "battery")
#: Metrics per iteration, as :func:`papwc.recording.summarize` returns them.
METRICS = ("final_error_m", "pulses", "settle_time_s", "limit_cycle", "cycle_p2p_m",
           "b_hat", "f_c_hat")
#: Fields that cannot be drawn from a distribution (whole numbers or words).
NOT_DRAWABLE = {"maneuver.iterations", "maneuver.noise_seed", "maneuver.timing",
                "controller.rest_samples", "controller.kind", "controller.label"}
JOURNAL_NAME = "journal.jsonl"
JOURNAL_FORMAT = 1
DISTRIBUTIONS = {
    "uniform": (("rel",), ("abs",), ("low", "high")),
    "normal": (("std",), ("rel_std",), ("mean", "std")),
}


class BatteryError(PapwcError):
    """A battery cannot run: its output folder, journal, FMU or cluster is not usable."""


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
    """

    name: str
    source: str
    data: dict
    n_controllers: int
    sweep: list[tuple[str, list]] = field(default_factory=list)
    draws: list[Distribution] = field(default_factory=list)
    n: int = 1
    seed: int = 0
    monte_carlo: bool = False
    success_tolerance: float | None = None

    @property
    def varied(self) -> list[str]:
        """Paths that differ between runs, sweep first."""
        out = [p for p, _ in self.sweep]
        return out + [d.path for d in self.draws if d.path not in out]


def load_battery(path: str | os.PathLike) -> Battery:
    """Read and validate a battery file.

    Raises
    ------
    ScenarioError
        Naming the file and the field that are wrong.
    """
    return parse_battery(read_toml(path, "battery"), str(path))


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_path(source: str, table: str, path: str, n_controllers: int, drawn: bool) -> None:
    """Raise ScenarioError unless ``path`` names a field a battery can vary."""
    parts = path.split(".")
    where = f"{source}: [{table}] field {path!r}"
    head = parts[0]
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

    sweep = data.get("sweep", {})
    if not isinstance(sweep, dict):
        raise ScenarioError(f"{source}: [sweep] must be a table of path = [values]")
    for path, values in sweep.items():
        _check_path(source, "sweep", path, n_ctrl, drawn=False)
        if not isinstance(values, list) or not values:
            raise ScenarioError(f"{source}: [sweep] field {path!r} = {values!r}: must be a "
                                "non-empty array of values")
        for v in values:
            if not (_is_number(v) or isinstance(v, str)):
                raise ScenarioError(f"{source}: [sweep] field {path!r}: value {v!r} must be "
                                    "a number or a string")
        battery.sweep.append((path, list(values)))

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

    opts = data.get("battery", {})
    if not isinstance(opts, dict):
        raise ScenarioError(f"{source}: [battery] must be a table")
    for key, value in opts.items():
        if key != "success_tolerance":
            raise ScenarioError(f"{source}: [battery] unknown field {key!r}; allowed: "
                                "success_tolerance")
        if not (_is_number(value) and math.isfinite(value) and value >= 0.0):
            raise ScenarioError(f"{source}: [battery] field 'success_tolerance' = {value!r}: "
                                "must be a number >= 0 (m)")
        battery.success_tolerance = float(value)
    return battery


def _parse_distribution(source: str, path: str, spec, n_ctrl: int) -> Distribution:
    where = f"{source}: [monte_carlo] field {path!r}"
    _check_path(source, "monte_carlo", path, n_ctrl, drawn=True)
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
        if not (_is_number(value) and math.isfinite(value)):
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


# --- resolving runs -------------------------------------------------------------------------


@dataclass
class RunSpec:
    """One resolved run of a battery.

    Attributes
    ----------
    battery : str
        Name of the battery it belongs to.
    run_id : str
        Stable id within the battery (from its grid point and draw).
    order : tuple of int
        (battery number, grid point, draw): the order of results.
    data : dict
        The scenario of this run, every varied field replaced.
    run_hash : str
        First 12 hex digits of the SHA-256 of ``data`` as canonical JSON.
    error : str
        Why ``data`` is not a valid scenario ("" if it is).
    """

    battery: str
    run_id: str
    order: tuple[int, int, int]
    data: dict
    run_hash: str
    error: str = ""

    def task(self, source: str) -> dict:
        """What a worker needs to run it (picklable)."""
        return {"battery": self.battery, "run_id": self.run_id, "run_hash": self.run_hash,
                "source": source, "data": self.data}


def _tables(data: dict) -> list[dict]:
    tables = data.get("controller", [])
    return [tables] if isinstance(tables, dict) else list(tables)


def _default(head: str, name: str):
    if head == "plant":
        return PLANT_FIELDS[name]
    if head == "maneuver":
        return getattr(Maneuver(), name)
    return getattr(ControllerSettings(), ControllerSettings.KEY_ALIASES.get(name, name))


def get_field(data: dict, path: str, table: int | None = None):
    """Value of ``path`` in a scenario mapping (its default if absent).

    ``table`` (0-based) picks the ``[[controller]]`` table of a ``controller.F``
    path; ``controller.N.F`` names its table itself.
    """
    parts = path.split(".")
    if parts[0] in ("plant", "maneuver"):
        return data.get(parts[0], {}).get(parts[1], _default(parts[0], parts[1]))
    if len(parts) == 3:
        table = int(parts[1]) - 1
    tables = _tables(data)
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
    """Replace the drawn fields of ``data`` (one grid point) for draw ``draw``."""
    ordered = [d for d in battery.draws if d.of is None] + [d for d in battery.draws if d.of]
    for d in ordered:
        u = _uniform(battery.seed, draw, d.path)
        of_value = None
        if d.of is not None:
            of_value = get_field(data, d.of)
            if not _is_number(of_value):
                raise ScenarioError(f"{battery.source}: [monte_carlo] field {d.path!r}: "
                                    f"of = {d.of!r} is {of_value!r}, not a number")
        parts = d.path.split(".")
        if parts[0] == "controller" and len(parts) == 2:
            targets = list(range(battery.n_controllers))
        else:
            targets = [None]
        for table in targets:
            nominal = get_field(data, d.path, table)
            if d.needs_nominal() and not _is_number(nominal):
                raise ScenarioError(
                    f"{battery.source}: [monte_carlo] field {d.path!r}: the nominal value "
                    f"is {nominal!r}; give it in the file or use low/high or mean/std")
            _set_field(data, d.path, d.value(u, nominal, of_value), table)


def plan_runs(batteries: list[Battery]) -> list[RunSpec]:
    """Every run of the batteries, resolved and validated, in result order.

    Raises
    ------
    ScenarioError
        If two batteries have the same name or a draw cannot be resolved.
    """
    names = [b.name for b in batteries]
    for name in names:
        if names.count(name) > 1:
            sources = [b.source for b in batteries if b.name == name]
            raise ScenarioError(f"{sources[1]}: field 'name' = {name!r} is also the name of "
                                f"{sources[0]}; battery names must differ")
    runs = []
    for bi, battery in enumerate(batteries):
        grid = list(itertools.product(*(values for _, values in battery.sweep)))
        gw = max(1, len(str(len(grid) - 1)))
        dw = max(3, len(str(battery.n - 1)))
        for gi, point in enumerate(grid):
            point_data = copy.deepcopy(battery.data)
            for (path, _), value in zip(battery.sweep, point, strict=True):
                _set_field(point_data, path, value)
            for di in range(battery.n):
                data = copy.deepcopy(point_data)
                if battery.monte_carlo:
                    _apply_draws(battery, data, di)
                ids = ([f"s{gi:0{gw}d}"] if battery.sweep else []) + (
                    [f"d{di:0{dw}d}"] if battery.monte_carlo else [])
                run_id = "-".join(ids) or "nominal"
                spec = RunSpec(battery.name, run_id, (bi, gi, di), data, _hash(data))
                try:
                    parse_scenario(data, f"{battery.source} run {run_id}")
                except ScenarioError as exc:
                    spec.error = str(exc)
                runs.append(spec)
    return runs


# --- running one run (in a worker) ----------------------------------------------------------

_FMU_CACHE: dict[str, tuple[str, str]] = {}
_FMU_LOCK = threading.Lock()


#: Prefix of the temporary folders of a worker process; the process id follows it.
_TMP_PREFIX = "papwcbattery"


def _private_dir() -> str:
    """A temporary folder named after this process; those of dead processes are removed."""
    root = Path(tempfile.gettempdir())
    for entry in root.glob(f"{_TMP_PREFIX}*_*"):
        pid = entry.name[len(_TMP_PREFIX):].split("_", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            shutil.rmtree(entry, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f"{_TMP_PREFIX}{os.getpid()}_")


def _extract(fmu_path: str) -> str:
    """Extract an FMU into a private temporary folder removed when the process exits.

    A process killed before it could remove its folder leaves it behind; the
    next worker that extracts an FMU removes it.
    """
    from fmpy import extract

    unzip_dir = _private_dir()
    extract(fmu_path, unzipdir=unzip_dir)
    import atexit
    from multiprocessing import util

    atexit.register(shutil.rmtree, unzip_dir, True)
    util.Finalize(None, shutil.rmtree, args=(unzip_dir, True), exitpriority=10)
    return unzip_dir


def _cached_plant(digest: str, fmu_path: str | None = None, fmu_bytes: bytes | None = None):
    """(fmu path, extracted folder) of the FMU with SHA-256 ``digest``, extracted once."""
    with _FMU_LOCK:
        if digest not in _FMU_CACHE:
            if fmu_path is None:
                folder = _private_dir()
                import atexit

                atexit.register(shutil.rmtree, folder, True)
                fmu_path = os.path.join(folder, "plant.fmu")
                with open(fmu_path, "wb") as f:
                    f.write(fmu_bytes)
            _FMU_CACHE[digest] = (fmu_path, _extract(fmu_path))
        return _FMU_CACHE[digest]


def execute_run(task: dict, fmu_path: str, unzip_dir: str) -> dict:
    """Run every controller of one resolved run against fresh plant instances.

    Parameters
    ----------
    task : dict
        From :meth:`RunSpec.task`.
    fmu_path, unzip_dir : str
        The plant FMU and an extracted copy of it.

    Returns
    -------
    dict
        The journal record: the task's ids and ``params``, ``status`` (``"ok"`` or
        ``"error"``), ``message``, and per controller its label, kind,
        tolerance, error and the metrics of every iteration. Exceptions are
        caught and recorded, never raised.
    """
    from papwc.master import FmuSlave, run_controller, summarize

    start = time.perf_counter()
    record = {"type": "run", "battery": task["battery"], "run_id": task["run_id"],
              "run_hash": task["run_hash"], "params": task["data"], "status": "ok",
              "message": "", "controllers": []}
    try:
        scenario = parse_scenario(task["data"], f"{task['source']} run {task['run_id']}")
        for settings, label in zip(scenario.controllers, scenario.labels, strict=True):
            slave = FmuSlave(fmu_path, unzip_dir=unzip_dir)
            try:
                slave.set_start_values(scenario.plant)
                result = run_controller(slave, settings, scenario.maneuver, label)
            finally:
                slave.close()
            iterations = []
            for trace in result.traces:
                metrics = summarize(trace, settings.tolerance)
                iterations.append({"iteration": trace.iteration, **metrics,
                                   "error": trace.error})
            record["controllers"].append({
                "label": label, "kind": settings.kind, "tolerance": settings.tolerance,
                "error": result.error, "iterations": iterations})
            if result.error and record["status"] == "ok":
                record["status"] = "error"
                record["message"] = f"{label}: {result.error}"
    except Exception as exc:  # noqa: BLE001 - a failing run is recorded, the battery goes on
        record["status"] = "error"
        record["message"] = f"{type(exc).__name__}: {exc}"
    record["elapsed_s"] = time.perf_counter() - start
    return record


def _error_record(spec: RunSpec, message: str) -> dict:
    return {"type": "run", "battery": spec.battery, "run_id": spec.run_id,
            "run_hash": spec.run_hash, "params": spec.data, "status": "error",
            "message": message, "controllers": [], "elapsed_s": 0.0}


_LOCAL: dict[str, str] = {}


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat.rsplit(")", 1)[-1].split()[0] not in ("Z", "X")


def _watch_owner(owner: int) -> None:
    while True:
        time.sleep(0.5)
        if not _alive(owner):
            if "unzip_dir" in _LOCAL:
                shutil.rmtree(_LOCAL["unzip_dir"], ignore_errors=True)
            os._exit(1)


def _init_local_worker(fmu_path: str, owner: int) -> None:
    """Initializer of a local worker process: extract the FMU once, ignore Ctrl-C.

    The worker exits by itself when ``owner`` (the process running the battery)
    is gone, e.g. killed: the worker is a child of the forkserver, which would
    otherwise keep it.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_owner, args=(owner,), daemon=True).start()
    _LOCAL["fmu_path"] = fmu_path
    _LOCAL["unzip_dir"] = _extract(fmu_path)


def _run_in_local_worker(task: dict) -> dict:
    return execute_run(task, _LOCAL["fmu_path"], _LOCAL["unzip_dir"])


def _run_in_dask_worker(tasks: list[dict], fmu_bytes: bytes, digest: str) -> list[dict]:
    """A Dask task: a few runs; the FMU comes as bytes; each worker process extracts it once."""
    fmu_path, unzip_dir = _cached_plant(digest, fmu_bytes=fmu_bytes)
    return [execute_run(task, fmu_path, unzip_dir) for task in tasks]


# --- engines ----------------------------------------------------------------------------------


def default_workers() -> int:
    """Number of cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def _mp_context():
    import multiprocessing

    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def _run_local(tasks: list[dict], fmu_path: Path, workers: int,
               on_done: Callable[[dict], None]) -> None:
    """Run tasks in a pool of ``workers`` processes; call ``on_done(record)`` as each ends.

    At most two tasks per worker are queued at a time. If a worker process dies
    (e.g. the FMU crashed it), the tasks that were queued are run again one per
    fresh single-process pool, so the one that kills its worker is recorded as an
    error and the others are not affected.
    """
    pending = list(reversed(tasks))
    suspects: list[dict] = []

    def pool(n: int) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=n, mp_context=_mp_context(),
                                   initializer=_init_local_worker,
                                   initargs=(str(fmu_path), os.getpid()))

    while pending:
        executor = pool(workers)
        in_flight: dict = {}
        broken = False
        try:
            while (pending or in_flight) and not broken:
                while pending and len(in_flight) < 2 * workers:
                    task = pending.pop()
                    in_flight[executor.submit(_run_in_local_worker, task)] = task
                done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                for fut in done:
                    task = in_flight.pop(fut)
                    try:
                        on_done(fut.result())
                    except BrokenProcessPool:
                        suspects.append(task)
                        broken = True
            suspects.extend(in_flight.values())
        finally:
            executor.shutdown(wait=True, cancel_futures=True)
        for task in suspects:
            with pool(1) as single:
                try:
                    on_done(single.submit(_run_in_local_worker, task).result())
                except BrokenProcessPool:
                    on_done(_task_error(task, "the worker process running it died "
                                        "(e.g. the FMU crashed the process)"))
        suspects = []


def _task_error(task: dict, message: str) -> dict:
    return {"type": "run", "battery": task["battery"], "run_id": task["run_id"],
            "run_hash": task["run_hash"], "params": task["data"], "status": "error",
            "message": message, "controllers": [], "elapsed_s": 0.0}


def _run_dask(tasks: list[dict], fmu_path: Path, digest: str, scheduler: str,
              on_done: Callable[[dict], None]) -> None:
    """Run tasks on a Dask distributed cluster; the FMU travels as bytes, scattered once."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError as exc:
        raise BatteryError("--scheduler needs dask[distributed]: pip install "
                           "'papwc[dask]'") from exc
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise BatteryError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from exc
    try:
        try:
            client.wait_for_workers(1, timeout=60)
        except TimeoutError as exc:
            raise BatteryError(f"the Dask scheduler at {scheduler} has no worker "
                               "(waited 60 s)") from exc
        fmu_future = client.scatter(fmu_path.read_bytes(), broadcast=True, hash=False)
        # Runs take tens of milliseconds; a few per task keep the scheduler's per-task
        # cost small while every worker still gets several tasks (and each finished
        # task's runs are persisted as soon as it ends).
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        size = max(1, min(8, len(tasks) // (8 * n_workers)))
        futures = {}
        for i in range(0, len(tasks), size):
            chunk = tasks[i : i + size]
            first = chunk[0]
            key = (f"papwc-battery-{first['battery']}-{first['run_id']}-{first['run_hash']}"
                   f"-{len(chunk)}")
            fut = client.submit(_run_in_dask_worker, chunk, fmu_future, digest, key=key,
                                pure=False)
            futures[fut] = chunk
        try:
            for fut in as_completed(futures):
                chunk = futures[fut]
                if fut.status == "finished":
                    for record in fut.result():
                        on_done(record)
                else:
                    exc = fut.exception()
                    for task in chunk:
                        on_done(_task_error(task, f"Dask task failed: {type(exc).__name__}: "
                                            f"{exc}"))
                fut.release()
        finally:
            client.cancel(list(futures))
    finally:
        client.close()


# --- journal ---------------------------------------------------------------------------------


def read_journal(path: Path) -> tuple[dict | None, list[dict], int]:
    """Header, run records and the size in bytes of the complete lines of a journal.

    A last line that is not complete JSON (the writer was killed) is ignored;
    a bad line before the last one raises :class:`BatteryError`.
    """
    header, records, good = None, [], 0
    with open(path, "rb") as f:
        lines = f.read().split(b"\n")
    offset = 0
    for i, line in enumerate(lines):
        end = offset + len(line) + 1
        is_last = i == len(lines) - 1 or (i == len(lines) - 2 and lines[-1] == b"")
        if not line:
            offset = end
            continue
        try:
            obj = json.loads(line)
            if not isinstance(obj, dict) or i == len(lines) - 1:
                raise ValueError("incomplete line")
        except ValueError as exc:
            if is_last:
                break
            raise BatteryError(f"{path}: line {i + 1} is not a journal record") from exc
        if obj.get("type") == "header":
            header = obj
        elif obj.get("type") == "run":
            records.append(obj)
        offset = good = end
    return header, records, good


class Journal:
    """Append-only JSON-lines file of finished runs, fsync'ed per record and locked."""

    def __init__(self, path: Path, header: dict, resume: bool, overwrite: bool) -> None:
        self.path = path
        self.records: dict[tuple[str, str], dict] = {}
        path.parent.mkdir(parents=True, exist_ok=True)
        lock_path = path.with_name(path.name + ".lock")
        self._lock = open(lock_path, "a")  # held until close()
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._lock.close()
            raise BatteryError(f"{path.parent}: another battery is writing into this "
                               "folder") from None
        try:
            self._open(header, resume, overwrite)
        except BaseException:
            self._lock.close()
            raise

    def _open(self, header: dict, resume: bool, overwrite: bool) -> None:
        path = self.path
        if path.exists() and resume:
            old, records, good = read_journal(path)
            if old is not None and old.get("fingerprint") != header["fingerprint"]:
                why = ("the plant FMU differs" if old.get("fmu_sha256") != header["fmu_sha256"]
                       else "the battery files resolve to other runs")
                raise BatteryError(f"{path}: cannot resume: {why} than when it was started; "
                                   "use another --out, or --overwrite to start again")
            if old is not None:
                with open(path, "r+b") as f:
                    f.truncate(good)
                    f.flush()
                    os.fsync(f.fileno())
                self.records = {(r["battery"], r["run_id"]): r for r in records}
                self._file = open(path, "a", encoding="utf-8")
                return
        elif path.exists() and not overwrite and read_journal(path)[1]:
            _, records, _ = read_journal(path)
            raise BatteryError(f"{path.parent} already holds a battery journal "
                               f"({len(records)} runs); pass --resume to continue it or "
                               "--overwrite to start again")
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(json.dumps(header) + "\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        self._file = open(path, "a", encoding="utf-8")

    def append(self, record: dict) -> None:
        """Persist one record (flush and fsync) and keep it."""
        self._file.write(json.dumps(record) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())
        self.records[(record["battery"], record["run_id"])] = record

    def close(self) -> None:
        self._file.close()
        self._lock.close()


# --- results ---------------------------------------------------------------------------------


def _label_of(table: dict, i: int) -> str:
    """Label of a controller table that may not be valid."""
    label = table.get("label") if isinstance(table, dict) else None
    if isinstance(label, str) and label:
        return label
    try:
        t = float(table.get("t_p_max", math.inf))
        kind = str(table.get("kind"))
    except (TypeError, ValueError, AttributeError):
        return f"controller{i + 1}"
    return controller_label(ControllerSettings(kind=kind, t_p_max=t))


def result_rows(batteries: list[Battery], runs: list[RunSpec], records: dict) -> list[dict]:
    """Rows of results.csv: per run, controller and iteration, in run order."""
    by_name = {b.name: b for b in batteries}
    rows = []
    for spec in runs:
        rec = records[(spec.battery, spec.run_id)]
        battery = by_name[spec.battery]
        base = {"battery": spec.battery, "run_id": spec.run_id, "run_hash": spec.run_hash}
        ctrls = rec["controllers"]
        if not ctrls:
            for i, table in enumerate(_tables(spec.data)):
                row = {**base, "controller": _label_of(table, i),
                       "kind": table.get("kind", "") if isinstance(table, dict) else "",
                       "iteration": "", "last_iteration": True}
                row.update({p: _varied_value(spec.data, p, i) for p in battery.varied})
                row.update({"success": False, "status": "error", "message": rec["message"]})
                rows.append(row)
            continue
        for i, c in enumerate(ctrls):
            tol = (battery.success_tolerance if battery.success_tolerance is not None
                   else c["tolerance"])
            entries = [dict(it) for it in c["iterations"]]
            if c["error"] and (not entries or not entries[-1]["error"]):
                entries.append({"iteration": len(entries) + 1, "error": c["error"]})
            for j, it in enumerate(entries):
                row = {**base, "controller": c["label"], "kind": c["kind"],
                       "iteration": it["iteration"], "last_iteration": j == len(entries) - 1}
                row.update({p: _varied_value(spec.data, p, i) for p in battery.varied})
                row.update({m: it.get(m, "") for m in METRICS})
                ok = not it["error"]
                row["success"] = bool(ok and abs(it["final_error_m"]) <= tol
                                      and not it["limit_cycle"])
                row["status"] = "ok" if ok else "error"
                row["message"] = it["error"]
                rows.append(row)
    return rows


def _varied_value(data: dict, path: str, table: int):
    return get_field(data, path, table if path.startswith("controller.") else None)


def _flatten(data: dict) -> dict:
    out = {f"plant.{k}": v for k, v in PLANT_FIELDS.items()}
    out.update({f"plant.{k}": v for k, v in data.get("plant", {}).items()})
    out.update({f"maneuver.{k}": v for k, v in data.get("maneuver", {}).items()})
    for i, table in enumerate(_tables(data), start=1):
        if isinstance(table, dict):
            out.update({f"controller.{i}.{k}": v for k, v in table.items()})
    return out


def _stats(values: list[float]) -> tuple[float, float, float]:
    import numpy as np

    if not values:
        return (math.nan, math.nan, math.nan)
    a = np.asarray(values, dtype=float)
    return float(np.median(a)), float(np.percentile(a, 95)), float(a.max())


def _fmt(x: float, spec: str) -> str:
    return "–" if isinstance(x, float) and math.isnan(x) else format(x, spec)


def summary_markdown(batteries: list[Battery], runs: list[RunSpec], rows: list[dict],
                     fmu_sha256: str) -> str:
    """The text of summary.md."""
    lines = ["# Battery results", ""]
    failed_keys = {(r["battery"], r["run_id"]) for r in rows if r["status"] == "error"}
    n_err = len(failed_keys)
    lines.append(f"{len(runs)} runs, {n_err} with status error. Plant FMU SHA-256: "
                 f"`{fmu_sha256[:16]}…`.")
    lines += ["", "**Success**: a controller succeeds in a run when, in the last iteration, "
              "the run has status ok, |final error| <= the success tolerance (the battery's "
              "`success_tolerance`, else the controller's `tolerance`) and there is no limit "
              "cycle (pulses in both directions in the final quarter of the iteration). "
              "Errors and pulses are taken over the runs with status ok, in the last "
              "iteration; settle times over those that settled.", ""]
    last = [r for r in rows if r["last_iteration"]]
    for battery in batteries:
        b_runs = [s for s in runs if s.battery == battery.name]
        tol = (f"{battery.success_tolerance:g} m" if battery.success_tolerance is not None
               else "each controller's tolerance")
        grid = math.prod(len(v) for _, v in battery.sweep)
        lines += [f"## {battery.name}", "",
                  f"File `{battery.source}`: {len(b_runs)} runs ({grid} grid point(s) × "
                  f"{battery.n} draw(s)"
                  + (f", seed {battery.seed}" if battery.monte_carlo else "")
                  + f"); success tolerance: {tol}.", ""]
        if battery.varied:
            lines += ["Varied: " + ", ".join(f"`{p}`" for p in battery.varied) + ".", ""]
        lines += ["| controller | runs | errors | success | limit cycles | abs(e) median (m) | "
                  "abs(e) p95 (m) | abs(e) max (m) | pulses median | p95 | max | settled | "
                  "settle median (s) | p95 | max |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        b_rows = [r for r in last if r["battery"] == battery.name]
        for label in dict.fromkeys(r["controller"] for r in b_rows):
            cr = [r for r in b_rows if r["controller"] == label]
            ok = [r for r in cr if r["status"] == "ok"]
            succ = sum(1 for r in cr if r["success"])
            cycles = sum(1 for r in ok if r["limit_cycle"])
            e = _stats([abs(r["final_error_m"]) for r in ok])
            p = _stats([float(r["pulses"]) for r in ok])
            settled = [r["settle_time_s"] for r in ok if not math.isnan(r["settle_time_s"])]
            s = _stats(settled)
            lines.append(
                f"| {label} | {len(cr)} | {len(cr) - len(ok)} | {succ / len(cr):.1%} | "
                f"{cycles} | {_fmt(e[0], '.3g')} | {_fmt(e[1], '.3g')} | {_fmt(e[2], '.3g')} | "
                f"{_fmt(p[0], '.0f')} | {_fmt(p[1], '.1f')} | {_fmt(p[2], '.0f')} | "
                f"{len(settled)} | {_fmt(s[0], '.3f')} | {_fmt(s[1], '.3f')} | "
                f"{_fmt(s[2], '.3f')} |")
        lines += ["", f"Distribution of |final error|: `final_error_{battery.name}.png`.", ""]
        failed = [s for s in b_runs if (s.battery, s.run_id) in failed_keys]
        if failed:
            lines += [f"Runs with status error ({len(failed)}):", ""]
            for s in failed[:20]:
                msg = next(r["message"] for r in rows if r["battery"] == s.battery
                           and r["run_id"] == s.run_id and r["status"] == "error")
                lines.append(f"- `{s.run_id}`: {msg}")
            if len(failed) > 20:
                lines.append(f"- … and {len(failed) - 20} more (see results.csv)")
            lines.append("")
    return "\n".join(lines)


def plot_final_errors(battery: Battery, rows: list[dict], path: Path) -> None:
    """Empirical CDF of |final error| per controller (last iteration), log x axis, as PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    floor = 1e-12
    last = [r for r in rows if r["last_iteration"] and r["battery"] == battery.name
            and r["status"] == "ok"]
    tols = {}
    for label in dict.fromkeys(r["controller"] for r in last):
        errs = sorted(max(abs(r["final_error_m"]), floor) for r in last
                      if r["controller"] == label)
        n = len(errs)
        ax.step(errs, [(i + 1) / n for i in range(n)], where="post", label=f"{label} ({n})")
    if battery.success_tolerance is not None:
        tols["success tolerance"] = battery.success_tolerance
    for name, tol in tols.items():
        if tol > 0:
            ax.axvline(tol, color="k", ls=":", lw=1, label=f"{name} {tol:g} m")
    ax.set_xscale("log")
    ax.set_xlabel(f"|final error| in the last iteration, m (values below {floor:g} drawn at it)")
    ax.set_ylabel("fraction of runs")
    ax.set_ylim(0.0, 1.02)
    ax.set_title(f"{battery.name}: final error per controller")
    ax.grid(True, which="both", alpha=0.3)
    if last:
        ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def write_outputs(out: Path, batteries: list[Battery], runs: list[RunSpec], records: dict,
                  fmu_sha256: str) -> list[Path]:
    """Write results.csv, runs.csv, summary.md and the plots from the records."""
    from papwc.output import write_rows

    rows = result_rows(batteries, runs, records)
    varied = list(dict.fromkeys(p for b in batteries for p in b.varied))
    columns = (["battery", "run_id", "run_hash", "controller", "kind", "iteration",
                "last_iteration"] + varied + list(METRICS) + ["success", "status", "message"])
    paths = [out / "results.csv", out / "runs.csv", out / "summary.md"]
    write_rows(paths[0], rows, columns)
    run_rows = []
    for spec in runs:
        rec = records[(spec.battery, spec.run_id)]
        run_rows.append({"battery": spec.battery, "run_id": spec.run_id,
                         "run_hash": spec.run_hash, "status": rec["status"],
                         "message": rec["message"], **_flatten(spec.data)})
    run_columns = ["battery", "run_id", "run_hash", "status", "message"]
    run_columns += list(dict.fromkeys(k for r in run_rows for k in r if k not in run_columns))
    write_rows(paths[1], run_rows, run_columns)
    tmp = paths[2].with_name("summary.md.tmp")
    tmp.write_text(summary_markdown(batteries, runs, rows, fmu_sha256), encoding="utf-8")
    os.replace(tmp, paths[2])
    for battery in batteries:
        png = out / f"final_error_{battery.name}.png"
        plot_final_errors(battery, rows, png)
        paths.append(png)
    return paths


# --- the whole battery -----------------------------------------------------------------------


@dataclass
class BatteryOutcome:
    """What :func:`run_battery` did.

    Attributes
    ----------
    runs : int
        Runs in the batteries.
    computed : int
        Runs computed in this call (the others came from the journal).
    failed : list of (battery, run id, message)
        Runs with status error.
    files : list of Path
        Files written.
    seconds : float
        Wall time of the call.
    run_seconds : float
        Wall time of the computing (starting the workers or connecting to the
        cluster, up to the last run finished).
    """

    runs: int
    computed: int
    failed: list[tuple[str, str, str]]
    files: list[Path]
    seconds: float
    run_seconds: float = 0.0


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def run_battery(
    batteries: list[Battery],
    out: str | os.PathLike,
    fmu: str | os.PathLike,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = True,
) -> BatteryOutcome:
    """Run batteries and write their results into ``out``.

    Parameters
    ----------
    batteries : list of Battery
        From :func:`load_battery`; names must differ.
    out : path
        Output folder (created); holds the journal and the results.
    fmu : path
        The plant FMU (FrictionPlant.fmu).
    workers : int, optional
        Local worker processes (default: the number of cores). Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://HOST:PORT``) to run on instead.
    resume : bool
        Continue the journal in ``out``: runs it holds are not computed again.
    overwrite : bool
        Start afresh even if ``out`` holds a journal.
    progress : bool
        Show a progress bar on stderr (only if stderr is a terminal).

    Returns
    -------
    BatteryOutcome
    """
    start = time.perf_counter()
    out = Path(out)
    fmu = Path(fmu)
    if not fmu.is_file():
        raise BatteryError(f"plant FMU {str(fmu)!r} does not exist")
    from fmpy import read_model_description

    try:
        cosim = read_model_description(str(fmu)).coSimulation
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain Exceptions for broken files
        raise BatteryError(f"{fmu}: not a readable FMU: {exc}") from exc
    if cosim is None:
        raise BatteryError(f"{fmu}: not a Co-Simulation FMU")
    runs = plan_runs(batteries)
    digest = _sha256(fmu)
    fingerprint = hashlib.sha256(json.dumps(
        [digest] + [[s.battery, s.run_id, s.run_hash] for s in runs]).encode()).hexdigest()
    header = {"type": "header", "format": JOURNAL_FORMAT, "fingerprint": fingerprint,
              "fmu_sha256": digest, "batteries": [[b.name, b.source] for b in batteries],
              "runs": len(runs)}
    journal = Journal(out / JOURNAL_NAME, header, resume, overwrite)
    computed = 0
    try:
        todo = [s for s in runs if (s.battery, s.run_id) not in journal.records]
        from tqdm import tqdm

        bar = tqdm(total=len(runs), initial=len(runs) - len(todo), unit="run",
                   desc="battery", file=sys.stderr, dynamic_ncols=True,
                   disable=not (progress and sys.stderr.isatty()))

        def done(record: dict) -> None:
            nonlocal computed
            journal.append(record)
            computed += 1
            bar.update(1)

        with bar:
            for spec in todo:
                if spec.error:
                    done(_error_record(spec, spec.error))
            sources = {b.name: b.source for b in batteries}
            tasks = [s.task(sources[s.battery]) for s in todo if not s.error]
            run_start = time.perf_counter()
            if tasks:
                if scheduler:
                    _run_dask(tasks, fmu, digest, scheduler, done)
                else:
                    n = workers or default_workers()
                    _run_local(tasks, fmu, max(1, min(n, len(tasks))), done)
            run_seconds = time.perf_counter() - run_start
        records = journal.records
    finally:
        journal.close()
    files = write_outputs(out, batteries, runs, records, digest)
    failed = [(s.battery, s.run_id, records[(s.battery, s.run_id)]["message"]) for s in runs
              if records[(s.battery, s.run_id)]["status"] != "ok"]
    return BatteryOutcome(len(runs), computed, failed, files, time.perf_counter() - start,
                          run_seconds)


# --- a Dask cluster of local processes (tests, benchmarks) -----------------------------------


def _stop(proc: subprocess.Popen) -> None:
    """Stop a process started in its own session, and its children."""
    if proc.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)


@contextlib.contextmanager
def local_dask_cluster(n_workers: int = 1, nthreads: int = 1,
                       timeout: float = 60.0) -> Iterator[str]:
    """Start ``dask scheduler`` and ``dask worker`` (the CLI) on 127.0.0.1; yield the address.

    The scheduler picks a free port and writes it to a scheduler file; the
    worker runs ``n_workers`` processes of ``nthreads`` threads, no dashboards.
    Both are stopped (their process groups) when the block ends.
    """
    dask_cli = Path(sys.executable).with_name("dask")
    cmd = [str(dask_cli)] if dask_cli.is_file() else [sys.executable, "-m", "dask"]
    with tempfile.TemporaryDirectory(prefix="papwcdask") as tmp:
        sched_file = Path(tmp) / "scheduler.json"
        procs: list[subprocess.Popen] = []
        logs = [open(Path(tmp) / name, "wb")
                for name in ("scheduler.log", "worker.log")]
        try:
            procs.append(subprocess.Popen(
                cmd + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                       "--scheduler-file", str(sched_file)],
                stdout=logs[0], stderr=subprocess.STDOUT, start_new_session=True, cwd=tmp))
            deadline = time.monotonic() + timeout
            address = None
            while address is None:
                if procs[0].poll() is not None or time.monotonic() > deadline:
                    raise BatteryError("dask scheduler did not start: "
                                       + (Path(tmp) / "scheduler.log").read_text()[-2000:])
                with contextlib.suppress(FileNotFoundError, ValueError):
                    address = json.loads(sched_file.read_text())["address"]
                time.sleep(0.05)
            procs.append(subprocess.Popen(
                cmd + ["worker", address, "--host", "127.0.0.1", "--no-dashboard",
                       "--nworkers", str(n_workers), "--nthreads", str(nthreads),
                       "--local-directory", tmp],
                stdout=logs[1], stderr=subprocess.STDOUT, start_new_session=True, cwd=tmp))
            from dask.distributed import Client

            with Client(address, timeout="20s") as client:
                try:
                    client.wait_for_workers(n_workers, timeout=timeout)
                except TimeoutError as exc:
                    raise BatteryError("dask worker did not connect: " + (
                        Path(tmp) / "worker.log").read_text()[-2000:]) from exc
            yield address
        finally:
            for proc in reversed(procs):
                _stop(proc)
            for f in logs:
                f.close()



# --- benchmark ------------------------------------------------------------------------------

#: The battery of the benchmark: the PWC and PAPWC of scenarios/robustness.toml, ``n`` draws.
BENCH_BATTERY = """\
name = "bench"
[plant]
m = 150.0
f_c = 100.0
f_s = 130.0
c = 700.0
[maneuver]
x_ref = 0.01
T = 0.01
duration = 2.0
iterations = 3
[[controller]]
kind = "pwc"
f_p_max = 300.0
t_p_max = 0.03
K_c = 0.5
tolerance = 0.0
m_est = 150.0
f_c_est = 80.0
F_inv0 = 1e-5
[[controller]]
kind = "papwc"
f_p_max = 300.0
t_p_max = 0.03
K_c = 0.8
tolerance = 2e-5
m_est = 150.0
f_c_est = 80.0
delta_inv = 1e-5
[monte_carlo]
n = {n}
seed = 20240
"plant.m" = {{ dist = "uniform", rel = 0.3 }}
"plant.f_c" = {{ dist = "uniform", rel = 0.3 }}
"plant.c" = {{ dist = "uniform", rel = 0.3 }}
"plant.f_s" = {{ dist = "uniform", low = 1.0, high = 1.6, of = "plant.f_c" }}
"controller.m_est" = {{ dist = "uniform", low = 0.8, high = 1.2, of = "plant.m" }}
"controller.f_c_est" = {{ dist = "uniform", low = 0.8, high = 1.2, of = "plant.f_c" }}
"""

#: Goals: 2 local workers at least this many times as fast as 1 ...
SPEEDUP_GOAL = 1.8
#: ... and the Dask cluster (same number of worker processes) at most this multiple of
#: the local pool's time.
DASK_RATIO_GOAL = 1.2


def _spin(n: int) -> float:
    """CPU-bound control task of the benchmark: a pure-Python loop."""
    x = 0
    for i in range(n):
        x += i * i
    return float(x % 7)


def _control_speedup(n: int) -> float:
    """Speed-up of 4 pure-Python loops from 1 to 2 processes: what the machine gives now."""
    seconds = []
    for workers in (1, 2):
        with ProcessPoolExecutor(max_workers=workers, mp_context=_mp_context()) as ex:
            list(ex.map(_spin, [1000] * workers))  # start the workers
            start = time.perf_counter()
            list(ex.map(_spin, [n] * 4))
            seconds.append(time.perf_counter() - start)
    return seconds[0] / seconds[1]


def bench_section(context) -> list:
    """``papwc bench`` section: battery throughput, local pool (1, 2 workers) and Dask.

    Runs the robustness battery (2 controllers x 3 iterations per run) with 1
    and 2 local worker processes and on a Dask cluster of 2 worker processes
    (started with the ``dask`` CLI on 127.0.0.1), interleaved over rounds;
    times are medians of the computing phase (workers' start included, reports
    excluded). Each round also measures a control: the speed-up of a
    pure-Python loop from 1 to 2 processes, i.e. what the machine gives at the
    time. Then the time for 20, 40 and 80 runs with 2 local workers.

    Parameters
    ----------
    context : papwc.bench.BenchContext
        Gives the FMU folder and ``quick``.

    Returns
    -------
    list of papwc.bench.Row
    """
    import statistics

    from papwc.bench import Row

    fmu = context.fmu("FrictionPlant.fmu")
    n_runs, rounds = (12, 1) if context.quick else (200, 2)
    sizes = (10, 20) if context.quick else (20, 40, 80)
    times: dict[str, list[float]] = {"local 1": [], "local 2": [], "dask 2": []}
    control: list[float] = []
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        def battery(n: int) -> Battery:
            return parse_battery(tomllib.loads(BENCH_BATTERY.format(n=n)), "bench battery")

        def timed(n: int, **kwargs) -> float:
            out = Path(tempfile.mkdtemp(dir=tmp))
            outcome = run_battery([battery(n)], out, fmu, progress=False, **kwargs)
            if outcome.failed:
                raise BatteryError(f"bench battery: {outcome.failed[0]}")
            return outcome.run_seconds

        timed(4, workers=1)  # warm-up: imports, page cache
        with local_dask_cluster(n_workers=2, nthreads=1) as address:
            for r in range(rounds):
                control.append(_control_speedup(1_000_000 if context.quick else 3_000_000))
                order = ["local 1", "local 2", "dask 2"]
                for name in order[r % 3:] + order[: r % 3]:
                    if name == "dask 2":
                        times[name].append(timed(n_runs, scheduler=address))
                    else:
                        times[name].append(timed(n_runs, workers=int(name[-1])))
        growth = {n: timed(n, workers=2) for n in sizes}
    med = {k: statistics.median(v) for k, v in times.items()}
    speedup = med["local 1"] / med["local 2"]
    ratio = med["dask 2"] / med["local 2"]
    v1 = "met" if speedup >= SPEEDUP_GOAL else "MISSED"
    v2 = "met" if ratio <= DASK_RATIO_GOAL else "MISSED"
    context.notes.append(
        f"{n_runs} runs (robustness battery: 2 controllers x 3 iterations of 200 steps), "
        f"{rounds} interleaved round(s), medians; time from starting the workers (or "
        f"connecting to the scheduler) to the last run; {default_workers()} cores here; "
        "the control row is what two processes gain on this machine at the time (other "
        "load lowers it)")
    rows = [
        Row("local pool, 1 worker", n_runs / med["local 1"], "runs/s"),
        Row("local pool, 2 workers", n_runs / med["local 2"], "runs/s"),
        Row("Dask, 2 worker processes x 1 thread", n_runs / med["dask 2"], "runs/s"),
        Row(f"speed-up 1 -> 2 workers (goal >= {SPEEDUP_GOAL}: {v1})", speedup, "x"),
        Row(f"Dask time / local time (goal <= {DASK_RATIO_GOAL}: {v2})", ratio, "x"),
        Row("control: pure-Python loop, speed-up 1 -> 2 processes", statistics.median(control),
            "x"),
    ]
    for n, seconds in growth.items():
        rows.append(Row(f"{n} runs, 2 local workers", seconds, "s"))
    first, last = sizes[0], sizes[-1]
    per_run = (growth[last] - growth[first]) / (last - first)
    rows.append(Row(f"marginal cost per run ({first} -> {last} runs)", per_run * 1e3, "ms"))
    rows.append(Row("fixed cost (intercept)", growth[first] - per_run * first, "s"))
    return rows
