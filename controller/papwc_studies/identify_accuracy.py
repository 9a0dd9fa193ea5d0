"""How well ``papwc identify`` recovers plants (``python -m papwc_studies.identify_accuracy``).

Two studies, each on plants drawn with a seed of its own, the default excitation (60 s at
100 Hz, :func:`papwc.identify.excitation.design`) applied and identified:

* ``--plants N`` (Table 1 +-50 %): each of m, f_c, f_s, c uniform in Table 1 +-50 %
  (:func:`draws`), through an ideal encoder and a 0.1 um encoder with 0.2 um noise;
  printed: the largest relative error of each parameter, whether the true values lie inside
  the reported 95 % intervals, the replay's rms, the deviations chosen, the time taken.
* ``--realism N``: tables drawn from the ranges of ``scenarios/realism_mc.toml``'s
  ``[monte_carlo]`` table (its plant, Table 1, with a Stribeck curve, a friction ripple of
  a drawn phase, random stiction and an actuator lag, each drawn) through the 0.1 um encoder
  with 0.2 um noise (:func:`realism_tables`); printed per table: the errors of v_s and of the
  ripple's amplitude and wavelength, whether the stiction band it reports holds the table's
  next :data:`papwc.identify.band.NEXT_DRAWS` draws of random stiction (those after the
  excitation's), the processor time; and a summary: on the tables whose ripple is at least
  ``--ripple-min``, the share with v_s and the ripple's amplitude each within 20 %, and on
  every table the share whose band holds the next draws.

The documentation's figures (docs/studies/identification-accuracy.md) are this command's
output.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
import time
from collections.abc import Sequence
from multiprocessing import Pool

from papwc.identify import DESIGN_DURATION, DESIGN_F_P_MAX, DESIGN_T, DESIGN_TRAVEL

__all__ = ["NOISY", "TABLE1", "TOLERANCE", "draws", "main", "realism_row", "realism_tables"]

#: Table 1 of the paper.
TABLE1 = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
#: The 0.1 um encoder with 0.2 um noise.
NOISY = {"x_resolution": 1e-7, "noise_std": 2e-7}
#: The relative error within which v_s and the ripple's amplitude must be recovered.
TOLERANCE = 0.2
#: The Monte Carlo file whose ranges ``--realism`` draws from.
REALISM_FILE = "realism_mc.toml"


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


def realism_tables(seed: int, n: int) -> list[dict[str, float]]:
    """``n`` tables drawn from the ranges of ``scenarios/realism_mc.toml``'s ``[monte_carlo]``
    plant fields (its ``[plant]`` table the nominal), the ripple's phase uniform in
    [-pi, pi), through the 0.1 um encoder with 0.2 um noise; each with its own ``seed``."""
    from papwc.battery.schema import load_battery
    from papwc.resources import scenario_file

    battery = load_battery(scenario_file(REALISM_FILE))
    nominal = dict(battery.data["plant"])
    rng = random.Random(f"papwc-identify-accuracy:{seed}")
    out = []
    for i in range(n):
        table = dict(nominal)
        for dist in battery.draws:
            head, name = dist.path.split(".", 1)
            if head != "plant" or name in NOISY or dist.of is not None:
                continue
            table[name] = dist.value(rng.random(), nominal.get(name), None)
        table["ripple_phase"] = rng.uniform(-math.pi, math.pi)
        table.update(NOISY)
        table["seed"] = 1000 * seed + i
        out.append(table)
    return out


def realism_row(table: dict[str, float]) -> dict[str, float]:
    """Identify one table of :func:`realism_tables`; its row of the study (see the module)."""
    import numpy as np

    from papwc.identify.band import NEXT_DRAWS
    from papwc.identify.excitation import design
    from papwc.identify.fit import identify
    from papwc.identify.log_file import Columns, Log
    from papwc.identify.simulate import plant_maker
    from papwc.master.native_plant import own_plant_library
    from papwc.model.effects.stiction import RandomStiction

    u = design(DESIGN_T, DESIGN_F_P_MAX, DESIGN_TRAVEL, DESIGN_DURATION)
    plant = plant_maker(own_plant_library())(table)
    x = [plant.x_meas()]
    for force in u:
        plant.step(float(force), DESIGN_T)
        x.append(plant.x_meas())
    log = Log(np.arange(len(x)) * DESIGN_T, np.append(u, 0.0), np.array(x), None, DESIGN_T,
              "the table", Columns(position="x"))
    began = time.process_time()
    ident = identify(log)
    cpu = time.process_time() - began
    found = ident.plant
    stiction = RandomStiction(table["f_s"], table["f_s_spread"], int(table["seed"]))
    drawn = int(plant.state()["stick_draws"])
    following = [stiction.draw(k) for k in range(drawn, drawn + NEXT_DRAWS)]
    band = ident.band
    holds = band is not None and all(band.low <= f <= band.high for f in following)

    def error(name: str) -> float:
        return float(found.get(name, 0.0)) / table[name] - 1.0 if table[name] else math.nan

    return {"ripple": table["ripple"], "ripple_period": table["ripple_period"],
            "v_s": table["v_s"], "tau_u": table["tau_u"], "f_s_spread": table["f_s_spread"],
            "v_s_error": error("v_s"), "ripple_error": error("ripple"),
            "period_error": error("ripple_period"), "tau_u_error": error("tau_u"),
            "band_low": band.low if band else math.nan,
            "band_high": band.high if band else math.nan,
            "draws_low": min(following), "draws_high": max(following),
            "band_holds": holds, "sticks": band.sticks if band else 0,
            "chosen": ",".join(ident.chosen) or "none", "cpu_s": cpu}


def _realism(seed: int, n: int, ripple_min: float, workers: int) -> None:
    tables = realism_tables(seed, n)
    print("table  ripple  period_mm  v_s_mm/s  spread  v_s_err  ripple_err  period_err  "
          "band_low  band_high  next_low  next_high  holds  chosen  cpu_s", flush=True)
    rows = []
    with Pool(workers) as pool:
        for i, row in enumerate(pool.imap(realism_row, tables)):
            rows.append(row)
            print(f"{i:>5}  {row['ripple']:6.3f}  {row['ripple_period'] * 1e3:9.3f}  "
                  f"{row['v_s'] * 1e3:8.3f}  {row['f_s_spread']:6.3f}  {row['v_s_error']:+7.3f}  "
                  f"{row['ripple_error']:+10.3f}  {row['period_error']:+10.4f}  "
                  f"{row['band_low']:8.2f}  {row['band_high']:9.2f}  {row['draws_low']:8.2f}  "
                  f"{row['draws_high']:9.2f}  {'yes' if row['band_holds'] else 'NO':>5}  "
                  f"{row['chosen']}  {row['cpu_s']:5.1f}", flush=True)
    rippled = [r for r in rows if r["ripple"] >= ripple_min]
    both = [r for r in rippled if abs(r["v_s_error"]) <= TOLERANCE
            and abs(r["ripple_error"]) <= TOLERANCE]
    v_s_ok = [r for r in rippled if abs(r["v_s_error"]) <= TOLERANCE]
    ripple_ok = [r for r in rippled if abs(r["ripple_error"]) <= TOLERANCE]
    holds = [r for r in rows if r["band_holds"]]
    cpu = sorted(r["cpu_s"] for r in rows)
    print(f"seed {seed}: {len(rows)} tables; with ripple >= {ripple_min:g}: {len(rippled)}; of "
          f"those v_s within {TOLERANCE:.0%}: {len(v_s_ok)}, the ripple's amplitude within "
          f"{TOLERANCE:.0%}: {len(ripple_ok)}, both: {len(both)} "
          f"({len(both) / max(len(rippled), 1):.0%})")
    print(f"seed {seed}: the band holds the next draws on {len(holds)} of {len(rows)} tables "
          f"({len(holds) / max(len(rows), 1):.0%}); processor time per table: median "
          f"{cpu[len(cpu) // 2]:.1f} s, largest {cpu[-1]:.1f} s")


def _table1(args: argparse.Namespace, tried: Sequence[str]) -> None:
    from papwc.identify.excitation import apply_to_plant, design
    from papwc.identify.fit import identify

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


def main(argv: list[str] | None = None) -> int:
    """Print the accuracy tables; return 0."""
    parser = argparse.ArgumentParser(prog="python -m papwc_studies.identify_accuracy",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--plants", type=int, default=10,
                        help="plants drawn in Table 1 +-50 %% (default 10; 0: none)")
    parser.add_argument("--realism", type=int, default=0, metavar="N",
                        help=f"tables drawn from {REALISM_FILE}'s ranges (default 0: none)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--stribeck", type=float, default=0.0, metavar="V_S",
                        help="give every Table 1 +-50 %% plant a Stribeck curve of this v_s "
                             "(m/s)")
    parser.add_argument("--deviations", default="stribeck,lag,ripple",
                        help="deviations tried on the Table 1 +-50 %% plants (default "
                             "stribeck,lag,ripple; none)")
    parser.add_argument("--ripple-min", type=float, default=0.01, metavar="A",
                        help="the summary's tables with ripple: amplitude at least this "
                             "(default 0.01)")
    parser.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    args = parser.parse_args(argv)
    tried = () if args.deviations == "none" else tuple(args.deviations.split(","))
    if args.plants > 0 and not args.realism:
        _table1(args, tried)
    if args.realism > 0:
        _realism(args.seed, args.realism, args.ripple_min, max(args.workers, 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
