"""The identified plant as the controllers take it: ``plant.toml``'s ``[identified]`` table.

``papwc identify`` writes ``plant.toml`` (:mod:`.fit_report`): a scenario whose ``[plant]``
table holds the identified values, and, beside it, the ``[identified]`` table of what only
identification knows -- each fitted parameter's 95 % interval and the stiction band
(:mod:`.band`)::

    [identified]
    log = "machine.csv"          # what was identified
    sample_period = 0.01         # s, the log's
    chosen = ["stribeck", "lag", "ripple"]
    cpu_s = 12.3                 # processor time of the identification, s

    [identified.intervals]       # 95 % intervals, the [plant] fields' units
    m = [149.9, 150.1]
    ...

    [identified.band]            # breakaway forces, N, the ripple's factor removed
    lowest_seen = 126.6          # the lowest and highest breakaway seen
    highest_seen = 133.1
    low = 123.8                  # the band that holds the next `next_draws` draws
    high = 135.9                 #   with probability `coverage` (uniform draws)
    sticks = 13
    next_draws = 20
    coverage = 0.95

:func:`read_plant_model` reads such a file (``papwc run --plant-model``) and refuses one that
is not (one line naming the file, the field, the value and what is allowed);
:meth:`PlantModel.settings` gives a controller the identified plant in place of what it
was told: ``m_est``, ``f_c_est``, ``c_est`` (the kinds that read it) and the band as the
exact-model controller's ``f_b_floor`` and ``f_b_step``
(:meth:`PlantModel.controller_band`). The battery's ``[battery] identify_first`` makes a
:class:`PlantModel` of each table it identifies (:func:`plant_model_of`).
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from typing import Any

from papwc.errors import ScenarioError

__all__ = ["BAND_FIELDS", "IDENTIFIED", "PlantModel", "check_identified", "plant_model_of",
           "read_plant_model"]

#: The top-level table of plant.toml that makes it a plant model.
IDENTIFIED = "identified"
#: The fields of ``[identified.band]``: name -> (unit, what).
BAND_FIELDS: dict[str, tuple[str, str]] = {
    "lowest_seen": ("N", "the lowest breakaway seen"),
    "highest_seen": ("N", "the highest breakaway seen"),
    "low": ("N", "the low end of the band for the next draws"),
    "high": ("N", "the high end of the band for the next draws"),
    "sticks": ("", "the breakaways the band is made of"),
    "next_draws": ("", "the draws the band holds"),
    "coverage": ("1", "the probability that it holds them all"),
}
#: The ``[plant]`` fields an identification gives.
RECORDED = ("m", "f_c", "f_s", "f_s_spread", "c", "v_s", "delta_s", "tau_u", "ripple",
            "ripple_period", "ripple_phase", "x_resolution", "noise_std")
#: The controller settings the identified plant replaces (where the kind reads them).
REPLACED = ("m_est", "f_c_est", "c_est", "f_b_floor", "f_b_step")


@dataclass(frozen=True)
class PlantModel:
    """An identified plant (see the module).

    Attributes
    ----------
    source : str
        Where it came from (a file, a table of a battery), for messages.
    plant : dict
        The identified ``[plant]`` values (SI units).
    intervals : dict
        ``name -> (low, high)``, 95 % intervals.
    band : dict or None
        The ``[identified.band]`` fields (None: no band was identified).
    cpu_s : float
        Processor time of the identification, s (nan: not known).
    chosen : tuple of str
        The deviations chosen.
    """

    source: str
    plant: dict[str, float]
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    band: dict[str, float] | None = None
    cpu_s: float = math.nan
    chosen: tuple[str, ...] = ()

    def controller_band(self, T: float) -> tuple[float, float]:
        """The band as commanded heights of one sample from rest at period ``T`` (s): the
        lowest one that may break a fresh stick away anywhere (the band's low end times the
        ripple's lowest factor, raised for the lag: the lagging force reaches ``1 -
        exp(-T/tau_u)`` of a one-sample pulse), and the band's width so (its high end times
        the ripple's highest factor, less that), N; (0, 0) without a band."""
        if self.band is None:
            return 0.0, 0.0
        a = float(self.plant.get("ripple", 0.0))
        tau = float(self.plant.get("tau_u", 0.0))
        reach = -math.expm1(-T / tau) if tau > 0.0 else 1.0
        low = self.band["low"] * (1.0 - a) / reach
        high = self.band["high"] * (1.0 + a) / reach
        return low, high - low

    def settings(self, settings: Any, T: float) -> Any:
        """``settings`` (a :class:`papwc.controllers.settings.ControllerSettings`) with the
        identified plant in place of what it was told, for the settings its kind reads
        (:data:`REPLACED`); T the controller's sample period, s."""
        from papwc.controllers.settings import settings_for_kind

        read = set(settings_for_kind(settings.kind))
        floor, step = self.controller_band(T)
        values = {"m_est": float(self.plant["m"]), "f_c_est": float(self.plant["f_c"]),
                  "c_est": float(self.plant["c"]), "f_b_floor": floor, "f_b_step": step}
        return dataclasses.replace(settings, **{name: value for name, value in values.items()
                                                if name in read})

    def give_to(self, scenario: Any) -> list[tuple[str, Any, Any]]:
        """Give every controller of ``scenario`` (a :class:`papwc.scenario.Scenario`) this
        plant (:meth:`settings`, at its maneuver's sample period), in place.

        Returns
        -------
        list of (str, ControllerSettings, ControllerSettings)
            Per controller: its label, the settings it was told, those it was given.

        Raises
        ------
        ScenarioError
            ``"controller LABEL: the identified plant gives it NAME: ..."`` if a controller's
            settings with this plant are not valid (none is changed then).
        """
        from papwc.controllers import CONTROLLER_KINDS

        T = scenario.maneuver.T
        out = []
        for settings, label in zip(scenario.controllers, scenario.labels, strict=True):
            given = self.settings(settings, T)
            problems = given.problems(tuple(CONTROLLER_KINDS))
            if problems:
                name, message = problems[0]
                raise ScenarioError(f"controller {label}: the identified plant gives it "
                                    f"{name}: {message}")
            out.append((label, settings, given))
        scenario.controllers[:] = [given for _, _, given in out]
        return out

    def record(self) -> dict[str, Any]:
        """The identified values as one flat mapping (the battery's identified.csv): the
        fields of :data:`RECORDED` (a deviation not chosen at the model layer's default,
        none), the band's (``band_<name>``, nan without a band), the deviations chosen."""
        from papwc.model.plant import PLANT_DEFAULTS

        out: dict[str, Any] = {name: float(self.plant.get(name, PLANT_DEFAULTS[name]))
                               for name in RECORDED}
        for name in BAND_FIELDS:
            out[f"band_{name}"] = (self.band or {}).get(name, math.nan)
        out["chosen"] = ",".join(self.chosen) or "none"
        return out


