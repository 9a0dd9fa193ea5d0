"""
The closed loop in libcosim and ecos
====================================

``papwc build`` writes ``ClosedLoop.ssp``: FrictionPlant.fmu under PulseController.fmu,
connected ``plant.x_meas -> controller.x_meas`` and ``controller.u -> plant.u``, with the
bindings of ``scenarios/paper.toml``'s PAPWC (t_p,max = 0.03 s) in one parameter set named
``scenario``. Here the FMUs and the SSP are built into a temporary folder
(:mod:`papwc.fmubuild`), the loop runs in libcosim (pip ``libcosimpy``) and in ecos's library
(pip ``ecospy``, which needs Debian's ``libtbb12``), and both are held against papwc's own
master running the same archive (``papwc cosim``). A host that is not installed is skipped,
with a line saying so: this documentation may be built without them (they come with the
``test`` extra).
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from papwc.fmubuild.fmus import build_fmu
from papwc.fmubuild.ssp_writer import build_closed_loop_ssp
from papwc.master.ssd import read_ssp
from papwc.master.ssp_runner import run_ssp
from papwc.resources import scenario_file

workdir = tempfile.TemporaryDirectory(prefix="papwc_ssp_")
tmp = Path(workdir.name)
plant = build_fmu("FrictionPlant", tmp)
controller = build_fmu("PulseController", tmp)
ssp = build_closed_loop_ssp(tmp, scenario_file("paper.toml"), plant, controller)
print("built", ssp.name, "with", plant.name, "and", controller.name)
STEPS = 200  # 2 s at 0.01 s

# %%
# papwc's master (``papwc cosim build/ClosedLoop.ssp``): the reference.
run = run_ssp(read_ssp(ssp), ["plant.x", "controller.u"])
assert not run.error, run.error
master_x = [row[1] for row in run.rows]
print(f"papwc cosim: x(2 s) = {master_x[-1]:.9f} m")
traces = {"papwc cosim": master_x}


def largest_difference(xs: list[float], reference: list[float]) -> float:
    """The largest difference between two runs' positions, m."""
    return max(abs(a - b) for a, b in zip(xs, reference, strict=True))

# %%
# libcosim, through libcosimpy (step 0.01 s from the SSP's OSP annotation).
try:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
except ImportError as exc:
    print(f"libcosim skipped: libcosimpy is not installed ({exc})")
else:
    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_ssp_file(str(ssp))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    index = execution.slave_index_from_instance_name("plant")
    ref = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    xs = [0.0]
    for _ in range(STEPS):
        assert execution.step()
        xs.append(observer.last_real_values(index, [ref["x"]])[0])
    traces["libcosim"] = xs
    print(f"libcosim:    x(2 s) = {xs[-1]:.9f} m, "
          f"max |x - x_master| = {largest_difference(xs, master_x):.2g} m")

# %%
# ecos's library, through ecospy.
try:
    from ecospy import EcosSimulation
except (ImportError, OSError) as exc:  # OSError: Debian's libtbb12 is missing
    print(f"ecos skipped: ecospy cannot be loaded ({exc})")
else:
    sim = EcosSimulation(ssp_path=str(ssp), step_size=0.01)
    sim.init(parameter_set="scenario")
    xs = [sim.get_real("plant::x")]
    for _ in range(STEPS):
        sim.step()
        xs.append(sim.get_real("plant::x"))
    sim.terminate()
    traces["ecos"] = xs
    print(f"ecos:        x(2 s) = {xs[-1]:.9f} m, "
          f"max |x - x_master| = {largest_difference(xs, master_x):.2g} m")

# %%
# The position in each host (they lie on each other).
fig, ax = plt.subplots(figsize=(7, 4))
for (name, xs), style in zip(traces.items(), ("-", "--", ":"), strict=False):
    ax.plot([0.01 * k for k in range(len(xs))], [1e3 * x for x in xs], style, label=name)
ax.axhline(10.0, color="k", lw=0.8, ls="--")
ax.set_xlabel("time t (s)")
ax.set_ylabel("position x (mm)")
ax.set_title("ClosedLoop.ssp: PAPWC, t_p,max = 0.03 s, first iteration")
ax.grid(True, alpha=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
workdir.cleanup()
