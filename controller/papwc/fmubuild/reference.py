"""Write the FrictionPlant reference result in the FMI cross-check layout.

Writes, into ``fmu_src/FrictionPlant/`` (or the folder given):

- ``FrictionPlant_in.csv``: the force ``u`` (N), zero-order hold: each change is
  written as two rows with the same time (old value, then new value);
- ``FrictionPlant_ref.csv``: ``x`` (m) and ``v`` (m/s) every 0.01 s from 0 s to
  1 s, the exact solution from :func:`papwc.model.stickslip.simulate` with the
  default parameters (m = 150 kg, f_c = 100 N, f_s = 130 N, c = 700 N.s/m);
- ``FrictionPlant_ref.opt``: StartTime, StopTime, StepSize, RelTol.

The input holds a positive and a negative pulse above f_s (each followed by a
coast to rest), a sub-stiction force that leaves the mass stuck, and a pulse
followed by a reverse force above f_s while the mass slides (a reversal inside
a step).

Run ``python -m papwc.fmubuild.reference [OUT_DIR]`` to regenerate the files.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from papwc.model.plant import PLANT_DEFAULTS
from papwc.model.stickslip import simulate
from papwc.resources import fmu_src_dir

__all__ = [
    "PARAMETERS",
    "STEP_SIZE",
    "STOP_TIME",
    "U_SEGMENTS",
    "reference_input",
    "write_reference",
]

#: Communication step size of the reference, s.
STEP_SIZE = 0.01
#: Number of steps; the reference covers 0 s to STOP_TIME.
N_STEPS = 100
#: Stop time, s.
STOP_TIME = N_STEPS * STEP_SIZE
#: Plant parameters of the reference (the FMU's start values): kg, N, N, N.s/m.
PARAMETERS: dict[str, float] = {k: PLANT_DEFAULTS[k] for k in ("m", "f_c", "f_s", "c")}

#: (first step index, force in N) of each input segment; the force holds until the next.
U_SEGMENTS: tuple[tuple[int, float], ...] = (
    (0, 300.0),  # pulse above f_s: breakaway
    (5, 0.0),  # coast to rest, then stuck
    (25, 120.0),  # |u| <= f_s at rest: stays stuck
    (35, -300.0),  # negative pulse above f_s
    (40, 0.0),  # coast to rest
    (55, 250.0),  # pulse above f_s
    (62, -200.0),  # reverse force above f_s while sliding: stops and reverses
    (66, 0.0),  # coast to rest, stuck until the end
)


def _time(k: int) -> float:
    """Time of step index k, s, as the double nearest to k * STEP_SIZE."""
    return round(k * STEP_SIZE, 12)


def reference_input() -> list[float]:
    """Force held over each of the N_STEPS intervals, N."""
    u_seq = []
    bounds = [k for k, _ in U_SEGMENTS[1:]] + [N_STEPS]
    for (k0, u), k1 in zip(U_SEGMENTS, bounds, strict=True):
        u_seq.extend([u] * (k1 - k0))
    return u_seq


def write_reference(out_dir: Path | None = None) -> tuple[Path, Path, Path]:
    """Write FrictionPlant_in.csv, FrictionPlant_ref.csv and FrictionPlant_ref.opt.

    Parameters
    ----------
    out_dir : Path, optional
        Folder to write into (default: ``fmu_src/FrictionPlant``).

    Returns
    -------
    tuple of Path
        The input, reference and options files written.
    """
    out_dir = fmu_src_dir() / "FrictionPlant" if out_dir is None else Path(out_dir)
    in_path = out_dir / "FrictionPlant_in.csv"
    ref_path = out_dir / "FrictionPlant_ref.csv"
    opt_path = out_dir / "FrictionPlant_ref.opt"

    rows = ['"time","u"']
    previous = None
    for k, u in U_SEGMENTS:
        if previous is not None:
            rows.append(f"{_time(k)!r},{previous!r}")
        rows.append(f"{_time(k)!r},{u!r}")
        previous = u
    rows.append(f"{_time(N_STEPS)!r},{previous!r}")
    in_path.write_text("\n".join(rows) + "\n")

    states = simulate(reference_input(), STEP_SIZE, **PARAMETERS)
    rows = ['"time","x","v"']
    rows += [f"{_time(k)!r},{x!r},{v!r}" for k, (x, v) in enumerate(states)]
    ref_path.write_text("\n".join(rows) + "\n")

    opt_path.write_text(
        f"StartTime, 0.0\nStopTime, {STOP_TIME!r}\nStepSize, {STEP_SIZE!r}\nRelTol, 1e-06\n"
    )
    return in_path, ref_path, opt_path


def main(argv: list[str] | None = None) -> int:
    """Command line: write the reference files and print their paths."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "out_dir",
        nargs="?",
        type=Path,
        default=None,
        help="folder to write into (default: fmu_src/FrictionPlant)",
    )
    args = parser.parse_args(argv)
    for path in write_reference(args.out_dir):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
