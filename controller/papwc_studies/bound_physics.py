"""Why a hard per-pulse bound holds for one-sample pulses only from about 50 um of error.

The figures behind docs/_incoming/43-the-bound.md, on the model layer's plant
(:class:`papwc.model.dynamics.Plant`; Table 1, T = 10 ms, a 0.1 um encoder), stick-slip
tables with a Stribeck curve as in ``scenarios/realism_mc.toml``:

1. *The move grows from zero.* The excess over the height that just breaks the table away
   (:attr:`papwc.results.quantum.Quantum.u_break`, the breakaway drawn at f_s) at which one
   sample from rest moves one count: per Stribeck velocity and lag.
2. *A fresh stick moves at most so far.* One sample at the height sure to break the table
   away anywhere in its band (``u_break`` at the band top, stiction spread and ripple at the
   Monte Carlo's largest, 15 % each) on a table whose breakaway was drawn at the band's
   bottom, at the ripple's trough: the largest move over the Monte Carlo's Stribeck
   velocities, lags and ripple periods.
3. *The best staircase still runs away.* Told the table but not the draw, from rest 1 um
   from the target through the encoder: one-sample pulses from the height that breaks the
   table away at the band's bottom, each the largest step higher that moves at most
   ``1.5*abs(e) + q`` should the breakaway lie just above the last pulse that did not move
   it, a 0.3 s wait after each; the approach ends at the first move the encoder shows. A
   creep below one count redraws the breakaway anywhere in the band, and the next step may
   then stand far above it: the share of approaches whose first seen move passes
   ``1.5*abs(e) + q``, at a 15 % spread.

Run ``python -m papwc_studies.bound_physics [--approaches N]`` (N approaches per table in
part 3, default 400; about 40 s on one core).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

from papwc.model.dynamics import Plant
from papwc.model.pulse import bisect_increasing
from papwc.results.quantum import move_from_rest, table_quantum

__all__ = ["excess_for_one_count", "fresh_stick_move", "main", "staircase_runaways"]

T = 0.01
#: One count of the Monte Carlo's encoder, m.
COUNT = 1e-7
#: Table 1.
TABLE_1 = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
#: The Monte Carlo's Stribeck velocities (m/s) and lags (s) the study goes over.
V_S = (2e-4, 1e-3, 5e-3)
TAU_U = (0.0, 2.5e-3, 5e-3)
#: The Monte Carlo's largest stiction spread and ripple, and its ripple periods (m).
SPREAD = 0.15
RIPPLE = 0.15
RIPPLE_PERIODS = (5e-4, 5e-3)
#: Samples waited after each pulse of the staircase.
WAIT = 30
#: Most pulses of one approach.
PULSES_MAX = 400


def excess_for_one_count(v_s: float, tau_u: float) -> float:
    """The excess (N) over ``u_break`` at which one sample from rest moves one count."""
    table = {**TABLE_1, "v_s": v_s, "tau_u": tau_u}
    u_break = table_quantum(table, T).u_break
    lo, hi = bisect_increasing(lambda x: move_from_rest(table, T, u_break + x), COUNT,
                               0.0, 60.0, tol=1e-4)
    return 0.5 * (lo + hi)


def fresh_stick_move(v_s: float, tau_u: float, period: float) -> float:
    """The move (m) of one sample at the band top's ``u_break`` on a table whose breakaway
    was drawn at the band's bottom, at the ripple's trough (see the module)."""
    table = {**TABLE_1, "v_s": v_s, "tau_u": tau_u, "f_s_spread": SPREAD, "ripple": RIPPLE,
             "ripple_period": period}
    u = table_quantum(table, T).u_break
    bottom = {**table, "f_s": TABLE_1["f_s"] * (1.0 - SPREAD), "f_s_spread": 0.0,
              "ripple_phase": -0.5 * math.pi}
    return move_from_rest(bottom, T, u)


def _step(table: dict, e: float) -> float:
    """The largest excess (N) whose one-sample move stays within 1.5*abs(e) + q, with the
    breakaway anywhere in the band (the least over its bottom, middle and top)."""
    bound = 1.5 * abs(e) + COUNT
    steps = []
    for share in (-1.0, 0.0, 1.0):
        at = {**table, "f_s": TABLE_1["f_s"] * (1.0 + share * SPREAD), "f_s_spread": 0.0}
        u_break = table_quantum(at, T).u_break
        lo, _ = bisect_increasing(lambda x, at=at, u=u_break: move_from_rest(at, T, u + x),
                                  bound, 0.0, 200.0, tol=1e-3)
        steps.append(lo)
    return min(steps)


def staircase_runaways(v_s: float, tau_u: float, approaches: int) -> tuple[int, int]:
    """(approaches whose first seen move passes 1.5*abs(e) + q, approaches) from 1 um."""
    table = {**TABLE_1, "v_s": v_s, "tau_u": tau_u, "f_s_spread": SPREAD,
             "x_resolution": COUNT}
    bottom = {**table, "f_s": TABLE_1["f_s"] * (1.0 - SPREAD), "f_s_spread": 0.0}
    start = table_quantum(bottom, T).u_break
    top = table_quantum(table, T).u_break
    e0 = 1e-6
    delta = _step(table, e0)
    runaways = 0
    for seed in range(1, approaches + 1):
        plant = Plant({**table, "seed": seed})
        height = start
        read = plant.x_meas()
        for _ in range(PULSES_MAX):
            e = e0 - plant.x
            x_before = plant.x
            for k in range(WAIT + 1):
                if plant.step(height if k == 0 else 0.0, T) is not None:
                    raise ValueError("the plant refused a step")
            if plant.x_meas() != read:
                runaways += abs(plant.x - x_before) > 1.5 * abs(e) + COUNT
                break
            height = min(height + delta, top)
    return runaways, approaches


def main(argv: Sequence[str] | None = None) -> int:
    """Print the three parts of the study (see the module)."""
    from papwc.limits import whole_number

    parser = argparse.ArgumentParser(prog="python -m papwc_studies.bound_physics",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--approaches", type=whole_number(1, 100_000), default=400,
                        metavar="N", help="approaches per table in part 3 (default 400)")
    args = parser.parse_args(argv)
    print("1. excess over u_break (N) at which one sample moves one count (0.1 um):")
    for tau_u in TAU_U:
        cells = [f"v_s {v_s * 1e3:g} mm/s: {excess_for_one_count(v_s, tau_u):.3g}"
                 for v_s in V_S]
        print(f"   tau_u {tau_u * 1e3:g} ms: " + "; ".join(cells))
    moves = [(fresh_stick_move(v_s, tau_u, period), v_s, tau_u, period)
             for v_s in V_S for tau_u in TAU_U for period in RIPPLE_PERIODS]
    worst = max(moves)
    print(f"2. one sample sure to break away (band top, spread and ripple {SPREAD:.0%}) on a "
          f"fresh stick at the band's bottom: largest move {worst[0] * 1e6:.1f} um (v_s "
          f"{worst[1] * 1e3:g} mm/s, tau_u {worst[2] * 1e3:g} ms, ripple period "
          f"{worst[3] * 1e3:g} mm); least {min(moves)[0] * 1e6:.1f} um")
    print(f"3. the best staircase from 1 um, spread {SPREAD:.0%}: approaches whose first seen "
          "move passes 1.5*abs(e) + q")
    for tau_u in TAU_U:
        cells = []
        for v_s in V_S:
            n, of = staircase_runaways(v_s, tau_u, args.approaches)
            cells.append(f"v_s {v_s * 1e3:g} mm/s: {n}/{of} ({n / of:.1%})")
        print(f"   tau_u {tau_u * 1e3:g} ms: " + "; ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
