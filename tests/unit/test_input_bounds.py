"""Every input has a bound and a named error before work starts (issue 13, groups 2, 5, 6, 9;
issue 44: a byte-order mark, an unquoted dotted key).

Scenario and battery files are validated here without running anything: the
messages name the file, the table, the field, the value and what is allowed.
"""

from __future__ import annotations

import re
import time
import tomllib
import tracemalloc
from pathlib import Path

import pytest

from papwc.battery import load_battery, parse_battery, plan_runs
from papwc.errors import ScenarioError
from papwc.limits import check_steps
from papwc.model.controller_settings import CONTROLLER_SETTINGS
from papwc.model.maneuver import MANEUVER_VARIABLES
from papwc.model.plant import PLANT_PARAMETERS
from papwc.scenario import field_table, load_scenario, parse_scenario

PROJECT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((PROJECT / "scenarios").glob("*.toml"))


def scenario(**tables) -> dict:
    """A valid scenario mapping with some tables replaced or extended."""
    data = {"name": "t", "plant": {}, "maneuver": {"iterations": 2},
            "controller": [{"kind": "papwc"}]}
    for key, value in tables.items():
        if isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
        else:
            data[key] = value
    return data


def refused(data: dict, *parts: str) -> str:
    with pytest.raises(ScenarioError) as info:
        parse_scenario(data, "s.toml")
    text = str(info.value)
    assert text.startswith("s.toml: "), text
    for part in parts:
        assert part in text, text
    return text


# --- group 5: every field of every kind is validated ------------------------------------------


@pytest.mark.parametrize("kind", [["papwc"], {"a": 1}, 3, None])
def test_kind_given_as_array_or_table_is_a_named_error(kind) -> None:
    refused(scenario(controller=[{"kind": kind}]), "[[controller]] #1 field 'kind'",
            "must be one of 'dual_loop', 'exact', 'hybrid', 'papwc', 'pid', 'pwc'")


@pytest.mark.parametrize("field, value, allowed", [
    ("history", -1, "a whole number 1 <= history <= 52"),
    ("c_est", "x", "must be a number"),
    ("f_s_tol", 0, "0 < f_s_tol <= 1"),
    ("max_pulses", 0.5, "a whole number 1 <= max_pulses <= 1000000"),
    ("history", 10**6, "<= 52"),
])
def test_exact_controller_settings_are_validated(field, value, allowed) -> None:
    refused(scenario(controller=[{"kind": "exact", field: value}]),
            f"[[controller]] #1 field '{field}'", allowed)


def test_every_setting_of_every_kind_is_range_checked() -> None:
    """Each numeric setting of the table refuses a value beyond its range, for its kinds."""
    for var in CONTROLLER_SETTINGS:
        if var.type not in ("Real", "Integer") or var.max is None:
            continue
        kind = var.kinds[0] if var.kinds else "papwc"
        table = {"kind": kind, var.name: var.max * 10 + 1}
        if var.name in ("f_c_est", "f_p_min"):
            table["f_p_max"] = 1e9
        refused(scenario(controller=[table]), f"field '{var.name}'", "must")


def test_a_battery_refuses_an_invalid_sweep_value_before_any_run() -> None:
    data = scenario(controller=[{"kind": "exact"}], sweep={"controller.history": [4, -1]})
    with pytest.raises(ScenarioError, match=r"b\.toml: \[sweep\] field 'controller.history': "
                                            r"value history = -1: must be a whole number"):
        parse_battery(data, "b.toml")


def test_a_battery_whose_every_run_is_invalid_is_refused_naming_the_file() -> None:
    data = scenario(plant={"f_c": 100.0, "f_s": 130.0}, sweep={"plant.f_s": [50.0, 60.0]})
    battery = parse_battery(data, "b.toml")
    with pytest.raises(ScenarioError, match=r"every run of the battery \(2\) is invalid; the "
                                            r"first: b\.toml run s0: \[plant\]"):
        plan_runs([battery])


def test_shipped_scenarios_and_batteries_stay_valid() -> None:
    assert SHIPPED
    for path in SHIPPED:
        text = path.read_text()
        if any(table in text for table in ("[monte_carlo]", "[sweep]", "[cases]")):
            battery = load_battery(path)
            runs = plan_runs([battery])
            assert len(runs) == battery.n_runs and runs
            assert all(not spec.error for spec in runs)
        else:
            assert not load_scenario(path).warnings


# --- group 6: names that go into file names --------------------------------------------------


