"""``papwc bench``: the wall time of ``papwc identify`` on a 60 s log at 100 Hz."""

from __future__ import annotations

import time

from papwc.bench import BenchContext, Row, register_section
from papwc.identify import DESIGN_DURATION, DESIGN_F_P_MAX, DESIGN_T, DESIGN_TRAVEL

#: A 60 s log must be identified within this time, s.
IDENTIFY_SECONDS_GOAL = 60.0
#: The log: the default excitation (60 s at 100 Hz) through Table 1's plant with a 0.1 um
#: encoder and 0.2 um noise.
ENCODER = {"x_resolution": 1e-7, "noise_std": 2e-7, "seed": 1}


@register_section("Identification: papwc identify on a 60 s log at 100 Hz")
def identify_wall_time(context: BenchContext) -> list[Row]:
    """Identify the Table 1 plant (and, unless quick, one with a Stribeck curve); time it."""
    from papwc.identify.excitation import apply_to_plant, design
    from papwc.identify.fit import identify

    u = design(DESIGN_T, DESIGN_F_P_MAX, DESIGN_TRAVEL, DESIGN_DURATION)
    cases = [("Table 1 plant", {})]
    if not context.quick:
        cases.append(("Table 1 plant with a Stribeck curve (v_s = 1 mm/s)", {"v_s": 1e-3}))
    rows = []
    for label, extra in cases:
        log = apply_to_plant(u, DESIGN_T, {**ENCODER, **extra})
        start, cpu = time.perf_counter(), time.process_time()
        ident = identify(log)
        wall = time.perf_counter() - start
        cpu = time.process_time() - cpu
        verdict = "met" if wall <= IDENTIFY_SECONDS_GOAL else "MISSED"
        rows.append(Row(f"{label}: wall time ({verdict}: goal {IDENTIFY_SECONDS_GOAL:g} s)",
                        wall, "s"))
        rows.append(Row(f"{label}: wall time / log duration", wall / (log.h * (log.x.size - 1)),
                        ""))
        rows.append(Row(f"{label}: CPU time of the process (the wall time on an idle core)",
                        cpu, "s"))
        context.notes.append(f"{label}: deviations chosen: "
                             + (", ".join(ident.chosen) or "none"))
    context.notes.append("0.1 um encoder, 0.2 um noise; every deviation tried (stribeck, lag)")
    return rows
