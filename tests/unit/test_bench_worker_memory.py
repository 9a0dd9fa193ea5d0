"""The process readings of ``papwc bench``'s workers' memory section."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from papwc.bench.battery_throughput import _descendants, _rss_kb

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs /proc")


def test_a_child_and_its_child_are_descendants() -> None:
    code = "import subprocess, sys; subprocess.run([sys.executable, '-c', " \
           "'import time; time.sleep(30)'])"
    child = subprocess.Popen([sys.executable, "-c", code])
    try:
        for _ in range(100):
            found = _descendants(os.getpid())
            if len(found) >= 2:
                break
            subprocess.run([sys.executable, "-c", "import time; time.sleep(0.05)"], check=True)
        assert child.pid in found
        assert len([pid for pid in found if pid != child.pid]) >= 1  # the grandchild
        assert os.getpid() not in found
    finally:
        for pid in _descendants(child.pid):
            os.kill(pid, 9)
        child.kill()
        child.wait()


def test_the_rss_of_this_process_is_read_and_grows_with_what_it_holds() -> None:
    before = _rss_kb(os.getpid())
    held = bytearray(64 * 1024 * 1024)
    held[::4096] = b"\1" * len(held[::4096])  # touch every page
    after = _rss_kb(os.getpid())
    assert before is not None and after is not None
    assert after - before >= 60 * 1024, (before, after)
    assert _rss_kb(2**22 + 12345) is None  # no such process