@pytest.mark.parametrize("name", ["../../../tmp/x", "a/b", "x\\y", "", ".hidden", "a" * 81,
                                  "tab\tname"])
def test_a_name_that_would_leave_the_output_folder_is_refused(name) -> None:
    refused(scenario(name=name), "field 'name'", "letters, digits")


@pytest.mark.parametrize("label", ["a/b", "../up", "sp ace", ""])
def test_a_label_that_goes_into_a_file_name_is_refused(label) -> None:
    refused(scenario(controller=[{"kind": "papwc", "label": label}]),
            "[[controller]] #1 field 'label'", "letters, digits")


def test_a_battery_named_with_a_slash_is_refused() -> None:
    with pytest.raises(ScenarioError, match="field 'name' = 'x/y'"):
        parse_battery(scenario(name="x/y", monte_carlo={
            "n": 2, "plant.m": {"dist": "uniform", "rel": 0.1}}), "b.toml")


def test_the_default_name_is_the_file_stem_made_safe() -> None:
    data = scenario()
    del data["name"]
    assert parse_scenario(data, "dir/my run (2).toml").name == "my_run__2_"


# --- group 2: bounds of work and of physical magnitudes ----------------------------------------


@pytest.mark.parametrize("maneuver, words", [
    ({"duration": 1e9, "T": 0.01}, "x 1e+11 steps (duration = 1000000000.0 s / T = 0.01 s) "
                                   "= 2e+11 communication steps"),
    ({"iterations": 1_000_000, "duration": 2.0}, "2e+08 communication steps"),
])
def test_work_beyond_the_step_limit_is_refused_with_the_estimate(maneuver, words) -> None:
    s = parse_scenario(scenario(maneuver=maneuver), "s.toml")
    m = s.maneuver
    with pytest.raises(ScenarioError) as info:
        check_steps("s.toml", len(s.controllers), m.iterations, m.duration, m.T, 1_000_000)
    text = str(info.value)
    assert words in text and "over the limit of 1e+06 steps" in text, text
    assert "--max-steps" in text and re.search(r"about [0-9.]+ [GT]B", text), text


@pytest.mark.parametrize("table, field, value", [
    ("maneuver", "iterations", 1e9),
    ("maneuver", "T", 1e-300),
    ("plant", "m", 1e-300),
    ("plant", "c", 1e300),
    ("maneuver", "x_ref", 1e6),
])
def test_magnitudes_outside_the_exact_range_are_refused(table, field, value) -> None:
    refused(scenario(**{table: {field: value}}), f"[{table}] field '{field}'", "must")


def test_the_ranges_are_the_model_layers_min_and_max() -> None:
    """Every numeric scenario field has both bounds (or is inf-capable) in the tables."""
    for var in PLANT_PARAMETERS + MANEUVER_VARIABLES + CONTROLLER_SETTINGS:
        if var.type in ("Real", "Integer"):
            assert var.min is not None and var.max is not None, var.name


def test_a_battery_of_ten_million_draws_is_refused_at_once() -> None:
    data = scenario(monte_carlo={"n": 10**7, "plant.m": {"dist": "uniform", "rel": 0.1}})
    battery = parse_battery(data, "b.toml")
    tracemalloc.start()
    start = time.perf_counter()
    with pytest.raises(ScenarioError, match=r"b\.toml: 1 grid point\(s\) x 10000000 draw\(s\) "
                                            r"= 10000000 runs, over the limit of 100000"):
        plan_runs([battery])
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert time.perf_counter() - start < 1.0 and peak < 10e6


def test_a_sweep_of_a_hundred_million_points_is_refused_at_once() -> None:
    values = [float(v) for v in range(1, 101)]
    data = scenario(controller=[{"kind": "papwc"}], sweep={
        "plant.m": values, "plant.c": values, "controller.K_c": [v / 101 for v in range(1, 101)],
        "maneuver.x_ref": [v / 1000 for v in values]})
    battery = parse_battery(data, "b.toml")
    start = time.perf_counter()
    with pytest.raises(ScenarioError, match=r"\[sweep\] has 100 x 100 x 100 x 100 = 100000000 "
                                            r"grid points, over the limit"):
        plan_runs([battery])
    assert time.perf_counter() - start < 1.0


