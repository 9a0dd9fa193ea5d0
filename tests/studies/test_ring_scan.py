"""papwc_studies.ring_scan: whether the pulse controllers ever see ringing on rigid tables."""

from __future__ import annotations

from harness import table_1

from papwc_studies.ring_scan import mc_rigid, realism_rigid, ringing_runs

RIGID = table_1()
#: 15 Hz while the table sticks, 2 % damping (as in tests/unit/test_ringing_unknown.py).
TABLE_15HZ = {**RIGID, "m": 100.0, "m_d": 50.0, "k_t": 4.441e5, "c_t": 188.5}


def test_the_ring_scan_finds_ringing_on_a_flexible_table_only():
    """python -m papwc_studies.ring_scan counts what it should."""
    runs, seen = ringing_runs([("flex15", TABLE_15HZ), ("eq1", RIGID)])
    assert runs == 18
    assert seen and all(line.startswith("flex15 ") for line in seen)
    assert len(realism_rigid()) == 15 and len(mc_rigid(2)) == 4
