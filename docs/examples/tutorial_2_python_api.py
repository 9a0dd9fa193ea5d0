"""
A controller on the in-process plant: the Python API
====================================================

The parts the commands are made of, used directly: a plant
(:class:`papwc.master.PhysicsSlave`, FrictionPlant's model in this process), the settings of
one controller (:class:`papwc.controllers.settings.ControllerSettings`, the fields of a
``[[controller]]`` table), a maneuver (:class:`papwc.master.Maneuver`) and
:func:`papwc.master.run_controller`, which closes the loop over the iterations and returns a
trace per iteration.

Here the exact-model controller moves the Table 1 plant, with a Stribeck curve and an actuator
lag it is not told about, 1 mm from rest, three times; what it learns carries over.
"""

import matplotlib.pyplot as plt

from papwc.controllers.settings import ControllerSettings
from papwc.master import Maneuver, PhysicsSlave, run_controller

plant = PhysicsSlave()
plant.set_start_values({"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0,
                        "v_s": 1e-3, "tau_u": 2e-3})
settings = ControllerSettings(kind="exact", tolerance=1e-7)
assert settings.problems() == []  # every setting within its range
maneuver = Maneuver(x_ref=1e-3, T=0.01, duration=2.0, iterations=3)

result = run_controller(plant, settings, maneuver, label="exact")
assert not result.error, result.error

# %%
# Each iteration is a :class:`papwc.master.Trace`: named columns, one value per sample.
for number, trace in enumerate(result.traces, start=1):
    print(f"iteration {number}: final error {maneuver.x_ref - trace.column('x')[-1]:+.2e} m, "
          f"{int(trace.column('pulses')[-1])} pulses")
print("columns:", ", ".join(result.traces[0].columns))

# %%
# Position and force of the first and last iteration: the coarse move, then pulses.
fig, (ax_x, ax_u) = plt.subplots(2, 1, sharex=True, figsize=(7, 5.5))
for number in (1, len(result.traces)):
    trace = result.traces[number - 1]
    t = trace.column("t")
    ax_x.plot(t, [1e3 * x for x in trace.column("x")], label=f"iteration {number}")
    ax_u.step(t, trace.column("u"), where="post", label=f"iteration {number}")
ax_x.axhline(1e3 * maneuver.x_ref, color="k", lw=0.8, ls="--")
ax_x.set_ylabel("position x (mm)")
ax_u.set_ylabel("force u (N)")
ax_u.set_xlabel("time t (s)")
for ax in (ax_x, ax_u):
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
ax_u.set_xlim(0, 1.0)
fig.tight_layout()
