"""Batteries with named cases: the ``[cases]`` table, validated, combined with grid and draws."""

from __future__ import annotations

import tomllib

import pytest
from harness import TABLE_1_TOML

from papwc.battery import get_field, load_battery, parse_battery, plan_runs
from papwc.errors import ScenarioError
from papwc.resources import scenario_file

BASE = 'name = "cases"\n' + TABLE_1_TOML + """\
[maneuver]
x_ref = 0.01
duration = 0.5
iterations = 1
[[controller]]
kind = "papwc"
t_p_max = 0.03
[[controller]]
kind = "exact"
"""

CASES = """\
[cases]
exact = {}
stribeck = { "plant.v_s" = 1e-3 }
lag = { "plant.tau_u" = 2e-3, "controller.2.f_p_max" = 250.0 }
"""


def battery(text: str):
    """The base scenario with ``text`` (tables) after it; a line ``top = ...`` goes first."""
    top, _, rest = text.partition("\n") if text.startswith("cases =") else ("", "", text)
    return parse_battery(tomllib.loads(top + "\n" + BASE + rest), "cases.toml")


def test_cases_give_one_run_each_named_after_the_case() -> None:
    b = battery(CASES)
    runs = plan_runs([b])
    assert [r.run_id for r in runs] == ["exact", "stribeck", "lag"]
    assert [r.case for r in runs] == ["exact", "stribeck", "lag"]
    assert not [r.error for r in runs if r.error]
    assert get_field(runs[0].data, "plant.v_s") == 0.0
    assert get_field(runs[1].data, "plant.v_s") == 1e-3
    assert get_field(runs[2].data, "plant.tau_u") == 2e-3
    assert get_field(runs[2].data, "controller.2.f_p_max") == 250.0
    assert b.varied == ["plant.v_s", "plant.tau_u", "controller.2.f_p_max"]


def test_cases_combine_with_the_grid_and_the_draws() -> None:
    b = battery(CASES + """
[sweep]
"maneuver.x_ref" = [1e-2, 1e-3]
[monte_carlo]
n = 2
seed = 3
"plant.c" = { dist = "uniform", rel = 0.2 }
""")
    runs = plan_runs([b])
    assert len(runs) == 3 * 2 * 2
    assert runs[0].run_id == "exact-s0-d000"
    assert runs[-1].run_id == "lag-s1-d001"
    # Common random numbers: every case and grid point draws the same c in draw d.
    for d in (0, 1):
        drawn = {get_field(r.data, "plant.c") for r in runs if r.run_id.endswith(f"d00{d}")}
        assert len(drawn) == 1
    assert len({r.run_hash for r in runs}) == len(runs)
    assert [r.order[1:] for r in runs] == [(g, d) for _ in range(3) for g in (0, 1)
                                           for d in (0, 1)]


def test_a_case_with_an_invalid_plant_is_an_error_run() -> None:
    runs = plan_runs([battery(CASES + 'bad = { "plant.m_d" = 20.0 }\n')])
    bad = [r for r in runs if r.case == "bad"]
    assert len(bad) == 1 and "k_t" in bad[0].error
    assert not [r for r in runs if r.case != "bad" and r.error]


@pytest.mark.parametrize(("text", "message"), [
    ("[cases]\n", "[cases] must be a non-empty table"),
    ('cases = 3\n', "[cases] must be a non-empty table"),
    ('[cases]\n"a b" = {}\n', "case name 'a b': must be made of letters, digits and '_'"),
    ("[cases]\nx = 3\n", "[cases] case 'x' = 3: must be a table"),
    ('[cases]\nx = { "plant.nope" = 1.0 }\n', "[cases.x] field 'plant.nope': [plant] has no "
                                             "field 'nope'"),
    ('[cases]\nx = { "plant.v_s" = true }\n', "[cases.x] field 'plant.v_s' = True: must be a "
                                             "number or a string"),
    ('[cases]\nx = { "plant.v_s" = 1e-3 }\n[sweep]\n"plant.v_s" = [1e-3, 2e-3]\n',
     "[cases.x] field 'plant.v_s' is also varied by [sweep]"),
    ('[cases]\nx = { "plant.c" = 500.0 }\n[monte_carlo]\nn = 2\n'
     '"plant.c" = { dist = "uniform", rel = 0.1 }\n',
     "[cases.x] field 'plant.c' is also varied by [monte_carlo]"),
])
def test_bad_cases_are_refused_naming_the_file_table_and_field(text: str, message: str) -> None:
    with pytest.raises(ScenarioError) as info:
        battery(text)
    assert str(info.value).startswith("cases.toml: ")
    assert message in str(info.value)


