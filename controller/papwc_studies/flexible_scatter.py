"""How far the same pulse from a relaxed flexible drive moves a table with random stiction.

The measurement behind the README's note on the dual-loop controller on the Monte Carlo's
flexible draws. The drive of ``scenarios/realism_mc_dual.toml`` (its ``[plant]`` and its
10 Hz and 20 Hz cases: a 100 kg table pushed through a spring by a 50 kg motor) with the
model layer's plant (:class:`papwc.model.dynamics.Plant`), a Stribeck curve and random
stiction at strengths inside the Monte Carlo's ranges, no lag, no ripple, no noise. Each
repetition starts from rest with the drive *perfectly* relaxed (motor at the table, no
speed: what the dual-loop controller's motor loop aims for), applies one sample of motor
force ``h/(2*sin(omega*T/2))`` (the spring's first peak pushes the table with about ``h``,
as the dual-loop controller plans its one-sample pulses), then no force until the table
sticks again.

For each drive, stiction spread and table push ``h`` it prints how many pulses moved the
table and, of those, the smallest, median and largest move, and the share that landed
within 1 um of the median: however well a controller knows the median move of a pulse, it
lands within 1 um of its plan no more often than that. A pulse near breakaway moves the
table by the slip the spring releases (tens of um on the 20 Hz drive, more on the 10 Hz
one), and the breakaway force redrawn at every stop moves the whole curve.

Run ``python -m papwc_studies.flexible_scatter [--repeats N]``; it prints one line per push.
"""

from __future__ import annotations

import math
import statistics
import tomllib
from collections.abc import Sequence

from papwc.model.dynamics import Plant
from papwc_studies import scenario_path
from papwc_studies.counts import MOVED, REPEATS_MAX, moves_line, parse_count

__all__ = ["DRIVES", "SPREADS", "drive", "main", "relaxed_pulse"]

#: Cases of realism_mc_dual.toml studied, and their mode's frequency (Hz).
DRIVES = (("flexible_20hz", 20.0), ("flexible_10hz", 10.0))
#: Fixed deviations (inside the Monte Carlo's ranges): Stribeck v_s (m/s), the
#: coupling's damping c_t (N.s/m).
V_S = 1.5e-3
C_T = 250.0
#: Relative spreads of the random stiction.
SPREADS = (0.01, 0.05, 0.15)
#: Table pushes above the highest breakaway force the spread allows, N.
ABOVE = (1.0, 5.0, 15.0)
#: Seed of the random stiction.
SEED = 1
#: Default number of repetitions of a pulse (at most ``REPEATS_MAX``).
REPEATS = 200
#: Longest wait for the table to stick after a pulse, s.
WAIT_MAX = 2.0
#: A move within this of the median lands on the plan, m.
LANDS = 1e-6


def drive(case: str) -> tuple[dict[str, float], float]:
    """The ``[plant]`` of ``scenarios/realism_mc_dual.toml`` with the case's fields (SI
    units), and its T (s)."""
    with open(scenario_path("realism_mc_dual.toml"), "rb") as f:
        data = tomllib.load(f)
    params = {k: float(v) for k, v in data["plant"].items()}
    for key, value in data["cases"][case].items():
        if key.startswith("plant."):
            params[key.removeprefix("plant.")] = float(value)
    return params, float(data["maneuver"]["T"])


def relaxed_pulse(params: dict[str, float], f_mode: float, h: float, repeats: int,
                  T: float) -> list[float]:
    """Moves (m) of ``repeats`` one-sample motor pulses that push the table with about h (N).

    Each from rest with the drive relaxed, read at the first sample the table sticks at
    after it moved, or after the spring's first peak if it did not (the best a motor loop
    can do: relax the drive from there). A pulse after which the table does not stick
    within ``WAIT_MAX`` ends the list.
    """
    plant = Plant(params)
    force = h / (2.0 * math.sin(math.pi * f_mode * T))
    wait = round(WAIT_MAX / T)
    # samples after the pulse's until the spring's first peak (the table breaks away by then)
    peak = math.ceil(0.25 / (f_mode * T) - 0.5)
    out = []
    for _ in range(repeats):
        plant.x_d, plant.v_d = plant.x, 0.0  # the motor loop's aim: the drive relaxed
        x0 = plant.x
        plant.step(force, T)
        for k in range(wait):
            plant.step(0.0, T)
            if plant.v == 0.0 and (plant.x != x0 or k >= peak):
                break
        else:
            break
        out.append(plant.x - x0)
    return out


def main(argv: Sequence[str] | None = None) -> None:
    """Print, per drive, spread and push, how the move of the same relaxed-drive pulse
    scatters.

    ``argv`` (default ``sys.argv[1:]``): ``--repeats N`` (1 to ``REPEATS_MAX``, default
    ``REPEATS``); anything else is refused (exit 2).
    """
    repeats = parse_count(argv, "python -m papwc_studies.flexible_scatter",
                          "how far the same one-sample pulse from a relaxed flexible drive "
                          "of scenarios/realism_mc_dual.toml moves a table whose breakaway "
                          "force is redrawn at every stop",
                          "--repeats", REPEATS, REPEATS_MAX, "pulses per push")
    for case, f_mode in DRIVES:
        base, T = drive(case)
        print(f"{case} of realism_mc_dual.toml: m = {base['m']:g} kg, m_d = {base['m_d']:g} "
              f"kg, k_t = {base['k_t']:g} N/m, f_s = {base['f_s']:g} N, f_c = "
              f"{base['f_c']:g} N, v_s = {V_S * 1e3:g} mm/s, c_t = {C_T:g} N.s/m; one "
              f"sample on the motor from a relaxed drive, {repeats} times")
        for spread in SPREADS:
            params = {**base, "v_s": V_S, "c_t": C_T, "f_s_spread": spread, "seed": SEED}
            top = base["f_s"] * (1.0 + spread)
            for above in ABOVE:
                h = top + above
                moved = [d * 1e6 for d in relaxed_pulse(params, f_mode, h, repeats, T)
                         if d > MOVED]
                head = f"  spread {100 * spread:4.1f} %, push {h:6.1f} N:"
                if not moved:
                    print(f"{head} moved 0 of {repeats}")
                    continue
                med = statistics.median(moved)
                lands = sum(abs(d - med) <= LANDS * 1e6 for d in moved)
                print(f"{head} {moves_line(moved, repeats)}; within 1 um of the median "
                      f"{lands} ({100.0 * lands / len(moved):.0f} %)")


if __name__ == "__main__":
    import sys

    from papwc.exit_status import run_command

    sys.exit(run_command("python -m papwc_studies.flexible_scatter", main))
