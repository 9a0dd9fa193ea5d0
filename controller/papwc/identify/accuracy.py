"""How well ``papwc identify`` recovers plants drawn in Table 1 +-50 %: ``python -m
papwc.identify.accuracy [--plants N] [--stribeck]``.

For each plant drawn (:func:`draws`), the default excitation (60 s at 100 Hz) is applied
through :class:`papwc.model.dynamics.Plant` with an ideal encoder and with a 0.1 um encoder
and 0.2 um noise, and identified; printed: the largest relative error of each parameter,
whether the true values lie inside the reported 95 % intervals, the replay's rms, the
deviations chosen and the time taken. The README's figures are this command's output.
"""

from __future__ import annotations

import argparse
import random
import sys
import time

from papwc.identify import DESIGN_DURATION, DESIGN_F_P_MAX, DESIGN_T, DESIGN_TRAVEL

__all__ = ["NOISY", "TABLE1", "draws", "main"]

#: Table 1 of the paper.
TABLE1 = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
#: The 0.1 um encoder with 0.2 um noise.
NOISY = {"x_resolution": 1e-7, "noise_std": 2e-7}


def draws(seed: int, n: int) -> list[dict[str, float]]:
    """``n`` plants with each of m, f_c, f_s, c uniform in Table 1 +-50 %, keeping those with
    f_s >= 1.1 f_c (a breakaway at least 10 % above the sliding friction; Table 1 has 30 %)."""
    rng = random.Random(seed)
    out: list[dict[str, float]] = []
    while len(out) < n:
        p = {k: v * rng.uniform(0.5, 1.5) for k, v in TABLE1.items()}
        if p["f_s"] >= 1.1 * p["f_c"]:
            out.append(p)
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the accuracy table; return 0."""
    from papwc.identify.excitation import apply_to_plant, design
    from papwc.identify.fit import identify

    parser = argparse.ArgumentParser(prog="python -m papwc.identify.accuracy",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--plants", type=int, default=10, help="plants drawn (default 10)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--stribeck", type=float, default=0.0, metavar="V_S",
                        help="give every plant a Stribeck curve of this v_s (m/s)")
    parser.add_argument("--deviations", default="stribeck,lag",
                        help="deviations tried (default stribeck,lag; none)")
    args = parser.parse_args(argv)
    tried = () if args.deviations == "none" else tuple(args.deviations.split(","))
    u = design(DESIGN_T, DESIGN_F_P_MAX, DESIGN_TRAVEL, DESIGN_DURATION)
    names = ["m", "f_c", "f_s", "c"] + (["v_s"] if args.stribeck > 0.0 else [])
    print("encoder  plant  " + "  ".join(f"{n:>9}" for n in names)
          + "  inside  replay_rms_m  chosen  seconds")
    for label, encoder in (("ideal", {}), ("0.1um+0.2um", NOISY)):
        worst = dict.fromkeys(names, 0.0)
        for i, plant in enumerate(draws(args.seed, args.plants)):
            truth = {**plant, **({"v_s": args.stribeck} if args.stribeck > 0.0 else {})}
            log = apply_to_plant(u, DESIGN_T, {**truth, **encoder, "seed": i})
            start = time.perf_counter()
            ident = identify(log, tried)
            seconds = time.perf_counter() - start
            est = {e.name: e for e in ident.estimates}
            errors = {n: (est[n].value / truth[n] - 1.0) if n in est else float("inf")
                      for n in names}
            inside = all(est[n].low <= truth[n] <= est[n].high for n in names if n in est)
            for n in names:
                worst[n] = max(worst[n], abs(errors[n]))
            print(f"{label:<8} {i:>5}  " + "  ".join(f"{errors[n]:>+9.2e}" for n in names)
                  + f"  {'yes' if inside else 'no':>6}  {ident.replay_rms:>12.3g}  "
                  + f"{','.join(ident.chosen) or 'none':>6}  {seconds:>7.1f}", flush=True)
        print(f"{label:<8} worst  " + "  ".join(f"{worst[n]:>9.2e}" for n in names), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