def test_plant_seed_can_be_swept_not_drawn() -> None:
    runs = plan_runs([battery('[sweep]\n"plant.seed" = [1, 2]\n')])
    assert [get_field(r.data, "plant.seed") for r in runs] == [1, 2]
    with pytest.raises(ScenarioError, match="only floating-point fields can be drawn"):
        battery('[monte_carlo]\nn = 2\n"plant.seed" = { dist = "uniform", low = 0, high = 9 }\n')


def test_the_realism_battery_is_valid() -> None:
    b = load_battery(scenario_file("realism.toml"))
    runs = plan_runs([b])
    names = [name for name, _ in b.cases]
    assert names == ["exact", "stribeck", "lugre", "ripple", "stiction", "lag", "flexible",
                     "noise"]
    assert len(runs) == len(names) * 3 * 5
    assert not [r.error for r in runs if r.error]
    assert [t["kind"] for t in b.data["controller"]] == ["pwc", "papwc", "exact", "pid"]


@pytest.mark.parametrize("name", ["realism", "realism_mc", "realism_mc_lugre"])
def test_the_1_khz_twin_of_a_realism_battery_runs_its_pid_on_the_same_plants(name) -> None:
    at_100hz = plan_runs([load_battery(scenario_file(f"{name}.toml"))])
    at_1khz = plan_runs([load_battery(scenario_file(f"{name}_1khz.toml"))])
    assert [r.run_id for r in at_1khz] == [r.run_id for r in at_100hz]
    assert all(a.data["plant"] == b.data["plant"] for a, b in zip(at_100hz, at_1khz,
                                                                  strict=True))
    assert not [r.error for r in at_1khz if r.error]
    pid = [t for t in at_100hz[0].data["controller"] if t["kind"] == "pid"]
    (fast,) = at_1khz[0].data["controller"]
    assert at_100hz[0].data["maneuver"]["T"] == 0.01 and at_1khz[0].data["maneuver"]["T"] == 1e-3
    # the same PID; at 1 ms its in-position window is on, and on the Monte Carlo's 0.1 um
    # encoder it is told the count (which only the window's decisions read)
    told = {"x_resolution": at_1khz[0].data["plant"]["x_resolution"]} if (
        "x_resolution" in fast) else {}
    assert [{**t, **told, "label": ""} for t in pid] == [{**fast, "label": ""}]
    assert name == "realism" or told == {"x_resolution": 1e-7}


@pytest.mark.parametrize("name", ["realism_mc", "realism_mc_lugre"])
def test_the_hybrid_and_fine_twins_run_the_monte_carlos_tables(name) -> None:
    """The hybrid twin (at 1 ms) and the fine-encoder twin run the same tables: run for run
    the same plants, but the fine twin's encoder count a tenth and its noise a tenth."""
    base = plan_runs([load_battery(scenario_file(f"{name}.toml"))])
    hybrid = plan_runs([load_battery(scenario_file(f"{name}_hybrid.toml"))])
    fine = plan_runs([load_battery(scenario_file(f"{name}_fine.toml"))])
    assert [r.run_id for r in hybrid] == [r.run_id for r in fine] == [r.run_id for r in base]
    assert all(a.data["plant"] == b.data["plant"] for a, b in zip(base, hybrid, strict=True))
    for a, b in zip(base, fine, strict=True):
        scaled = {**a.data["plant"], "x_resolution": 1e-8,
                  "noise_std": a.data["plant"]["noise_std"] / 10.0}
        assert b.data["plant"] == pytest.approx(scaled, rel=1e-12, abs=1e-30)
    (ctl,) = hybrid[0].data["controller"]
    assert ctl["kind"] == "hybrid" and hybrid[0].data["maneuver"]["T"] == 1e-3
    assert not [r.error for r in hybrid + fine if r.error]
    exact = [t for t in fine[0].data["controller"] if t["kind"] == "exact"]
    assert exact[0]["x_resolution"] == exact[0]["tolerance"] == 1e-8
