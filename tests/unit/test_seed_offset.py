"""Judged where it was not tuned: ``papwc battery --seed-offset`` and ``papwc spec``.

The offset shifts the Monte Carlo draws' seed and every run's plant and noise seeds; the
same offset reproduces the same runs; it is part of the run hashes and of the journal, so a
resumed battery cannot mix offsets. ``papwc spec`` sets two spec.csv side by side.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from papwc.battery import load_battery, plan_runs
from papwc.battery.journal import JOURNAL_FORMAT, Journal
from papwc.battery.spec import REQUIREMENT_IDS, SPEC_COLUMNS, compare_rows, read_spec
from papwc.cli import main
from papwc.errors import BatteryError, ScenarioError
from papwc.resources import scenario_file

#: The drawn fields of scenarios/realism_mc.toml.
DRAWN = ("v_s", "ripple", "ripple_period", "f_s_spread", "tau_u", "noise_std", "c_t")


def _plan(offset: int, name: str = "realism_mc.toml") -> list:
    battery = load_battery(scenario_file(name))
    battery.seed_offset = offset
    return plan_runs([battery])


def test_an_offset_draws_other_tables_and_seeds_and_the_same_offset_the_same() -> None:
    tuned, other, again = _plan(0), _plan(1000), _plan(1000)
    assert [r.run_id for r in tuned] == [r.run_id for r in other]
    for a, b, c in zip(tuned, other, again, strict=True):
        assert b.data == c.data and b.run_hash == c.run_hash  # reproduced
        assert b.run_hash != a.run_hash
        assert b.data["plant"]["seed"] == a.data["plant"]["seed"] + 1000
        assert b.data["maneuver"]["noise_seed"] == 1000 and "noise_seed" not in a.data.get(
            "maneuver", {})
        assert all(b.data["plant"][name] != a.data["plant"][name] for name in DRAWN)
        # the same grid point and case
        assert b.data["maneuver"]["x_ref"] == a.data["maneuver"]["x_ref"]
        assert b.data["plant"].get("m_d") == a.data["plant"].get("m_d")


def test_without_an_offset_the_runs_are_the_files_own() -> None:
    """Offset 0 changes nothing: the hashes of journals written before the option stay."""
    import hashlib

    for spec in _plan(0):
        text = json.dumps(spec.data, sort_keys=True, separators=(",", ":"))
        assert spec.run_hash == hashlib.sha256(text.encode()).hexdigest()[:12]


def test_a_battery_without_draws_gets_other_plant_seeds() -> None:
    """realism.toml has no [monte_carlo]: the stiction and noise cases' seeds shift."""
    tuned, other = _plan(0, "realism.toml"), _plan(7, "realism.toml")
    assert [r.data["plant"]["seed"] + 7 for r in tuned] == [
        r.data["plant"]["seed"] for r in other]


def test_an_offset_that_takes_a_seed_out_of_its_range_is_refused() -> None:
    with pytest.raises(ScenarioError, match=r"--seed-offset 2147483646: .*realism_mc.toml run "
                                            r"rigid-s1-d000: plant.seed = 2 becomes 2147483648"):
        _plan(2**31 - 2)


def test_a_resume_with_another_offset_is_refused(tmp_path: Path) -> None:
    header = {"type": "header", "format": JOURNAL_FORMAT, "key": "k" * 32, "fingerprint": "a",
              "seed_offset": 0}
    Journal(tmp_path / "journal.jsonl", header, resume=False, overwrite=False).close()
    with pytest.raises(BatteryError, match="drawn with --seed-offset 0, these with 1000; "
                                           "resume with the journal's offset"):
        Journal(tmp_path / "journal.jsonl", {**header, "fingerprint": "b", "seed_offset": 1000},
                resume=True, overwrite=False)


def _spec_row(battery: str, controller: str, within: int, far_beyond: int) -> dict:
    row = {c: "" if c in REQUIREMENT_IDS else "0" for c in SPEC_COLUMNS}
    row.update(battery=battery, case="rigid", controller=controller, kind="exact", runs="30",
               within_1um=str(within), counted_runs="30", within_count="9",
               settle_median_s="0.62", settle_p95_s="inf", far_beyond=str(far_beyond),
               R1="MISSED" if within < 26 else "met", R4h="MISSED" if far_beyond else "met")
    return row


def _write_spec(folder: Path, rows: list[dict]) -> Path:
    folder.mkdir()
    with open(folder / "spec.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=SPEC_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    return folder


def test_the_tuned_and_the_out_of_sample_figures_side_by_side(tmp_path: Path) -> None:
    tuned = _write_spec(tmp_path / "tuned", [_spec_row("realism_mc", "exact", 27, 0)])
    other = _write_spec(tmp_path / "other", [_spec_row("realism_mc_fresh", "exact", 18, 2),
                                             _spec_row("realism_mc_fresh", "pid", 0, 0)])
    rows = compare_rows(read_spec(tuned), read_spec(other))
    by = {(r["controller"], r["figure"]): (r["tuned"], r["other"]) for r in rows}
    assert by[("exact", "within 1 um")] == ("27/30 (90%)", "18/30 (60%)")
    assert by[("exact", "beyond at >= 50 um")] == ("0", "2")
    assert by[("exact", "settle p95 (s)")] == ("inf", "inf")
    assert by[("exact", "verdicts")] == ("R1 met, R4h met", "R1 MISSED, R4h MISSED")
    assert by[("pid", "within 1 um")] == ("–", "0/30 (0%)")  # only out of sample
    assert {r["battery"] for r in rows} == {"realism_mc"}  # the twin's suffix dropped

    out = tmp_path / "cmp"
    assert main(["spec", str(tuned), str(other / "spec.csv"), "--out", str(out)]) == 0
    text = (out / "spec_compare.md").read_text()
    assert ("| rigid | exact | 27/30 (90%) → 18/30 (60%) | 9/30 (30%) → 9/30 (30%) | – → – "
            "|") in text
    assert text.count("| rigid | exact |") == 1 and "| rigid | pid | – → 0/30 (0%) |" in text
    with open(out / "spec_compare.csv", newline="") as f:
        assert len(list(csv.DictReader(f))) == len(rows)


def test_a_missing_or_foreign_spec_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    assert main(["spec", str(tmp_path / "nowhere"), str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "nowhere: no such file; give a battery's output" in err
    (tmp_path / "spec.csv").write_text("battery,case,controller\nb,,c\n")
    assert main(["spec", str(tmp_path), str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "not a spec.csv of this papwc: column(s) within_1um, runs" in err


@pytest.mark.parametrize("value", ["-1", "x", "2147483648"])
def test_a_bad_offset_is_refused_before_anything_runs(value: str, tmp_path: Path,
                                                      capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["battery", str(scenario_file("realism_mc.toml")), "--seed-offset", value,
              "--out", str(tmp_path / "out")])
    assert stop.value.code == 2 and "--seed-offset" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
