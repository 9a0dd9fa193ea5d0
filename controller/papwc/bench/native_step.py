"""``papwc bench`` section: the native FrictionPlant.fmu against the pythonfmu one.

One communication step (setReal + doStep + getReal through fmpy's FMU2Slave) of each,
interleaved in the same run, at the default parameters and with a deviation (Stribeck
curve; flexible drive), as ratios: native / pythonfmu. The pythonfmu FMU is
``pythonfmu/FrictionPlant.fmu`` in the bench's FMU folder (``papwc bench`` builds it;
with ``--fmu-dir`` it is built there by ``papwc build --backend pythonfmu --out
DIR/pythonfmu``).
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from papwc.bench import BenchContext, Row, gc_paused, median_interleaved, register_section
from papwc.bench.plant_calls import plant_forces, slave_methods_loop

#: The pythonfmu FrictionPlant, relative to the bench's FMU folder.
PYTHONFMU_PLANT = "pythonfmu/FrictionPlant.fmu"

#: case -> (plant parameters, goal: native cost / pythonfmu cost at most).
CASES: dict[str, tuple[dict[str, float], float]] = {
    "defaults": ({}, 1 / 2),
    "Stribeck (v_s = 0.01 m/s)": ({"v_s": 0.01}, 1 / 20),
    "flexible (m_d = 30 kg, k_t = 2e6 N/m, c_t = 300 N.s/m)": (
        {"m_d": 30.0, "k_t": 2e6, "c_t": 300.0}, 1 / 50),
}


def step_loop(fmu_path: Path, unzip_root: Path, params: dict[str, float], arrays: bool = False
              ) -> tuple[Callable[[list[float]], float], Callable[[], None]]:
    """An instance with ``params``; return (loop(forces) -> s per step, close()).

    ``arrays=False``: FMU2Slave's methods (``setReal(vrs, values)``, ...), as a script
    calls them; ``arrays=True``: the fmi2 functions of the library fmpy loaded, as bare
    function pointers with ctypes arguments made once, as papwc's master calls them
    (:class:`papwc.master.FmuSlave`).
    """
    import ctypes

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu_path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    folder = unzip_root / f"{fmu_path.parent.name}_{len(list(unzip_root.iterdir()))}"
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu_path), str(folder)),
                      modelIdentifier="FrictionPlant", instanceName="bench")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    for name, value in params.items():
        slave.setReal([vr[name]], [value])
    slave.exitInitializationMode()
    vr_in, vr_out = [vr["u"]], [vr["x"]]
    clock = {"k": 0}
    h = 0.01

    def loop_arrays(forces: list[float]) -> float:
        c = ctypes.c_void_p(slave.component)
        bare = ctypes.CFUNCTYPE(ctypes.c_int)  # no argtypes: the ctypes objects pass as they are
        set_real, do_step, get_real = (
            bare(ctypes.cast(getattr(slave.dll, name), ctypes.c_void_p).value)
            for name in ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal"))
        vr_u, vr_x = (ctypes.c_uint * 1)(*vr_in), (ctypes.c_uint * 1)(*vr_out)
        u_buf, x_buf, one = (ctypes.c_double * 1)(), (ctypes.c_double * 1)(), ctypes.c_size_t(1)
        t_c, h_c = ctypes.c_double(0.0), ctypes.c_double(h)
        k0 = clock["k"]
        with gc_paused():
            start = time.perf_counter_ns()
            for i, u in enumerate(forces):
                u_buf[0] = u
                t_c.value = (k0 + i) * h
                if set_real(c, vr_u, one, u_buf) or do_step(c, t_c, h_c, 1) or get_real(
                        c, vr_x, one, x_buf):
                    raise RuntimeError(f"bench: {fmu_path} refused a step")
            elapsed = time.perf_counter_ns() - start
        clock["k"] = k0 + len(forces)
        return elapsed * 1e-9 / len(forces)

    loop, close = slave_methods_loop(slave, vr_in, vr_out, clock, h)
    return (loop_arrays if arrays else loop), close


@register_section("FrictionPlant.fmu native / pythonfmu: one setReal + doStep + getReal (fmpy)")
def native_against_pythonfmu(context: BenchContext) -> list[Row]:
    """Cost per step of the native and the pythonfmu plant, interleaved; ratios and goals."""
    rows = []
    verdicts = []
    modes = {"FMU2Slave methods": False, "ctypes arrays, as the master": True}
    with tempfile.TemporaryDirectory(prefix="papwcbench") as tmp:
        for (case, (params, goal)), (mode, arrays) in (
                (c, m) for c in CASES.items() for m in modes.items()):
            n_steps, rounds = (2_000, 7) if not params else (300, 5)
            if context.quick:
                n_steps, rounds = max(50, n_steps // 10), 3
            forces = plant_forces(n_steps)
            native, close_native = step_loop(context.fmu("FrictionPlant.fmu"), Path(tmp), params,
                                             arrays)
            python, close_python = step_loop(context.fmu(PYTHONFMU_PLANT), Path(tmp), params,
                                             arrays)
            try:
                native(forces[:50])
                python(forces[:50])
                medians, per_round = median_interleaved(
                    {"native": lambda n=native, f=forces: n(f),
                     "pythonfmu": lambda p=python, f=forces: p(f)},
                    rounds)
            finally:
                close_native()
                close_python()
            ratio = statistics.median(m["native"] / m["pythonfmu"] for m in per_round)
            verdict = "met" if ratio <= goal else "MISSED"
            verdicts.append(f"{case}: {n_steps} steps x {rounds} rounds")
            label = f"{case}, {mode}"
            rows += [
                Row(f"{label}: native", medians["native"] * 1e6, "us/step"),
                Row(f"{label}: pythonfmu", medians["pythonfmu"] * 1e6, "us/step"),
                Row(f"{label}: ratio native / pythonfmu", ratio, "x"),
                Row(f"{label}: goal at most ({verdict})", goal, "x"),
            ]
    context.notes.append("interleaved rounds, medians; ratio = median of the per-round "
                         "ratios; forces of the FrictionPlant.fmu section; "
                         + "; ".join(dict.fromkeys(verdicts)))
    return rows
