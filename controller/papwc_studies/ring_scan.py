"""Whether the pulse controllers ever see ringing on rigid tables (they must not).

Runs PWC, PAPWC and the exact-model controller (the settings of scenarios/realism.toml)
in process, 3 iterations of 2 s toward 10 mm, 1 mm and 50 um, on

* the rigid cases of scenarios/realism.toml (Eq. (1), Stribeck, LuGre, ripple, random
  stiction and noise over five seeds, lag), and
* rigid tables drawn uniformly over the ranges of scenarios/realism_mc.toml and
  realism_mc_lugre.toml (``--draws`` of each),

and counts the runs after which a controller has seen ringing (``trust.ring``, see
:mod:`papwc.controllers.rest`). With none, every figure of those tables is what it was
before the ringing detection existed: the detection changes nothing until it fires.

    python -m papwc_studies.ring_scan [--draws 12]
"""

from __future__ import annotations

import argparse
import random
import sys

from papwc.controllers import make_controller
from papwc.controllers.settings import ControllerSettings
from papwc.master import Maneuver, PhysicsSlave
from papwc.master.closed_loop import run_closed_loop
from papwc.master.slave import ControllerSlave
from papwc.model.plant import plant_problems

__all__ = ["main", "realism_rigid", "mc_rigid", "ringing_runs"]

T = 0.01
TABLE_1 = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
#: The controllers of scenarios/realism.toml.
SETTINGS = {
    "pwc": {"kind": "pwc", "f_p_max": 300.0, "t_p_max": 0.03, "K_c": 0.5, "tolerance": 0.0,
            "m_est": 150.0, "f_c_est": 80.0, "F_inv0": 1e-5},
    "papwc": {"kind": "papwc", "f_p_max": 300.0, "t_p_max": 0.03, "K_c": 0.8,
              "tolerance": 2e-5, "m_est": 150.0, "f_c_est": 80.0, "delta_inv": 1e-5},
    "exact": {"kind": "exact", "f_p_max": 300.0, "tolerance": 1e-7, "m_est": 150.0,
              "f_c_est": 80.0},
}
TARGETS = (1e-2, 1e-3, 5e-5)


def realism_rigid() -> list[tuple[str, dict]]:
    """The rigid cases of scenarios/realism.toml, each seed of the seeded ones."""
    cases = {"exact": {}, "stribeck": {"v_s": 1e-3},
             "lugre": {"sigma_0": 6.5e7, "sigma_1": 2e5, "v_s": 1e-3},
             "ripple": {"ripple": 0.1, "ripple_period": 1e-3}, "lag": {"tau_u": 2e-3}}
    out = [(name, {**TABLE_1, **extra}) for name, extra in cases.items()]
    for seed in range(1, 6):
        out.append((f"stiction-{seed}", {**TABLE_1, "f_s_spread": 0.1, "seed": seed}))
        out.append((f"noise-{seed}", {**TABLE_1, "noise_std": 2e-7, "x_resolution": 1e-7,
                                      "seed": seed}))
    return out


def mc_rigid(draws: int, seed: int = 7) -> list[tuple[str, dict]]:
    """Rigid tables drawn over the ranges of realism_mc.toml and realism_mc_lugre.toml."""
    rng = random.Random(seed)
    out = []
    for k in range(draws):
        for lugre in (False, True):
            p = {**TABLE_1, "x_resolution": 1e-7, "v_s": rng.uniform(2e-4, 5e-3),
                 "ripple": rng.uniform(0.0, 0.15), "ripple_period": rng.uniform(5e-4, 5e-3),
                 "tau_u": rng.uniform(1e-6, 5e-3), "noise_std": rng.uniform(0.0, 4e-7),
                 "seed": k}
            if lugre:
                p["sigma_0"] = rng.uniform(2e7, 2e8)
                p["sigma_1"] = rng.uniform(1e-3, 1e-2) * p["sigma_0"]
            else:
                p["f_s_spread"] = rng.uniform(1e-9, 0.15)
            out.append((f"{'mc_lugre' if lugre else 'mc'}-{k}", p))
    return out


def ringing_runs(tables: list[tuple[str, dict]]) -> tuple[int, list[str]]:
    """Runs made, and those after which the controller had seen ringing."""
    runs, seen = 0, []
    for name, params in tables:
        if plant_problems(params):
            raise ValueError(f"{name}: {plant_problems(params)}")
        for x_ref in TARGETS:
            for kind, values in SETTINGS.items():
                if kind == "exact" and "x_resolution" in params:
                    values = {**values, "x_resolution": params["x_resolution"]}
                settings = ControllerSettings.from_mapping(values)
                controller = make_controller(settings, T)
                plant = PhysicsSlave()
                plant.set_start_values(params)
                maneuver = Maneuver(x_ref=x_ref, T=T, duration=2.0, iterations=3)
                run_closed_loop(plant, ControllerSlave(controller), maneuver, settings, kind)
                runs += 1
                if controller.trust.ring or controller.rest.ring_dwell:
                    seen.append(f"{name} {kind} x_ref={x_ref!r}")
    return runs, seen


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papwc_studies.ring_scan",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=12, choices=range(0, 1001),
                        metavar="N", help="Monte Carlo draws of each file (0-1000)")
    args = parser.parse_args(argv)
    for label, tables in (("realism.toml rigid cases", realism_rigid()),
                          ("Monte Carlo rigid draws", mc_rigid(args.draws))):
        runs, seen = ringing_runs(tables)
        print(f"{label}: {runs} runs, ringing seen in {len(seen)}")
        for line in seen:
            print(f"  {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
