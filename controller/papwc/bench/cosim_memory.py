"""``papwc cosim`` in bounded memory: the peak resident memory of a short and a long run.

Each run is ``papwc cosim`` of the closed loop of ``scenarios/paper.toml``
(``build_closed_loop_ssp``: FrictionPlant.fmu under PulseController.fmu, every
output recorded) in a process of its own, which reports its own peak resident
set size (``VmHWM``): rows are streamed to the CSV, so the long run's peak
is that of the short one (goal: under 200 MB at 1e6 steps).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from papwc.bench import BenchContext, Row, register_section
from papwc.errors import PapwcError

#: Peak resident memory allowed to ``papwc cosim`` of 1e6 steps, MB.
MAX_PEAK_MB = 200.0

# VmHWM is the peak of this program's own memory (getrusage's ru_maxrss keeps, across exec,
# the peak of the process that started it, e.g. a large pytest).
_CHILD = """\
import resource, sys
from papwc.cli import main
code = main(sys.argv[1:])
try:
    with open("/proc/self/status") as f:
        peak = next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))
except (OSError, StopIteration, ValueError):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print("peak_kb", peak, "code", code)
"""


def cosim_peak_mb(ssp: Path, out: Path, stop: float) -> float:
    """Peak RSS (MB) of ``papwc cosim ssp --stop stop`` in a new process."""
    done = subprocess.run([sys.executable, "-c", _CHILD, "cosim", str(ssp), "--out", str(out),
                           "--stop", repr(stop)], capture_output=True, text=True)
    words = done.stdout.split()
    if done.returncode != 0 or "peak_kb" not in words or words[-1] != "0":
        raise PapwcError(f"bench: papwc cosim --stop {stop!r} failed: "
                         f"{(done.stderr or done.stdout).strip()[-300:]}")
    return int(words[words.index("peak_kb") + 1]) / 1024.0


@register_section("papwc cosim: peak resident memory (MB) against the run's length")
def cosim_memory(context: BenchContext) -> list[Row]:
    """Peak RSS of 1e3 and 1e6 steps (quick: 1e3 and 1e5) of the closed loop's SSP."""
    from papwc.fmubuild.ssp_writer import build_closed_loop_ssp
    from papwc.resources import scenario_file

    long_steps = 100_000 if context.quick else 1_000_000
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        ssp = build_closed_loop_ssp(Path(tmp), scenario_file("paper.toml"),
                                    context.fmu("FrictionPlant.fmu"),
                                    context.fmu("PulseController.fmu"))
        short = cosim_peak_mb(ssp, Path(tmp) / "short", 1_000 * 0.01)
        long = cosim_peak_mb(ssp, Path(tmp) / "long", long_steps * 0.01)
    context.notes.append(f"step 0.01 s, every output recorded; goal: under {MAX_PEAK_MB:g} "
                         "MB at 1e6 steps (memory independent of the run's length)")
    return [Row("peak RSS, 1e3 steps", short, "MB"),
            Row(f"peak RSS, {long_steps:.0e} steps", long, "MB"),
            Row("ratio long / short", long / short, "")]
