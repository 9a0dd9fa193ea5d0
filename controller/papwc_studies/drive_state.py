"""Planning pulses on a flexible drive from a model of it: how exact the model must be.

The table's encoder does not show the drive's ringing while the table sticks, but the
ringing follows from the force commanded and the table's position, given the drive's
masses, spring and damper. This measures what planning with such a model would reach, on
the ``flexible`` case of ``scenarios/realism.toml`` (the model layer's plant,
:class:`papwc.model.dynamics.Plant`, as the machine):

* a second plant, the model, with some parameters off by a given fraction, is driven by
  the same force as the machine; at every rest of the machine the model's table (and its
  motor with it, the spring's stretch kept) is moved to the encoder's reading;
* the drive is first set ringing by one sample at ``RING_FORCE``; then ``moves`` moves of
  ``STEP`` each are made, each by one sample whose height is found by bisection so that
  the model lands on the target ``REST`` s later;
* it prints, per model, where the machine landed against each target.

Run ``python -m papwc_studies.drive_state [--moves N]``; it prints one line per model.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from papwc.model.dynamics import Plant
from papwc.model.pulse import bisect_increasing
from papwc_studies.counts import parse_count
from papwc_studies.ringing import flexible_plant

__all__ = ["MODELS", "landings", "main"]

#: Models: name and the parameters scaled (factor) against the machine's.
MODELS: tuple[tuple[str, Mapping[str, float]], ...] = (
    ("exact parameters", {}),
    ("damping c_t +20 %", {"c_t": 1.2}),
    ("spring k_t +0.5 %", {"k_t": 1.005}),
    ("spring k_t +2 %", {"k_t": 1.02}),
    ("motor mass m_d +2 %", {"m_d": 1.02}),
)
#: Height of the one-sample pulse that sets the drive ringing first, N.
RING_FORCE = 200.0
#: Length of each move, m.
STEP = 30e-6
#: Time at rest after each pulse, s.
REST = 0.3
#: Bisection of the height: interval and the bracket's width it stops at (30 halvings), N.
HEIGHT_RANGE = (0.0, 300.0)
HEIGHT_TOL = (HEIGHT_RANGE[1] - HEIGHT_RANGE[0]) / 2**30
#: Default and largest number of moves.
MOVES = 4
MOVES_MAX = 50


class _Pair:
    """The machine and a model of it, driven by the same force (SI units)."""

    def __init__(self, params: Mapping[str, float], model: Mapping[str, float], T: float):
        self.machine = Plant(params)
        self.model = Plant(model)
        self.model_params = dict(model)
        self.T = T

    def apply(self, forces: Sequence[float]) -> None:
        """Hold each force for one sample on both; at a rest, the model's table is re-read."""
        for u in forces:
            self.machine.step(u, self.T)
            self.model.step(u, self.T)
        if self.machine.v == 0.0:
            state = self.model.state()
            shift = self.machine.x_meas() - state["x"]
            state["x"] += shift
            state["x_d"] += shift
            state["v"] = 0.0
            self.model.set_state(state)

    def model_move(self, f_p: float, rest: int) -> float:
        """Where the model's table ends after one sample at f_p (N) and ``rest`` samples, m."""
        trial = Plant(self.model_params)
        trial.set_state(self.model.state())
        trial.step(f_p, self.T)
        for _ in range(rest):
            trial.step(0.0, self.T)
        return trial.x

    def plan(self, target: float, rest: int) -> float:
        """Height (N) of one sample by which the model lands on target (m), by bisection."""
        lo, hi = HEIGHT_RANGE
        if self.model_move(hi, rest) < target:
            return hi
        return bisect_increasing(lambda f: self.model_move(f, rest), target, lo, hi,
                                 HEIGHT_TOL)[1]


def landings(scale: Mapping[str, float], moves: int) -> list[float]:
    """Errors (m, machine minus target) of ``moves`` planned moves with the model ``scale``."""
    params, _, T = flexible_plant()
    model = {k: v * scale.get(k, 1.0) for k, v in params.items()}
    pair = _Pair(params, model, T)
    rest = round(REST / T)
    pair.apply([RING_FORCE] + [0.0] * rest)
    target = pair.machine.x
    out = []
    for _ in range(moves):
        target += STEP
        f_p = pair.plan(target, rest)
        pair.apply([f_p] + [0.0] * rest)
        out.append(pair.machine.x - target)
    return out


def main(argv: Sequence[str] | None = None) -> None:
    """Print, per model, where the machine lands against each target.

    ``argv`` (default ``sys.argv[1:]``): ``--moves N`` (1 to ``MOVES_MAX``, default
    ``MOVES``); anything else is refused (exit 2).
    """
    moves = parse_count(argv, "python -m papwc_studies.drive_state",
                        "one-sample pulses on the flexible drive of scenarios/realism.toml "
                        "planned on a model of the drive carried along with the force: the "
                        "landing errors", "--moves", MOVES, MOVES_MAX, "moves per model")
    print(f"flexible case of realism.toml: one sample at {RING_FORCE:g} N, then {moves} "
          f"moves of {STEP * 1e6:g} um, each one sample planned on the model, {REST:g} s apart")
    for name, scale in MODELS:
        errors = landings(scale, moves)
        worst = max(abs(e) for e in errors)
        print(f"{name:20s}: lands " + " ".join(f"{e * 1e6:+7.2f}" for e in errors)
              + f" um off (largest {worst * 1e6:.2f} um)")


if __name__ == "__main__":
    import sys

    from papwc.exit_status import run_command

    sys.exit(run_command("python -m papwc_studies.drive_state", main))
