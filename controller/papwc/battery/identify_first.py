"""``[battery] identify_first``: each table identified through its encoder before it is
controlled.

For a run of a battery with ``identify_first = true`` the worker, before the controllers
run, applies the excitation of ``papwc identify --design`` (its defaults, at the maneuver's
sample period) to the run's table -- the battery's plant FMU with the run's ``[plant]``
values, read through its encoder (``x_meas``) -- identifies the table from that log
(:func:`papwc.identify.fit.identify`, on the FMU's C plant where it has one), and gives every
controller the identified plant in place of the values it was told
(:meth:`papwc.identify.plant_model.PlantModel.settings`: ``m_est``, ``f_c_est``, ``c_est``
and the stiction band, where its kind reads them).

The excitation runs on a fresh instance of the plant whose random stiction and encoder noise
are drawn under another seed (:data:`SEED_SHIFT` added to the table's, modulo the seed's
range): the identification does not see the draws the maneuvers will meet.

A table is identified once per worker process (:func:`identified_table`, cached by the
table's values and the sample period): the runs of one table (its targets, its
controllers, their iterations) share it. The journal record of each run holds what was
identified and the identification's processor time (``identified``); the battery writes
them to ``identified.csv``.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Mapping
from typing import Any

__all__ = ["CACHE_SIZE", "SEED_SHIFT", "check_excitable", "excitation_seed", "identified_table",
           "table_key"]

#: Added to a table's seed for the excitation's run (modulo the seed's range).
SEED_SHIFT = 104_729
#: Tables kept identified per worker process.
CACHE_SIZE = 256
_CACHE: dict[str, dict[str, Any]] = {}


def excitation_seed(seed: int) -> int:
    """The seed the excitation runs under for a table of seed ``seed``: :data:`SEED_SHIFT`
    added, modulo the seed's range (the model layer's ``seed``)."""
    from papwc.model.plant import PLANT_PARAMETERS
    from papwc.model.variables import by_name

    return (int(seed) + SEED_SHIFT) % (int(by_name(PLANT_PARAMETERS)["seed"].max) + 1)


def table_key(plant: Mapping[str, Any], T: float) -> str:
    """The identity of a table for the cache: its ``[plant]`` values and the period."""
    text = json.dumps({"plant": dict(plant), "T": T}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _excitation(T: float):
    from papwc.identify import DESIGN_DURATION, DESIGN_F_P_MAX, DESIGN_TRAVEL
    from papwc.identify.excitation import design

    return design(T, DESIGN_F_P_MAX, DESIGN_TRAVEL, DESIGN_DURATION)


def check_excitable(source: str, fmu_variables: Mapping[str, tuple[str, str]],
                    T_values: set[float]) -> None:
    """Refuse (ScenarioError, one line naming the battery file) a battery with
    ``identify_first`` whose plant FMU cannot be excited (no Real input ``u`` or no Real
    output ``x_meas``: ``fmu_variables`` maps a name to (causality, type)), or at whose
    sample periods ``T_values`` the excitation cannot be made, or where scipy (the extra
    ``identify``) is not installed."""
    from papwc.errors import ScenarioError
    from papwc.identify import IdentifyError, require_scipy
    from papwc.model.maneuver import LOG_SAMPLE_PERIOD

    try:
        require_scipy("[battery] identify_first = true")
    except IdentifyError as exc:
        raise ScenarioError(f"{source}: {exc}") from None
    for name, causality in (("u", "input"), ("x_meas", "output")):
        if fmu_variables.get(name) != (causality, "Real"):
            raise ScenarioError(f"{source}: [battery] identify_first = true: the plant FMU has "
                                f"no Real {causality} {name!r} to apply the excitation through "
                                "(force u) and read the table by (x_meas); give "
                                "FrictionPlant.fmu or set identify_first = false")
    period = LOG_SAMPLE_PERIOD
    for T in sorted(T_values):
        if not period.min <= T <= period.max:
            raise ScenarioError(f"{source}: [battery] identify_first = true: maneuver.T = {T!r} "
                                f"s: the excitation's sample period must be {period.min:g} to "
                                f"{period.max:g} s")
        try:
            _excitation(T)
        except IdentifyError as exc:
            raise ScenarioError(f"{source}: [battery] identify_first = true: at maneuver.T = "
                                f"{T!r} s the excitation cannot be made: {exc}") from None


def identified_table(plant: Mapping[str, Any], T: float, fmu_path: str, unzip_dir: str,
                     library: Any = None) -> dict[str, Any]:
    """The identification of one table (cached, see the module): a record with its values
    (:meth:`papwc.identify.plant_model.PlantModel.record`), the band's fields, ``cpu_s``
    (the excitation and the identification, s) and ``key``; or ``error`` (one line) if
    the plant refused the excitation or the log could not be identified."""
    key = table_key(plant, T)
    found = _CACHE.get(key)
    if found is not None:
        return {**found, "cached": True}
    began = time.process_time()
    record: dict[str, Any] = {"key": key}
    try:
        record.update(_identify(plant, T, fmu_path, unzip_dir, library))
    except Exception as exc:  # noqa: BLE001 - the run records it, the battery goes on
        record["error"] = f"identify_first: {type(exc).__name__}: {exc}"
    record["cpu_s"] = time.process_time() - began
    if len(_CACHE) >= CACHE_SIZE:
        del _CACHE[next(iter(_CACHE))]
    _CACHE[key] = record
    return dict(record)


def _identify(plant: Mapping[str, Any], T: float, fmu_path: str, unzip_dir: str,
              library: Any) -> dict[str, Any]:
    from papwc.identify.excitation import apply_to_fmu
    from papwc.identify.fit import identify
    from papwc.identify.plant_model import plant_model_of

    values = {**plant, "seed": excitation_seed(plant.get("seed", 0))}
    u = _excitation(T)
    log = apply_to_fmu(fmu_path, u, T, values, unzip_dir=unzip_dir)
    ident = identify(log, library="installed" if library is None else library)
    model = plant_model_of(ident, "the table")
    return {"model": {"plant": model.plant, "band": model.band,
                      "intervals": {k: list(v) for k, v in model.intervals.items()},
                      "chosen": list(model.chosen)}}


def model_of(record: Mapping[str, Any]):
    """The :class:`papwc.identify.plant_model.PlantModel` of a record of
    :func:`identified_table`."""
    from papwc.identify.plant_model import PlantModel

    m = record["model"]
    return PlantModel("the table", dict(m["plant"]),
                      {k: tuple(v) for k, v in m["intervals"].items()}, m["band"],
                      float(record["cpu_s"]), tuple(m["chosen"]))
