"""The battery journal survives every corruption tried here (issue 13, group 8).

A line that cannot be used is skipped with a warning and its run computed
again; resume is never blocked by a bad record and never raises a traceback.
The end-to-end check (a real battery, corrupted, resumed to byte-identical
results) is in tests/integration/test_battery_limits.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from papwc.battery.journal import JOURNAL_FORMAT, Journal, read_journal, record_problem
from papwc.errors import BatteryError, OutputError

KEY = "k" * 32
HEADER = {"type": "header", "format": JOURNAL_FORMAT, "key": KEY, "fingerprint": "f1",
          "runs": 3}


def record(run_id: str, run_hash: str = "", **extra) -> dict:
    it = {"iteration": 1, "final_error_m": 1e-6, "pulses": 3, "settle_time_s": 0.5,
          "limit_cycle": False, "cycle_p2p_m": 0.0, "b_hat": 2.0, "f_c_hat": 90.0, "error": ""}
    rec = {"type": "run", "battery": "b", "run_id": run_id, "run_hash": run_hash or f"h{run_id}",
           "params": {}, "status": "ok", "message": "", "key": KEY,
           "controllers": [{"label": "c", "kind": "papwc", "tolerance": 2e-5, "error": "",
                            "iterations": [it]}], "elapsed_s": 0.1}
    rec.update(extra)
    return rec


PLANNED = {("b", f"d{i}"): f"hd{i}" for i in range(8)}


def write(path: Path, lines: list) -> None:
    path.write_bytes(b"\n".join(
        line if isinstance(line, bytes) else json.dumps(line).encode() for line in lines)
        + b"\n")


def reopen(path: Path, header: dict = HEADER) -> Journal:
    journal = Journal(path, header, resume=True, overwrite=False, planned=PLANNED)
    journal.close()
    return journal


def wrong_shapes() -> list:
    bad_iteration = record("d3")
    bad_iteration["controllers"][0]["iterations"][0]["final_error_m"] = "x"
    no_label = record("d4")
    del no_label["controllers"][0]["label"]
    return [
        {**record("d1"), "controllers": None},          # valid JSON, wrong type
        {k: v for k, v in record("d2").items() if k != "status"},
        bad_iteration,
        no_label,
        {**record("d5"), "status": "ok", "controllers": []},
        [1, 2, 3],
        "just a string",
    ]


def test_malformed_middle_records_are_skipped_with_a_warning(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    write(path, [HEADER, record("d0"), *wrong_shapes(), record("d6")])
    journal = reopen(path)
    assert sorted(journal.records) == [("b", "d0"), ("b", "d6")]
    assert len(journal.warnings) == 7
    assert all("skipped" in w and str(path) in w for w in journal.warnings)


def test_an_unreadable_middle_line_does_not_block_resume(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    write(path, [HEADER, record("d0"), b"\x00\xff\xfe not json {", b'{"type": "run", "bat',
                 record("d1")])
    journal = reopen(path)
    assert sorted(journal.records) == [("b", "d0"), ("b", "d1")]
    assert [w.split("(")[1].split(")")[0] for w in journal.warnings] == ["not JSON"] * 2


def test_a_torn_last_line_is_dropped_and_the_journal_rewritten(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    write(path, [HEADER, record("d0"), record("d1")])
    path.write_bytes(path.read_bytes() + json.dumps(record("d2")).encode()[:40])
    journal = reopen(path)
    assert sorted(journal.records) == [("b", "d0"), ("b", "d1")] and not journal.warnings
    header, records, _ = read_journal(path)
    assert header == HEADER and [r["run_id"] for r in records] == ["d0", "d1"]


def test_records_of_other_code_parameters_runs_or_timeouts_are_recomputed(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    write(path, [HEADER, record("d0"), record("d1", key="other"), record("d2", run_hash="x"),
                 record("zz"), record("d3", status="error", message="timed out: ...",
                                      controllers=[], transient=True)])
    journal = reopen(path)
    assert sorted(journal.records) == [("b", "d0")]
    text = " ".join(journal.warnings)
    assert "another FMU model or papwc code" in text and "parameters differ" in text
    assert "not a run of these batteries" in text and "timed out" in text


def test_an_unreadable_header_keeps_the_records_of_this_key(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    write(path, [b"{not a header", record("d0"), record("d1", key="old")])
    journal = reopen(path)
    assert sorted(journal.records) == [("b", "d0")]
    assert any("header" in w for w in journal.warnings)
    assert read_journal(path)[0] == HEADER


def test_a_journal_of_another_format_or_fmu_is_refused_with_a_way_out(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    write(path, [{**HEADER, "format": 1}, record("d0")])
    with pytest.raises(BatteryError, match="journal format 1.*--overwrite"):
        reopen(path)
    write(path, [{**HEADER, "key": "other", "fingerprint": "f0"}, record("d0")])
    with pytest.raises(BatteryError, match=r"model \(its GUID\) or papwc's code differs"):
        reopen(path)


def test_a_folder_where_the_journal_should_be_is_a_named_error(tmp_path: Path) -> None:
    (tmp_path / "journal.jsonl").mkdir()
    with pytest.raises(OutputError, match="journal.jsonl': a folder is in the way"):
        Journal(tmp_path / "journal.jsonl", HEADER, resume=False, overwrite=True)


def test_every_valid_record_shape_passes_and_nan_metrics_are_allowed() -> None:
    rec = record("d0")
    rec["controllers"][0]["iterations"][0]["settle_time_s"] = float("nan")
    assert record_problem(rec) is None
    assert record_problem(json.loads(json.dumps(rec))) is None


def test_a_ctrl_c_during_an_append_comes_after_the_record_is_written_and_counted(
        tmp_path: Path) -> None:
    """A Ctrl-C that arrives while a record is appended -- here while its line is flushed,
    the SIGINT handler in effect then being run as Python runs it for a signal that came
    just before -- is raised once the record is on disk and counted, never between."""
    import signal

    path = tmp_path / "journal.jsonl"
    journal = Journal(path, HEADER, resume=False, overwrite=True, planned=PLANNED)
    real_flush = journal._file.flush

    def flush_with_ctrl_c() -> None:
        journal._file.flush = real_flush  # once
        signal.getsignal(signal.SIGINT)(signal.SIGINT, None)
        real_flush()

    journal._file.flush = flush_with_ctrl_c
    try:
        with pytest.raises(KeyboardInterrupt):
            journal.append(record("d0"))
        assert ("b", "d0") in journal.records
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        journal.close()
    assert path.read_text().count("\n") == 2  # the header and the record
