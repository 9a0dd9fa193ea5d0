"""
A small battery and its plots
=============================

A battery file is a scenario file with tables that vary it: ``[cases]`` (named sets of
overrides), ``[sweep]`` (a grid) and ``[monte_carlo]`` (draws). Here: PAPWC and the exact-model
controller on the paper's plant, with and without a Stribeck curve, over 8 plants drawn with
m, f_c and c ±30 % and the estimates 20 % off, two iterations each; 16 runs. The battery is
written into a temporary folder and run as

.. code-block:: bash

    papwc battery small.toml --workers 1 --out results/small

with the plant FMU built from the sources. It writes ``results.csv`` (a row per run, controller
and iteration), ``summary.md`` and ``spec.csv`` (per case and controller), ``pulses.csv`` and a
plot of the final errors; the figure below is drawn from ``results.csv``.
"""

import csv
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from papwc.fmubuild.fmus import build_fmu

BATTERY = """
name = "small"
[plant]
m = 150.0
f_c = 100.0
f_s = 130.0
c = 700.0
[maneuver]
x_ref = 0.01
iterations = 2
[[controller]]
kind = "papwc"
label = "papwc"
t_p_max = 0.03
K_c = 0.8
tolerance = 2e-5
[[controller]]
kind = "exact"
label = "exact"
tolerance = 1e-7
[cases]
ideal = {}
stribeck = { "plant.v_s" = 1e-3 }
[monte_carlo]
n = 8
seed = 3
"plant.m" = { dist = "uniform", rel = 0.3 }
"plant.f_c" = { dist = "uniform", rel = 0.3 }
"plant.c" = { dist = "uniform", rel = 0.3 }
"plant.f_s" = { dist = "uniform", low = 1.1, high = 1.5, of = "plant.f_c" }
"controller.m_est" = { dist = "uniform", low = 0.8, high = 1.2, of = "plant.m" }
"controller.f_c_est" = { dist = "uniform", low = 0.8, high = 1.2, of = "plant.f_c" }
"""

workdir = tempfile.TemporaryDirectory(prefix="papwc_battery_")
tmp = Path(workdir.name)
(tmp / "small.toml").write_text(BATTERY)
fmu = build_fmu("FrictionPlant", tmp / "fmu")
# ``papwc battery`` in a process of its own (its workers are processes too).
subprocess.run([sys.executable, "-m", "papwc.cli", "battery", str(tmp / "small.toml"),
                "--workers", "1", "--fmu", str(fmu), "--quiet", "--out", str(tmp / "small")],
               check=True)
print("written:", ", ".join(sorted(p.name for p in (tmp / "small").iterdir())))

# %%
# ``spec.csv``: per case and controller, the spec's figures over the runs.
with open(tmp / "small" / "spec.csv", newline="") as f:
    spec = list(csv.DictReader(f))
columns = ["case", "controller", "runs", "within_1um", "settle_median_s", "pulses_far",
           "runaway_far", "farther", "false_settled"]
print(" | ".join(columns))
for row in spec:
    print(" | ".join(row[c] for c in columns))

# %%
# The final error of each run's last iteration, per case and controller.
with open(tmp / "small" / "results.csv", newline="") as f:
    rows = [r for r in csv.DictReader(f) if r["iteration"] == "2"]
groups = sorted({(r["case"], r["controller"]) for r in rows})
fig, ax = plt.subplots(figsize=(7, 4))
for i, (case, controller) in enumerate(groups):
    errors = [abs(float(r["final_error_m"])) for r in rows
              if (r["case"], r["controller"]) == (case, controller)]
    errors = [max(e, 1e-16) for e in errors if not math.isnan(e)]
    ax.plot([i] * len(errors), errors, "o", alpha=0.6)
ax.set_xticks(range(len(groups)), [f"{case}\n{controller}" for case, controller in groups])
ax.set_yscale("log")
ax.set_ylabel("abs(final error), iteration 2 (m)")
ax.axhline(2e-5, color="C0", lw=0.8, ls="--", label="PAPWC tolerance 2e-5 m")
ax.axhline(1e-7, color="C1", lw=0.8, ls="--", label="exact tolerance 1e-7 m")
ax.grid(True, axis="y", alpha=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
workdir.cleanup()
