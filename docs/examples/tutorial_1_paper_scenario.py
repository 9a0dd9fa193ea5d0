"""
The paper's scenario from Python
================================

``papwc run scenarios/paper.toml`` from Python: read the scenario file, run each of its
controllers on the in-process plant (:class:`papwc.master.PhysicsSlave`, the same model as
FrictionPlant.fmu, bit for bit) and plot the error of the adaptive PWC and PAPWC in the first
and the last of the ten iterations, as the paper's Figures 3 and 4 do.
"""

import math

import matplotlib.pyplot as plt

from papwc.resources import scenario_file
from papwc.results.summary import summarize
from papwc.scenario import load_scenario
from papwc.scenario_run import run_scenario

scenario = load_scenario(scenario_file("paper.toml"))
print(f"{scenario.name}: plant", {k: scenario.plant[k] for k in ("m", "f_c", "f_s", "c")})
print(f"maneuver: x_ref = {scenario.maneuver.x_ref} m, T = {scenario.maneuver.T} s, "
      f"{scenario.maneuver.iterations} iterations of {scenario.maneuver.duration} s")
print("controllers:", ", ".join(scenario.labels))

# %%
# Every controller of the file on the in-process plant (``papwc run --plant physics``).
results = run_scenario(scenario, plant="physics")
for result in results:
    last = summarize(result.traces[-1], result.settings.tolerance)
    print(f"{result.label:22s} iteration {len(result.traces)}: final error "
          f"{last['final_error_m']:+.3e} m, {last['pulses']} pulses, {last['outcome']}")

# %%
# The error e = x_ref - x of the pulse controllers, first and last iteration.
fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5.5))
for result in results:
    if not result.label.startswith(("pwc", "papwc")):
        continue
    for ax, trace in zip(axes, (result.traces[0], result.traces[-1]), strict=True):
        ax.plot(trace.column("t"), [1e3 * e for e in trace.column("e")], label=result.label)
for ax, number in zip(axes, (1, scenario.maneuver.iterations), strict=True):
    ax.set_title(f"iteration {number}")
    ax.set_ylabel("error e (mm)")
    ax.grid(True, alpha=0.3)
axes[0].legend(fontsize=8)
axes[1].set_xlabel("time t (s)")
axes[1].set_ylim(-0.5, 10.5)
fig.tight_layout()
assert all(not math.isnan(summarize(r.traces[-1], 0.0)["final_error_m"]) for r in results)
