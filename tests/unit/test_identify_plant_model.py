"""plant.toml as a plant model: what ``papwc run --plant-model`` and ``[battery]
identify_first`` give the controllers, and the files that are not one."""

from __future__ import annotations

import math

import pytest

from papwc.controllers.settings import ControllerSettings
from papwc.errors import ScenarioError
from papwc.identify.plant_model import PlantModel, read_plant_model

GOOD = """name = "identified"

[plant]
m = 151.0
f_c = 99.0
f_s = 130.0
f_s_spread = 0.05
c = 690.0
tau_u = 0.002
ripple = 0.1
ripple_period = 0.001
x_resolution = 1e-7

[maneuver]
T = 0.01

[[controller]]
kind = "papwc"

[identified]
log = "machine.csv"
sample_period = 0.01
chosen = ["lag", "ripple"]
cpu_s = 12.5

[identified.intervals]
m = [150.0, 152.0]
f_c = [98.0, 100.0]

[identified.band]
lowest_seen = 125.0
highest_seen = 135.0
low = 122.0
high = 138.0
sticks = 14.0
next_draws = 20.0
coverage = 0.95
"""


def _write(tmp_path, text: str):
    path = tmp_path / "plant.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_plant_model_gives_each_kind_what_it_reads(tmp_path):
    model = read_plant_model(_write(tmp_path, GOOD))
    assert model.plant["m"] == 151.0 and model.intervals["m"] == (150.0, 152.0)
    assert model.band["low"] == 122.0 and model.chosen == ("lag", "ripple")
    papwc = model.settings(ControllerSettings(kind="papwc"), 0.01)
    assert (papwc.m_est, papwc.f_c_est, papwc.c_est) == (151.0, 99.0, 0.0)  # no c_est read
    pid = model.settings(ControllerSettings(kind="pid"), 0.01)
    assert (pid.m_est, pid.f_c_est) == (151.0, 99.0)


def test_the_band_is_given_as_one_sample_heights_through_the_lag_and_ripple(tmp_path):
    model = read_plant_model(_write(tmp_path, GOOD))
    floor, step = model.controller_band(0.01)
    reach = 1.0 - math.exp(-0.01 / 0.002)
    assert floor == pytest.approx(122.0 * 0.9 / reach, rel=1e-12)
    assert floor + step == pytest.approx(138.0 * 1.1 / reach, rel=1e-12)
    assert PlantModel("x", {"m": 1.0, "f_c": 1.0, "c": 0.0}).controller_band(0.01) == (0.0, 0.0)


@pytest.mark.parametrize("change, message", [
    (lambda t: t.split("[identified]")[0],
     "not a plant model written by papwc identify: it has no [identified] table"),
    (lambda t: t.replace("low = 122.0", "low = 140.0"),
     "[identified.band] field 'low' = 140.0 N > 'high' = 138.0 N: the band must have low <= "
     "lowest_seen <= highest_seen <= high"),
    (lambda t: t.replace("lowest_seen = 125.0", "lowest_seen = 136.0"),
     "[identified.band] field 'lowest_seen' = 136.0 N > 'highest_seen' = 135.0 N"),
    (lambda t: t.replace("high = 138.0\n", "high = \"a lot\"\n"),
     "[identified.band] field 'high' = 'a lot': must be a finite number > 0"),
    (lambda t: t.replace("sticks = 14.0\n", ""),
     "[identified.band] has no field 'sticks' (the breakaways the band is made of)"),
    (lambda t: t.replace("m = [150.0, 152.0]", "m = [152.0, 150.0]"),
     "[identified.intervals] field 'm' = [152.0, 150.0]: an interval must have low <= high"),
    (lambda t: t.replace("cpu_s = 12.5", "cpu_s = 12.5\nguess = 1"),
     "[identified] unknown field 'guess'; allowed: log, sample_period, chosen, cpu_s, "
     "intervals, band"),
    (lambda t: t.replace("m = 151.0", "m = -1.0"), "[plant] field 'm'"),
])
def test_a_file_that_is_not_a_plant_model_is_one_line_naming_where(tmp_path, change, message):
    path = _write(tmp_path, change(GOOD))
    with pytest.raises(ScenarioError) as info:
        read_plant_model(path)
    text = str(info.value)
    assert text.startswith(f"{path}: ") and message in text and "\n" not in text


def test_a_scenario_with_a_bad_identified_table_is_refused_by_the_run_too(tmp_path):
    from papwc.scenario import load_scenario

    path = _write(tmp_path, GOOD.replace("low = 122.0", "low = 140.0"))
    with pytest.raises(ScenarioError, match="the band must have low <= lowest_seen"):
        load_scenario(path)
    assert load_scenario(_write(tmp_path, GOOD)).plant["m"] == 151.0


def test_a_controller_the_identified_plant_does_not_fit_is_refused_naming_it(tmp_path):
    from papwc.scenario import parse_scenario

    model = read_plant_model(_write(tmp_path, GOOD))
    scenario = parse_scenario({"controller": [
        {"kind": "exact", "label": "fine"},
        {"kind": "papwc", "label": "weak", "f_p_max": 95.0, "f_c_est": 50.0}]}, "s.toml")
    told = list(scenario.controllers)
    with pytest.raises(ScenarioError) as info:
        model.give_to(scenario)
    assert str(info.value).startswith("controller weak: the identified plant gives it "
                                      "f_c_est: f_c_est = 99.0 N: must satisfy")
    assert scenario.controllers == told  # none changed
    scenario.controllers.pop()
    scenario.labels.pop()
    [(label, before, after)] = model.give_to(scenario)
    assert label == "fine" and before.m_est == 150.0 and after.m_est == 151.0
    assert scenario.controllers == [after]
