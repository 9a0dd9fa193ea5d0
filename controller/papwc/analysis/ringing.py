"""What pulses do to a flexible drive: the measurements behind the README's flexible-mode notes.

On the ``flexible`` case of ``scenarios/realism.toml`` (a 100 kg table driven through a
spring by a 50 kg motor, a 20 Hz mode with 2 % damping while the table sticks), with the
model layer's plant (:class:`papwc.model.dynamics.Plant`), every force held over whole
samples of T:

* one-mode-period pulses (``round(1/(f_mode*T))`` samples) of rising height, and one
  sample at 140 N: how far the table moves and the spring force left ringing 0.6 s
  later, N;
* the same pulse twice: how far the second moves, by the time between them.

Run ``python -m papwc.analysis.ringing``; it prints one line per pulse.
"""

from __future__ import annotations

import argparse
import tomllib
from collections.abc import Sequence

from papwc.model.dynamics import Plant
from papwc.resources import scenario_file

__all__ = ["flexible_plant", "main", "spring_force"]

#: Heights of the one-period pulses, N.
HEIGHTS = (67.0, 67.5, 70.0, 75.0, 80.0)
#: Height of a one-sample pulse shown beside them, N.
ONE_SAMPLE = 140.0
#: Height of the repeated pulse, N, and the times from the end of the first to the second, s.
REPEATED = 75.0
WAITS = (0.15, 0.2, 0.25, 0.4, 1.0)
#: Time at rest after a pulse before its displacement and ringing are read, s.
SETTLE = 0.6


def flexible_plant() -> tuple[dict[str, float], float, float]:
    """Plant parameters, f_mode (Hz) and T (s) of the ``flexible`` case of realism.toml."""
    with open(scenario_file("realism.toml"), "rb") as f:
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


def main(argv: Sequence[str] | None = None) -> None:
    """Print the table's moves and the ringing left, pulse by pulse.

    Takes no arguments (``argv``, default ``sys.argv[1:]``); any given is refused (exit 2).
    """
    argparse.ArgumentParser(
        prog="python -m papwc.analysis.ringing",
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


if __name__ == "__main__":
    main()
