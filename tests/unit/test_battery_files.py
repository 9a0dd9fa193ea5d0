"""Battery files: validation, runs resolved up front with stable ids and draws, the journal.

Running batteries (local processes, kill and resume, Dask) is in tests/integration/."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from papwc.battery import (
    get_field,
    load_battery,
    parse_battery,
    plan_runs,
    read_journal,
)
from papwc.errors import ScenarioError

PROJECT = Path(__file__).resolve().parents[2]

def write(tmp_path: Path, text: str, name: str = "battery.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- battery files ----------------------------------------------------------------------------

BASE = 'name = "b"\n[[controller]]\nkind = "papwc"\n'


@pytest.mark.parametrize(
    ("extra", "field"),
    [
        ('[sweep]\n"plant.mass" = [1.0]\n', "plant.mass"),
        ('[sweep]\n"plant.m" = 150.0\n', "plant.m"),
        ('[sweep]\n"plant.m" = []\n', "plant.m"),
        ('[sweep]\n"controller.2.K_c" = [0.5]\n', "controller.2.K_c"),
        ('[sweep]\n"controller.kind" = ["pwc"]\n', "controller.kind"),
        ('[sweep]\n"speed" = [1.0]\n', "speed"),
        ('[monte_carlo]\nseed = 1\n"plant.m" = { dist = "uniform", rel = 0.1 }\n', "'n'"),
        ('[monte_carlo]\nn = 2\nseed = -1\n"plant.m" = { dist = "uniform", rel = 0.1 }\n',
         "'seed'"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "gauss", std = 1.0 }\n', "plant.m"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "uniform", rel = 0.1, abs = 2.0 }\n',
         "plant.m"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "uniform", low = 2.0, high = 1.0 }\n',
         "plant.m"),
        ('[monte_carlo]\nn = 2\n"plant.m" = { dist = "normal", std = -1.0 }\n', "plant.m"),
        ('[monte_carlo]\nn = 2\n"maneuver.iterations" = { dist = "normal", std = 1.0 }\n',
         "maneuver.iterations"),
        ('[monte_carlo]\nn = 2\n"plant.f_s" = { dist = "uniform", rel = 0.1, of = "plant.f_c" }\n',
         "plant.f_s"),
        ('[monte_carlo]\nn = 2\n"plant.f_s" = { dist = "uniform", low = 1.0, high = 2.0, '
         'of = "controller.m_est" }\n', "plant.f_s"),
        ('[monte_carlo]\nn = 2\n"plant.m" = 3.0\n', "plant.m"),
        ('[monte_carlo]\nn = 2\n', "[monte_carlo]"),
        ('[battery]\nsuccess_tolerance = -1.0\n', "success_tolerance"),
        ('[battery]\ntolerance = 1.0\n', "tolerance"),
        ('[battery]\nidentify_first = 1\n', "'identify_first' = 1: must be true or false"),
        ('[plant]\nf_s = 50.0\n', "f_s"),
    ],
)
def test_battery_file_errors_name_the_file_and_the_field(tmp_path, extra, field):
    path = write(tmp_path, BASE + extra, "bad_battery.toml")
    with pytest.raises(ScenarioError) as info:
        load_battery(path)
    message = str(info.value)
    assert str(path) in message
    assert field in message


def test_runs_are_resolved_up_front_with_stable_ids_and_draws():
    data = {
        "name": "g",
        "plant": {"m": 150.0, "f_c": 100.0, "f_s": 130.0},
        "controller": [{"kind": "pwc", "m_est": 150.0}, {"kind": "papwc", "m_est": 140.0}],
        "sweep": {"plant.f_c": [80.0, 100.0], "controller.2.K_c": [0.5, 0.8, 1.2]},
        "monte_carlo": {
            "n": 4,
            "seed": 11,
            "plant.m": {"dist": "uniform", "low": 100.0, "high": 200.0},
            "controller.m_est": {"dist": "normal", "rel_std": 0.1},
            "plant.f_s": {"dist": "uniform", "low": 1.0, "high": 1.5, "of": "plant.f_c"},
        },
    }
    battery = parse_battery(data, "g.toml")
    runs = plan_runs([battery])
    assert len(runs) == 2 * 3 * 4
    assert [r.run_id for r in runs[:5]] == ["s0-d000", "s0-d001", "s0-d002", "s0-d003",
                                            "s1-d000"]
    again = plan_runs([parse_battery(data, "g.toml")])
    assert [(r.run_id, r.run_hash, r.data) for r in runs] == [
        (r.run_id, r.run_hash, r.data) for r in again]
    assert len({r.run_hash for r in runs}) == len(runs)
    for r in runs:
        m = get_field(r.data, "plant.m")
        f_c, f_s = get_field(r.data, "plant.f_c"), get_field(r.data, "plant.f_s")
        assert 100.0 <= m <= 200.0
        assert f_c <= f_s <= 1.5 * f_c
        assert f_c == [80.0, 100.0][r.order[1] // 3]
        assert get_field(r.data, "controller.2.K_c") == [0.5, 0.8, 1.2][r.order[1] % 3]
        # one random number per draw for every table: the relative offsets agree
        e1 = get_field(r.data, "controller.m_est", 0) / 150.0
        e2 = get_field(r.data, "controller.m_est", 1) / 140.0
        assert e1 == pytest.approx(e2, rel=1e-15)  # measured: 1.2e-16 (was 1e-12)
        assert not r.error
    # common random numbers: draw d has the same m at every grid point
    by_draw = {}
    for r in runs:
        by_draw.setdefault(r.order[2], set()).add(get_field(r.data, "plant.m"))
    assert all(len(v) == 1 for v in by_draw.values())


def test_read_journal_drops_a_torn_last_line(tmp_path):
    path = tmp_path / "journal.jsonl"
    lines = [json.dumps({"type": "header", "fingerprint": "x"}),
             json.dumps({"type": "run", "battery": "b", "run_id": "d000"})]
    path.write_text("\n".join(lines) + "\n" + '{"type": "run", "batt')
    header, records, good = read_journal(path)
    assert header["fingerprint"] == "x"
    assert [r["run_id"] for r in records] == ["d000"]
    assert good == len("\n".join(lines)) + 1
    # a bad middle line is skipped with a warning naming it (its run is computed again)
    path.write_text(lines[0] + "\n{broken\n" + lines[1] + "\n")
    warnings: list[str] = []
    header, records, _ = read_journal(path, warnings)
    assert [r["run_id"] for r in records] == ["d000"]
    assert len(warnings) == 1 and "line 2 skipped" in warnings[0]


def test_robustness_battery_file_is_valid():
    battery = load_battery(PROJECT / "scenarios" / "robustness.toml")
    runs = plan_runs([battery])
    assert len(runs) == 200 and not any(r.error for r in runs)
    for r in runs:
        plant = r.data["plant"]
        assert plant["f_s"] >= plant["f_c"]
        assert 0.7 * 150.0 <= plant["m"] <= 1.3 * 150.0
        for table in r.data["controller"]:
            assert 0.8 <= table["m_est"] / plant["m"] <= 1.2
            assert 0.8 <= table["f_c_est"] / plant["f_c"] <= 1.2


def test_identify_first_is_read_and_changes_the_runs_hashes_only_when_on(tmp_path):
    off = plan_runs([load_battery(write(tmp_path, BASE, "off.toml"))])
    on_battery = load_battery(write(tmp_path, BASE + "[battery]\nidentify_first = true\n",
                                    "on.toml"))
    assert on_battery.identify_first
    on = plan_runs([on_battery])
    assert [r.run_id for r in on] == [r.run_id for r in off]
    assert all(a.run_hash != b.run_hash for a, b in zip(on, off, strict=True))
    explicit = load_battery(write(tmp_path, BASE + "[battery]\nidentify_first = false\n",
                                  "false.toml"))
    assert [r.run_hash for r in plan_runs([explicit])] == [r.run_hash for r in off]


def test_identify_first_refuses_a_plant_it_cannot_excite():
    from papwc.battery.identify_first import check_excitable

    good = {"u": ("input", "Real"), "x_meas": ("output", "Real")}
    check_excitable("b.toml", good, {0.01})
    with pytest.raises(ScenarioError) as info:
        check_excitable("b.toml", {"u": ("input", "Real")}, {0.01})
    assert str(info.value) == (
        "b.toml: [battery] identify_first = true: the plant FMU has no Real output 'x_meas' to "
        "apply the excitation through (force u) and read the table by (x_meas); give "
        "FrictionPlant.fmu or set identify_first = false")
    with pytest.raises(ScenarioError, match=r"b.toml: \[battery\] identify_first = true: "
                                            r"maneuver.T = 0.5 s: the excitation's sample "
                                            r"period must be"):
        check_excitable("b.toml", good, {0.5})
