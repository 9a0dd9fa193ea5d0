"""How far the same pulse moves a table whose breakaway force is redrawn at every stop.

The measurements behind the README's note on the Monte Carlo's rigid tables: with the
table of ``scenarios/realism_mc.toml`` (its ``[plant]``: m, f_c, f_s, c, the encoder) and
the model layer's plant (:class:`papwc.model.dynamics.Plant`), a Stribeck curve and random
stiction at strengths inside the Monte Carlo's ranges, one sample at a fixed height is
applied again and again, each time from rest (``REST`` s after the last). For each height
it prints how many of the pulses moved the table and, of those, the smallest, median and
largest displacement, the largest over the median, and how many moved more than 1.5 times
the median: a pulse planned for an error ``|e|`` equal to its median displacement moves
beyond the runaway bound ``1.5*|e|`` that often, however well its median is known. The
line ends with ``1.5/(largest/median)``, the largest fraction of ``|e|`` such a pulse could
be planned for and never pass the bound over these repetitions.

Run ``python -m papwc_studies.scatter [--repeats N]``; it prints one line per height.
"""

from __future__ import annotations

import statistics
import tomllib
from collections.abc import Sequence

from papwc.model.dynamics import Plant
from papwc_studies import scenario_path
from papwc_studies.counts import MOVED, REPEATS_MAX, moves_line, parse_count

__all__ = ["CASES", "HEIGHTS", "main", "repeated_pulse", "table"]

#: Deviations applied (name, plant fields), each inside the Monte Carlo's ranges.
CASES = (
    ("Stribeck v_s = 1.5 mm/s, random stiction +-10 %", {"v_s": 1.5e-3, "f_s_spread": 0.10}),
    ("Stribeck v_s = 5 mm/s, random stiction +-15 %", {"v_s": 5e-3, "f_s_spread": 0.15}),
)
#: Heights of the one-sample pulse, N.
HEIGHTS = (150.0, 160.0, 180.0)
#: Time at rest after each pulse, s.
REST = 0.6
#: Seed of the random stiction.
SEED = 1
#: Default number of repetitions of a pulse (at most ``REPEATS_MAX``).
REPEATS = 300


def table() -> tuple[dict[str, float], float]:
    """The ``[plant]`` table of ``scenarios/realism_mc.toml`` (SI units) and its T (s)."""
    with open(scenario_path("realism_mc.toml"), "rb") as f:
        data = tomllib.load(f)
    return {k: float(v) for k, v in data["plant"].items()}, float(data["maneuver"]["T"])


def repeated_pulse(params: dict[str, float], f_p: float, repeats: int, T: float) -> list[float]:
    """Displacements (m) of ``repeats`` pulses of one sample T (s) at f_p (N), each from rest."""
    plant = Plant(params)
    rest = round(REST / T)
    out = []
    for _ in range(repeats):
        x0 = plant.x
        plant.step(f_p, T)
        for _ in range(rest):
            plant.step(0.0, T)
        out.append(plant.x - x0)
    return out


def main(argv: Sequence[str] | None = None) -> None:
    """Print, per deviation and height, how the displacement of the same pulse scatters.

    ``argv`` (default ``sys.argv[1:]``): ``--repeats N`` (1 to ``REPEATS_MAX``, default
    ``REPEATS``); anything else is refused (exit 2).
    """
    repeats = parse_count(argv, "python -m papwc_studies.scatter",
                          "how far the same one-sample pulse moves a table of scenarios/"
                          "realism_mc.toml whose breakaway force is redrawn at every stop",
                          "--repeats", REPEATS, REPEATS_MAX, "pulses per height")
    base, T = table()
    print(f"table of realism_mc.toml: m = {base['m']:g} kg, f_c = {base['f_c']:g} N, "
          f"f_s = {base['f_s']:g} N; one sample of T = {T:g} s, {repeats} times, "
          f"{REST:g} s apart")
    for name, fields in CASES:
        params = {**base, **fields, "seed": SEED}
        print(name)
        for f_p in HEIGHTS:
            moved = [d * 1e6 for d in repeated_pulse(params, f_p, repeats, T) if d > MOVED]
            if not moved:
                print(f"  {f_p:5.1f} N: moved 0 of {repeats}")
                continue
            med = statistics.median(moved)
            top = max(moved)
            beyond = sum(d > 1.5 * med for d in moved)
            print(f"  {f_p:5.1f} N: {moves_line(moved, repeats)}, "
                  f"largest/median {top / med:.2f}, beyond 1.5*median {beyond} "
                  f"({100.0 * beyond / len(moved):.0f} %); safe plan {1.5 * med / top:.2f}*|e|")


if __name__ == "__main__":
    import sys

    from papwc.exit_status import run_command

    sys.exit(run_command("python -m papwc_studies.scatter", main))