def test_a_swept_tiny_sample_period_is_refused_before_any_run() -> None:
    data = scenario(sweep={"maneuver.T": [0.01, 1e-7]}, maneuver={"duration": 2.0})
    battery = parse_battery(data, "b.toml")
    with pytest.raises(ScenarioError, match=r"b\.toml run s1: 1 controller\(s\) x 2 "
                                            r"iteration\(s\) x 2e\+07 steps"):
        plan_runs([battery])
    assert len(plan_runs([battery], max_steps=10**8)) == 2


# --- group 9: inputs that cannot work are refused or warned ---------------------------------


def test_a_duration_that_is_not_a_whole_number_of_samples_is_refused() -> None:
    refused(scenario(maneuver={"duration": 0.025, "T": 0.01}), "[maneuver] field 'duration'",
            "a whole number of samples T = 0.01 s (it is 2.5 samples; 0.02 s or 0.03 s")


def test_t_p_max_below_the_sample_period_is_refused() -> None:
    refused(scenario(maneuver={"T": 0.01}, controller=[{"kind": "pwc", "t_p_max": 0.005}]),
            "[[controller]] #1 field 't_p_max'", "must be >= T = 0.01 s")


def test_f_p_max_at_or_below_f_s_is_warned_naming_both() -> None:
    s = parse_scenario(scenario(plant={"f_s": 130.0}, controller=[
        {"kind": "papwc", "f_p_max": 120.0}, {"kind": "pwc", "f_p_max": 300.0}]), "s.toml")
    assert s.warnings == [("papwc_tpmax_inf", "f_p_max = 120.0 N <= f_s = 130.0 N: no force "
                                              "of this controller breaks the mass away from rest")]
    assert s.warnings_of("pwc_tpmax_inf") == ""


def test_every_default_of_a_scenario_field_is_listed_from_the_tables() -> None:
    table = field_table()
    for var in PLANT_PARAMETERS:
        if var.name not in ("x0", "v0"):
            assert f"| [plant] | `{var.name}` |" in table
    for var in MANEUVER_VARIABLES + CONTROLLER_SETTINGS:
        assert f"`{var.name}` |" in table
    assert "| [plant] | `m` | kg | 150.0 | 1e-06 <= m <= 1e+09 kg |" in table


# --- issue 44: a byte-order mark, an unquoted dotted key ----------------------------------------


def test_a_byte_order_mark_is_read_past(tmp_path: Path) -> None:
    """Issue 44: a scenario saved with a UTF-8 BOM (as some editors do) was 'Invalid
    statement (at line 1, column 1)'."""
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + (PROJECT / "scenarios" / "paper.toml").read_bytes())
    read, shipped = load_scenario(path), load_scenario(PROJECT / "scenarios" / "paper.toml")
    assert (read.plant, read.maneuver, read.controllers) == (
        shipped.plant, shipped.maneuver, shipped.controllers)
    battery = tmp_path / "bom_battery.toml"
    battery.write_bytes(b"\xef\xbb\xbf" + (PROJECT / "scenarios" / "robustness.toml").read_bytes())
    assert load_battery(battery).n_runs == load_battery(
        PROJECT / "scenarios" / "robustness.toml").n_runs


@pytest.mark.parametrize("table, key, words", [
    ("[sweep]", "plant.m = [100.0, 120.0]", "[sweep] field 'plant': TOML read the unquoted key "
                                            "plant.m as a table 'plant'; quote the path: "
                                            "\"plant.m\" = ..."),
    ("[sweep]", "controller.1.K_c = [0.5, 0.8]", "quote the path: \"controller.1.K_c\" = ..."),
    ("[monte_carlo]\nn = 2", "plant.m = { dist = \"uniform\", rel = 0.1 }",
     "[monte_carlo] field 'plant': TOML read the unquoted key plant.m as a table 'plant'; "
     "quote the path: \"plant.m\" = ..."),
    ("[cases]", "light = { plant.m = 100.0 }", "[cases.light] field 'plant': TOML read the "
                                               "unquoted key plant.m as a table 'plant'"),
], ids=["sweep", "sweep-numbered", "monte_carlo", "cases"])
def test_an_unquoted_dotted_key_gets_a_hint_to_quote_it(table, key, words) -> None:
    """Issue 44: plant.m = [...] unquoted (a TOML table plant) was 'not a field path' with no
    hint that the quotes were missing."""
    text = (f'name = "b"\n[maneuver]\niterations = 1\n[[controller]]\nkind = "papwc"\n'
            f"{table}\n{key}\n")
    with pytest.raises(ScenarioError) as info:
        parse_battery(tomllib.loads(text), "b.toml")
    assert str(info.value).startswith("b.toml: ") and words in str(info.value), info.value
