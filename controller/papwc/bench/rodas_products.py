"""``papwc bench`` section: what RODAS4's written-out matrix-vector products save.

:func:`papwc.model.rodas.matvec` gives, for the plant's 2 to 6 states, a product written
out term by term instead of the loop it takes for other sizes. Each RODAS4 step makes
six products; this section measures both ways of making them, and a whole 10 ms step of
the model layer's :class:`~papwc.model.dynamics.Plant`, for two integrated cases (LuGre:
3 states; flexible drive with actuator lag: 5 states), so that the share of a step the
written-out products save is a measured figure.
"""

from __future__ import annotations

import random
import time

from papwc.bench import BenchContext, Row, gc_paused, median_interleaved, register_section
from papwc.bench.plant_calls import plant_forces

#: case -> plant parameters (integrated: every step is RODAS4 steps).
CASES: dict[str, dict[str, float]] = {
    "LuGre (3 states)": {"sigma_0": 6.5e7, "sigma_1": 2e5, "v_s": 1e-3},
    "flexible + lag (5 states)": {"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3,
                                  "tau_u": 2e-3},
}


@register_section("RODAS4: products written out against the loop (model layer)")
def rodas_products(context: BenchContext) -> list[Row]:
    """Cost of six products per size both ways, and of one integrated 10 ms Plant step."""
    from papwc.model.dynamics import Plant
    from papwc.model.rodas import _matvec_any, matvec

    rounds, repeat = (3, 2_000) if context.quick else (9, 20_000)
    rng = random.Random(1)
    forces = plant_forces(200 if context.quick else 1_000)
    rows = []
    for name, params in CASES.items():
        plant = Plant(params)
        n = len(plant._names)
        m = [[rng.uniform(-1.0, 1.0) for _ in range(n)] for _ in range(n)]
        b = [rng.uniform(-1.0, 1.0) for _ in range(n)]
        written = matvec(n)
        if written(m, b) != _matvec_any(m, b):
            raise RuntimeError(f"bench {name}: the written-out product differs from the loop")

        def six(product, m=m, b=b) -> float:
            with gc_paused():
                start = time.thread_time_ns()
                for _ in range(repeat):
                    product(m, b)
                    product(m, b)
                    product(m, b)
                    product(m, b)
                    product(m, b)
                    product(m, b)
                elapsed = time.thread_time_ns() - start
            return elapsed * 1e-9 / repeat

        def plant_step(plant=plant, name=name) -> float:
            steps = 0
            with gc_paused():
                start = time.thread_time_ns()
                for u in forces:
                    reason = plant.step(u, 0.01)
                    if reason is not None:
                        raise RuntimeError(f"bench {name}: step refused: {reason}")
                    steps += plant.work[0]
                elapsed = time.thread_time_ns() - start
            return elapsed * 1e-9 / max(steps, 1)

        medians, _ = median_interleaved(
            {"written": lambda written=written: six(written),
             "loop": lambda: six(_matvec_any), "rodas": plant_step}, rounds)
        saved = medians["loop"] - medians["written"]
        rows += [
            Row(f"{name}: six products written out", medians["written"] * 1e6, "us"),
            Row(f"{name}: six products by the loop", medians["loop"] * 1e6, "us"),
            Row(f"{name}: one RODAS4 step of Plant.step (with the written-out products)",
                medians["rodas"] * 1e6, "us"),
            Row(f"{name}: share of a RODAS4 step the written-out products save",
                saved / (medians["rodas"] + saved), "x"),
        ]
    context.notes.append(
        f"{rounds} interleaved rounds; CPU time of this thread; a RODAS4 step's cost is a "
        "10 ms Plant.step's divided by its integrator steps (events included); the saving "
        "is (loop - written) / (the step with the loop's products)")
    return rows
