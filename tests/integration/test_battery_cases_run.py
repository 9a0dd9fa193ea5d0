"""A battery with named cases run on FrictionPlant.fmu: results per case, errors recorded."""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path

from harness import TABLE_1_TOML

from papwc.battery import parse_battery, run_battery

TEXT = 'name = "cases"\n' + TABLE_1_TOML + """\
[maneuver]
x_ref = 1e-3
duration = 0.4
iterations = 2
[[controller]]
kind = "papwc"
t_p_max = 0.03
K_c = 0.8
tolerance = 2e-5
[[controller]]
kind = "exact"
tolerance = 1e-7
[cases]
exact = {}
lag = { "plant.tau_u" = 2e-3 }
noise = { "plant.noise_std" = 2e-7, "plant.x_resolution" = 1e-7 }
bad = { "plant.m_d" = 20.0 }
[sweep]
"plant.seed" = [1, 2]
"""


def read(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_battery_with_cases_reports_each_case(tmp_path: Path, friction_plant_fmu: Path) -> None:
    battery = parse_battery(tomllib.loads(TEXT), "cases.toml")
    outcome = run_battery([battery], tmp_path, friction_plant_fmu, workers=1, progress=False)
    assert outcome.runs == 8
    assert sorted(run_id for _, run_id, _ in outcome.failed) == ["bad-s0", "bad-s1"]
    assert all("k_t" in message for _, _, message in outcome.failed)
    rows = read(tmp_path / "results.csv")
    assert list(rows[0])[:4] == ["battery", "run_id", "run_hash", "case"]
    assert [r["case"] for r in rows if r["last_iteration"] == "True"] == [
        case for case in ("exact", "lag", "noise", "bad") for _ in range(2) for _ in range(2)]
    ok = [r for r in rows if r["case"] != "bad"]
    assert ok and all(r["status"] == "ok" for r in ok)
    assert {r["plant.tau_u"] for r in rows if r["case"] == "lag"} == {"0.002"}
    runs = read(tmp_path / "runs.csv")
    assert [r["case"] for r in runs] == ["exact"] * 2 + ["lag"] * 2 + ["noise"] * 2 + ["bad"] * 2
    summary = (tmp_path / "summary.md").read_text()
    assert "| case | controller |" in summary
    for case in ("exact", "lag", "noise", "bad"):
        assert f"| {case} | exact_tpmax_inf |" in summary
    assert "4 case(s) × 2 grid point(s)" in summary
    # The noise case: the seed changes what the encoder reads, so the runs differ.
    noise = [r for r in rows if r["case"] == "noise" and r["kind"] == "exact"]
    assert noise[0]["final_error_m"] != noise[2]["final_error_m"] or (
        noise[0]["pulses"] != noise[2]["pulses"])


def test_battery_without_cases_has_no_case_column(tmp_path: Path, friction_plant_fmu) -> None:
    text = TEXT.split("[cases]")[0]
    battery = parse_battery(tomllib.loads(text), "plain.toml")
    run_battery([battery], tmp_path, friction_plant_fmu, workers=1, progress=False)
    assert "case" not in read(tmp_path / "results.csv")[0]
    assert "case" not in read(tmp_path / "runs.csv")[0]
    assert "| case |" not in (tmp_path / "summary.md").read_text()
