"""Issue 46, control on the identified plant: ``[battery] identify_first`` identifies each
table through its encoder before its controllers run and gives them the identified plant
(once per table: the runs of one table share it); ``papwc run --plant-model`` gives a
scenario's controllers the plant ``papwc identify`` wrote; a plant FMU that cannot be
excited and a plant model that is not one are refused in one line."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from papwc.cli import main

#: A Table 1 table with a Stribeck curve, a lag, a ripple and random stiction, read through
#: the 0.1 um encoder with 0.2 um noise; two targets (the runs share the table), two
#: controllers, one iteration.
BATTERY = """
name = "first"

[plant]
m = 150.0
f_c = 100.0
f_s = 130.0
c = 700.0
x_resolution = 1e-7
noise_std = 2e-7
v_s = 1.5e-3
tau_u = 1e-3
ripple = 0.08
ripple_period = 2e-3
f_s_spread = 0.05
seed = 3

[maneuver]
x_ref = 1e-3
T = 0.01
duration = 1.0
iterations = 1

[[controller]]
kind = "exact"
label = "exact"
tolerance = 1e-7
m_est = 100.0
f_c_est = 60.0
x_resolution = 1e-7

[[controller]]
kind = "papwc"
tolerance = 2e-5

[sweep]
"maneuver.x_ref" = [1e-3, 5e-5]

[battery]
identify_first = true
"""


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_each_table_is_identified_once_and_its_controllers_told_it(tmp_path, capsys,
                                                                   friction_plant_fmu):
    battery = tmp_path / "first.toml"
    battery.write_text(BATTERY)
    out = tmp_path / "out"
    assert main(["battery", str(battery), "--workers", "1", "--fmu", str(friction_plant_fmu),
                 "--out", str(out)]) == 0
    capsys.readouterr()
    rows = _rows(out / "identified.csv")
    assert [r["run_id"] for r in rows] == ["s0", "s1"]
    assert [r["cached"] for r in rows] == ["False", "True"]
    first, second = rows
    assert first["table_key"] == second["table_key"] and first["cpu_s"] == second["cpu_s"]
    assert 0.0 < float(first["cpu_s"]) <= 60.0
    assert abs(float(first["m"]) / 150.0 - 1.0) < 0.02
    assert abs(float(first["v_s"]) / 1.5e-3 - 1.0) < 0.2
    assert abs(float(first["ripple"]) / 0.08 - 1.0) < 0.2
    assert float(first["band_low"]) < 130.0 * 0.95 and float(first["band_high"]) > 130.0 * 1.05
    assert first["table.v_s"] == "0.0015" and first["error"] == ""
    assert {r["status"] for r in _rows(out / "runs.csv")} == {"ok"}


def test_the_worker_gives_each_kind_the_identified_plant(friction_plant_fmu, monkeypatch):
    import tomllib

    import papwc.identify.excitation as excitation
    from papwc.battery.identify_first import SEED_SHIFT
    from papwc.battery.worker import _extract, _identify_first
    from papwc.scenario import parse_scenario

    excited = []
    apply = excitation.apply_to_fmu

    def recorded(fmu, u, h, start_values, *args, **kwargs):
        excited.append(dict(start_values))
        return apply(fmu, u, h, start_values, *args, **kwargs)

    monkeypatch.setattr(excitation, "apply_to_fmu", recorded)

    data = tomllib.loads(BATTERY)
    for table in ("sweep", "battery"):
        data.pop(table)
    scenario = parse_scenario(data, "first.toml")
    unzip = _extract(str(friction_plant_fmu))
    record: dict = {}
    assert _identify_first(scenario, str(friction_plant_fmu), unzip, record) == ""
    found = record["identified"]
    exact, papwc = scenario.controllers
    assert exact.m_est == found["m"] and exact.f_c_est == found["f_c"]
    assert exact.c_est == found["c"]
    assert papwc.m_est == found["m"] and papwc.c_est == 0.0  # papwc does not read c_est
    # the excitation met other draws of random stiction and noise than the maneuvers will
    assert [values["seed"] for values in excited] == [3 + SEED_SHIFT]
    assert {k: v for k, v in excited[0].items() if k != "seed"} == {
        k: v for k, v in scenario.plant.items() if k != "seed"}


@pytest.mark.parametrize("fmu, message", [
    ("trivial", "not a plant FMU: it has no Real x (output), v (output), x_meas (output)"),
    ("plant", "first.toml: [battery] identify_first = true: at maneuver.T = 0.1 s the "
              "excitation cannot be made: "),
])
def test_a_table_that_cannot_be_excited_is_refused_before_any_run(
        tmp_path, capsys, trivial_fmu, friction_plant_fmu, fmu, message):
    battery = tmp_path / "first.toml"
    battery.write_text(BATTERY.replace("T = 0.01", "T = 0.1"))
    out = tmp_path / "out"
    path = trivial_fmu if fmu == "trivial" else friction_plant_fmu
    code = main(["battery", str(battery), "--workers", "1", "--fmu", str(path),
                 "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and message in err, err
    assert not out.exists()


@pytest.mark.slow
def test_run_takes_the_plant_model_identify_wrote(tmp_path, empty_cwd, capsys,
                                                  friction_plant_fmu):
    identified = tmp_path / "id"
    assert main(["identify", "--fmu", str(friction_plant_fmu), "--start-values",
                 "m=120,f_c=80,f_s=110,c=500,f_s_spread=0.05,seed=2", "--deviations", "none",
                 "--out", str(identified)]) == 0
    capsys.readouterr()
    text = (identified / "plant.toml").read_text()
    assert "[identified]" in text and "[identified.band]" in text
    scenario = tmp_path / "s.toml"
    scenario.write_text('[maneuver]\nx_ref = 1e-3\niterations = 1\nduration = 0.5\n\n'
                        '[[controller]]\nkind = "exact"\nlabel = "exact"\ntolerance = 1e-7\n'
                        'm_est = 150.0\nf_c_est = 80.0\n')
    assert main(["run", str(scenario), "--plant", "physics", "--plant-model",
                 str(identified / "plant.toml"), "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert f"the plant identified in {identified / 'plant.toml'} given to exact (m_est = " in err
    # a scenario is not a plant model
    assert main(["run", str(scenario), "--plant", "physics", "--plant-model", str(scenario),
                 "--out", str(tmp_path / "run2")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"{scenario}: not a plant model written by papwc identify" in err
    assert list(empty_cwd.iterdir()) == []