def _number(source: str, where: str, name: str, value: Any, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value) or (positive and not value > 0.0):
        what = "a finite number > 0" if positive else "a finite number"
        raise ScenarioError(f"{source}: {where} field {name!r} = {value!r}: must be {what}")
    return float(value)


def check_identified(table: Any, source: str) -> tuple[dict, dict | None, float, tuple]:
    """Check an ``[identified]`` table: its intervals, band, processor time and deviations.

    Raises
    ------
    ScenarioError
        Naming the file, the table, the field, the value and what is allowed.
    """
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [{IDENTIFIED}] must be a table (what papwc identify "
                            "found: intervals and the stiction band)")
    allowed = ("log", "sample_period", "chosen", "cpu_s", "intervals", "band")
    for key in table:
        if key not in allowed:
            raise ScenarioError(f"{source}: [{IDENTIFIED}] unknown field {key!r}; allowed: "
                                + ", ".join(allowed))
    intervals: dict[str, tuple[float, float]] = {}
    raw = table.get("intervals", {})
    if not isinstance(raw, dict):
        raise ScenarioError(f"{source}: [{IDENTIFIED}.intervals] must be a table of "
                            "name = [low, high]")
    for name, pair in raw.items():
        if not (isinstance(pair, list) and len(pair) == 2):
            raise ScenarioError(f"{source}: [{IDENTIFIED}.intervals] field {name!r} = "
                                f"{pair!r}: must be [low, high]")
        low = _number(source, f"[{IDENTIFIED}.intervals]", name, pair[0], positive=False)
        high = _number(source, f"[{IDENTIFIED}.intervals]", name, pair[1], positive=False)
        if not low <= high:
            raise ScenarioError(f"{source}: [{IDENTIFIED}.intervals] field {name!r} = "
                                f"{pair!r}: an interval must have low <= high")
        intervals[name] = (low, high)
    band = None
    if "band" in table:
        raw = table["band"]
        where = f"[{IDENTIFIED}.band]"
        if not isinstance(raw, dict):
            raise ScenarioError(f"{source}: {where} must be a table of "
                                + ", ".join(BAND_FIELDS))
        for key in raw:
            if key not in BAND_FIELDS:
                raise ScenarioError(f"{source}: {where} unknown field {key!r}; allowed: "
                                    + ", ".join(BAND_FIELDS))
        for key in BAND_FIELDS:
            if key not in raw:
                raise ScenarioError(f"{source}: {where} has no field {key!r} "
                                    f"({BAND_FIELDS[key][1]})")
        band = {key: _number(source, where, key, raw[key]) for key in BAND_FIELDS}
        if not band["coverage"] < 1.0:
            raise ScenarioError(f"{source}: {where} field 'coverage' = {raw['coverage']!r}: "
                                "must satisfy 0 < coverage < 1")
        for lo, hi in (("low", "high"), ("lowest_seen", "highest_seen"),
                       ("low", "lowest_seen"), ("highest_seen", "high")):
            if not band[lo] <= band[hi]:
                raise ScenarioError(f"{source}: {where} field {lo!r} = {raw[lo]!r} N > "
                                    f"{hi!r} = {raw[hi]!r} N: the band must have low <= "
                                    "lowest_seen <= highest_seen <= high")
    cpu = table.get("cpu_s", math.nan)
    if not (isinstance(cpu, float) and math.isnan(cpu)):
        cpu = _number(source, f"[{IDENTIFIED}]", "cpu_s", cpu, positive=False)
    chosen = table.get("chosen", [])
    if not (isinstance(chosen, list) and all(isinstance(c, str) for c in chosen)):
        raise ScenarioError(f"{source}: [{IDENTIFIED}] field 'chosen' = {chosen!r}: must be a "
                            "list of deviation names")
    return intervals, band, cpu, tuple(chosen)


