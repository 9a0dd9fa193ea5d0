"""
Identifying a machine from a log
================================

``papwc identify`` fits FrictionPlant's ``m``, ``f_c``, ``f_s`` and ``c`` (and the Stribeck
curve or an actuator lag where the data support them) to a log of force and position. Here the
"machine" is FrictionPlant.fmu with parameters the identification is not told, read through a
0.1 µm encoder with 0.2 µm of noise: ``papwc identify --fmu`` applies its excitation to it and
writes the log, ``log.csv``, as a machine's data logger would (40 s instead of the default 60 s,
to stay small). Then the log alone is identified, as one from a real machine would be:

.. code-block:: bash

    papwc identify --fmu FrictionPlant.fmu --duration 40 --deviations none --out machine \\
        --start-values m=120,f_c=80,f_s=110,c=500,x_resolution=1e-7,noise_std=2e-7
    papwc identify machine/log.csv --deviations none --out fit
"""

import csv
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from papwc.cli import main as papwc
from papwc.fmubuild.fmus import build_fmu

TRUE = {"m": 120.0, "f_c": 80.0, "f_s": 110.0, "c": 500.0}
workdir = tempfile.TemporaryDirectory(prefix="papwc_identify_")
tmp = Path(workdir.name)
fmu = build_fmu("FrictionPlant", tmp)
start = ",".join(f"{k}={v}" for k, v in TRUE.items()) + ",x_resolution=1e-7,noise_std=2e-7"

# %%
# The machine's log, made by ``papwc identify --fmu`` (it identifies the FMU too; here only its
# ``log.csv`` is used; ``--deviations none`` keeps that fit short).
assert papwc(["identify", "--fmu", str(fmu), "--start-values", start, "--duration", "40",
              "--deviations", "none", "--out", str(tmp / "machine")]) == 0
log = tmp / "machine" / "log.csv"
with open(log, newline="") as f:
    rows = list(csv.reader(f))
print(f"{log.name}: {len(rows) - 1} rows, columns {rows[0]}")
for row in rows[1:4]:
    print("   ", ", ".join(row))

# %%
# The log identified as a machine's would be (Eq. (1) alone: ``--deviations none``).
assert papwc(["identify", str(log), "--deviations", "none", "--out", str(tmp / "fit")]) == 0
with open(tmp / "fit" / "identified.csv", newline="") as f:
    identified = {r["parameter"]: r for r in csv.DictReader(f)}
print(f"{'parameter':10s} {'true':>8s} {'estimate':>12s} {'95 % interval':>26s}")
for name, true in TRUE.items():
    r = identified[name]
    low, high, est = float(r["ci_low"]), float(r["ci_high"]), float(r["estimate"])
    print(f"{name:10s} {true:8.1f} {est:12.4f} [{low:11.4f}, {high:11.4f}] {r['unit']}")
    assert abs(est - true) <= 0.03 * true, (name, est, true)
print((tmp / "fit" / "plant.toml").read_text().split("[maneuver]")[0])

# %%
# The first seconds of the log: the staircase of one-sample pulses that brackets f_s, and the
# table's position as the encoder read it.
t = [float(r[0]) for r in rows[1:]]
u = [float(r[1]) for r in rows[1:]]
x = [float(r[2]) for r in rows[1:]]
n = sum(1 for v in t if v <= 8.0)
fig, (ax_u, ax_x) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
ax_u.step(t[:n], u[:n], where="post", lw=0.8)
ax_x.plot(t[:n], [1e3 * v for v in x[:n]], lw=0.8)
ax_u.set_ylabel("force u (N)")
ax_x.set_ylabel("position x_meas (mm)")
ax_x.set_xlabel("time t (s)")
for ax in (ax_u, ax_x):
    ax.grid(True, alpha=0.3)
fig.tight_layout()
workdir.cleanup()
