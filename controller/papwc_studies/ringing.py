"""What pulses do to a flexible drive: the measurements behind the README's flexible-mode notes.

On the ``flexible`` case of ``scenarios/realism.toml`` (a 100 kg table driven through a
spring by a 50 kg motor, a 20 Hz mode with 2 % damping while the table sticks), with the
model layer's plant (:class:`papwc.model.dynamics.Plant`), every force held over whole
samples of T:

* one-mode-period pulses (``round(1/(f_mode*T))`` samples) of rising height, and one
  sample at 140 N: how far the table moves and the spring force left ringing 0.6 s
  later, N;
* the same pulse twice: how far the second moves, by the time between them;
* the smallest move: for pulses of 1 and 2 samples and of one mode period, the height at
  which the table breaks away (found by bisection to ``THRESHOLD_TOL``), how far it moves
  just above it and ``ABOVE`` N higher: the slip has a smallest size, and above it each
  newton moves the table some um, so a move known to 1 um needs the height known against
  a breakaway, set by the spring force the drive is left with, to a fraction of a newton.

Run ``python -m papwc_studies.ringing``; it prints one line per pulse.
"""

from __future__ import annotations

import argparse
import math
import tomllib
from collections.abc import Callable, Sequence

from papwc.model.dynamics import Plant
from papwc.model.pulse import bisect_increasing
from papwc_studies import scenario_path

__all__ = ["breakaway_height", "flexible_plant", "main", "spring_force"]

#: Heights of the one-period pulses, N.
HEIGHTS = (67.0, 67.5, 70.0, 75.0, 80.0)
#: Height of a one-sample pulse shown beside them, N.
ONE_SAMPLE = 140.0
#: Height of the repeated pulse, N, and the times from the end of the first to the second, s.
REPEATED = 75.0
WAITS = (0.15, 0.2, 0.25, 0.4, 1.0)
#: Widths (samples; 0 = one mode period) whose breakaway height is searched.
THRESHOLD_WIDTHS = (1, 2, 0)
#: Bisection interval (N) and tolerance (N) of the breakaway height, and the step above, N.
THRESHOLD_RANGE = (10.0, 300.0)
THRESHOLD_TOL = 1e-4
ABOVE = 0.5
#: Time at rest after a pulse before its displacement and ringing are read, s.
SETTLE = 0.6


def flexible_plant() -> tuple[dict[str, float], float, float]:
    """Plant parameters, f_mode (Hz) and T (s) of the ``flexible`` case of realism.toml."""
    with open(scenario_path("realism.toml"), "rb") as f:
        data = tomllib.load(f)
    params = dict(data["plant"])
    f_mode = 0.0
    for key, value in data["cases"]["flexible"].items():
        if key.startswith("plant."):
            params[key.removeprefix("plant.")] = value
        elif key == "controller.f_mode":
            f_mode = float(value)
    return params, f_mode, float(data["maneuver"]["T"])


def spring_force(plant: Plant) -> float:
    """Force of the coupling on the table, N (``FlexibleMode.coupling``)."""
    return plant.flexible.coupling(plant.x, plant.v, plant.x_d, plant.v_d)


def breakaway_height(moves: Callable[[float], float]) -> float:
    """Lowest height (N) in ``THRESHOLD_RANGE`` at which ``moves(height)`` (m) is > 0.

    By bisection to ``THRESHOLD_TOL``; ``moves`` is taken as 0 below a height and > 0 above.
    NaN if the top of the range does not move the table.
    """
    lo, hi = THRESHOLD_RANGE
    if not moves(hi) > 0.0:
        return math.nan
    if moves(lo) > 0.0:
        return lo
    # the indicator "it moved" is non-decreasing in the height: 0 below, 1 from breakaway
    return bisect_increasing(lambda f: float(moves(f) > 0.0), 0.5, lo, hi, THRESHOLD_TOL)[1]


def main(argv: Sequence[str] | None = None) -> None:
    """Print the table's moves and the ringing left, pulse by pulse.

    Takes no arguments (``argv``, default ``sys.argv[1:]``); any given is refused (exit 2).
    """
    argparse.ArgumentParser(
        prog="python -m papwc_studies.ringing",
        description="what one-period pulses do to the flexible drive of scenarios/realism.toml",
    ).parse_args(argv)
    params, f_mode, T = flexible_plant()
    n = max(1, round(1.0 / (f_mode * T)))
    rest = round(SETTLE / T)

    def run(forces: list[float]) -> Plant:
        plant = Plant(params)
        for u in forces:
            plant.step(u, T)
        return plant

    print(f"flexible case of realism.toml: f_mode = {f_mode:g} Hz, T = {T:g} s, "
          f"one mode period = {n} samples")
    for f in HEIGHTS:
        p = run([f] * n + [0.0] * rest)
        print(f"one-period pulse at {f:5.1f} N: moves {p.x * 1e6:6.1f} um, "
              f"leaves {spring_force(p):5.1f} N ringing")
    p = run([ONE_SAMPLE] + [0.0] * rest)
    print(f"one-sample pulse at {ONE_SAMPLE:5.1f} N: moves {p.x * 1e6:6.1f} um, "
          f"leaves {spring_force(p):5.1f} N ringing")
    first = run([REPEATED] * n + [0.0] * rest).x
    for wait in WAITS:
        k = round(wait / T)
        before = run([REPEATED] * n + [0.0] * k).x
        after = run([REPEATED] * n + [0.0] * k + [REPEATED] * n + [0.0] * rest).x
        print(f"the {REPEATED:g} N pulse again {wait * 1e3:5.0f} ms after the first "
              f"(which moved {first * 1e6:.1f} um): moves {(after - before) * 1e6:6.1f} um")
    for width in THRESHOLD_WIDTHS:
        k = width or n

        def moves(f: float, k: int = k) -> float:
            return run([f] * k + [0.0] * rest).x

        f_b = breakaway_height(moves)
        print(f"breakaway of a {k}-sample pulse at {f_b:.4f} N: moves {moves(f_b) * 1e6:5.2f} um "
              f"there and {moves(f_b + ABOVE) * 1e6:5.2f} um at {ABOVE:g} N more")


if __name__ == "__main__":
    import sys

    from papwc.exit_status import run_command

    sys.exit(run_command("python -m papwc_studies.ringing", main))
