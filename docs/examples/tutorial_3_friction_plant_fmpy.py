"""
FrictionPlant.fmu with fmpy, against its reference result
=========================================================

FrictionPlant.fmu is an ordinary FMI 2.0 Co-Simulation FMU: any host runs it. Here it is
built into a temporary folder (:func:`papwc.fmubuild.fmus.build_fmu`: the native plant in C,
compiled by zig) and simulated with fmpy through the reference input of its folder,
``fmu_src/FrictionPlant/FrictionPlant_in.csv`` (a 300 N pulse of 0.05 s), with the settings of
``FrictionPlant_ref.opt`` (the FMI cross-check layout). The result is held against
``FrictionPlant_ref.csv``, the exact solution of Eq. (1) that
``python -m papwc.fmubuild.reference`` writes from the model layer.
"""

import csv
import tempfile
from pathlib import Path

import fmpy
import matplotlib.pyplot as plt
import numpy as np

from papwc.fmubuild.fmus import build_fmu
from papwc.resources import fmu_src_dir

folder = fmu_src_dir() / "FrictionPlant"
lines = (folder / "FrictionPlant_ref.opt").read_text().splitlines()
options = dict(line.split(", ") for line in lines if line)
print("FrictionPlant_ref.opt:", options)

with tempfile.TemporaryDirectory() as tmp:
    fmu = build_fmu("FrictionPlant", Path(tmp))
    print("built", fmu.name, f"({fmu.stat().st_size // 1024} kB)")
    description = fmpy.read_model_description(str(fmu))
    print(description.coSimulation.modelIdentifier, "variables:",
          ", ".join(f"{v.name} ({v.causality})" for v in description.modelVariables))
    signal = fmpy.read_csv(str(folder / "FrictionPlant_in.csv"))
    result = fmpy.simulate_fmu(str(fmu), start_time=float(options["StartTime"]),
                               stop_time=float(options["StopTime"]),
                               output_interval=float(options["StepSize"]), input=signal,
                               output=["x", "v", "stuck"])

# %%
# The reference result, and the largest difference in x and v (the FMU's step is exact).
with open(folder / "FrictionPlant_ref.csv", newline="") as f:
    rows = list(csv.DictReader(f))
ref_t = np.array([float(r["time"]) for r in rows])
ref_x = np.array([float(r["x"]) for r in rows])
ref_v = np.array([float(r["v"]) for r in rows])
assert np.allclose(result["time"], ref_t, rtol=0.0, atol=1e-9)
dx = np.max(np.abs(result["x"] - ref_x))
dv = np.max(np.abs(result["v"] - ref_v))
print(f"max |x - x_ref| = {dx:.3g} m, max |v - v_ref| = {dv:.3g} m/s over {len(ref_t)} rows")
assert dx <= 1e-12 and dv <= 1e-12

# %%
# The pulse: the mass slides, decelerates under Coulomb and viscous friction and sticks.
fig, (ax_x, ax_v) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
ax_x.plot(result["time"], 1e3 * result["x"], label="FrictionPlant.fmu (fmpy)")
ax_x.plot(ref_t, 1e3 * ref_x, "k.", ms=3, label="FrictionPlant_ref.csv")
ax_v.plot(result["time"], result["v"], label="FrictionPlant.fmu (fmpy)")
ax_v.plot(ref_t, ref_v, "k.", ms=3, label="FrictionPlant_ref.csv")
ax_x.set_ylabel("position x (mm)")
ax_v.set_ylabel("velocity v (m/s)")
ax_v.set_xlabel("time t (s)")
for ax in (ax_x, ax_v):
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
ax_v.set_xlim(0, 0.3)
fig.tight_layout()