def read_plant_model(path: str | os.PathLike) -> PlantModel:
    """The plant model of a ``plant.toml`` written by ``papwc identify``.

    Raises
    ------
    ScenarioError
        If the file cannot be read, is not a scenario, or has no valid ``[identified]``
        table (one line: the file, the field, the value and what is allowed).
    """
    from papwc.scenario import parse_scenario, read_toml

    source = str(path)
    data = read_toml(path, "plant model")
    if IDENTIFIED not in data:
        raise ScenarioError(f"{source}: not a plant model written by papwc identify: it has no "
                            f"[{IDENTIFIED}] table (papwc identify LOG.csv --out DIR writes "
                            "DIR/plant.toml)")
    scenario = parse_scenario(data, source)
    intervals, band, cpu, chosen = check_identified(data[IDENTIFIED], source)
    plant = {name: float(value) for name, value in scenario.plant.items()}
    return PlantModel(source, plant, intervals, band, cpu, chosen)


def plant_model_of(ident: Any, source: str) -> PlantModel:
    """The :class:`PlantModel` of an identification (:class:`papwc.identify.fit.Identification`)."""
    from papwc.identify.band import COVERAGE, NEXT_DRAWS

    plant = {name: float(value) for name, value in ident.plant.items()}
    intervals = {e.name: (float(e.low), float(e.high)) for e in ident.estimates
                 if math.isfinite(e.low) and math.isfinite(e.high)}
    band = None
    if ident.band is not None:
        b = ident.band
        band = {"lowest_seen": b.lowest, "highest_seen": b.highest, "low": b.low,
                "high": b.high, "sticks": float(b.sticks), "next_draws": float(NEXT_DRAWS),
                "coverage": COVERAGE}
    return PlantModel(source, plant, intervals, band, float(ident.cpu_seconds),
                      tuple(ident.chosen))
