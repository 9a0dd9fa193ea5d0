"""The battery's results: results.csv, runs.csv, pulses.csv, spec.csv, summary.md and the
plots."""

from __future__ import annotations

import math
from pathlib import Path

from papwc.battery.plan import RunSpec, controller_tables, get_field
from papwc.battery.schema import Battery
from papwc.battery.spec import (
    RATIO_SLACK,
    SPEC_COLUMNS,
    beside_markdown,
    spec_markdown,
    spec_rows,
)
from papwc.controllers.settings import ControllerSettings
from papwc.output_files import save_figure
from papwc.results.pulses import ROW_COLUMNS
from papwc.scenario import (
    PLANT_FIELDS,
    controller_label,
)

# --- results ---------------------------------------------------------------------------------


#: Metrics per iteration, as :func:`papwc.master.summarize` returns them, then the
#: largest ratio of a pulse's displacement to its bound (:mod:`papwc.results.pulses`),
#: whether the iteration ended farther from the target than it started, and how far the
#: table moved after the controller called it settled in the iteration's last 0.5 s
#: (:func:`papwc.results.summary.settled_span`).
METRICS = ("final_error_m", "pulses", "settle_time_s", "limit_cycle", "cycle_p2p_m",
           "b_hat", "f_c_hat", "outcome", "outcome_reason", "pulse_ratio", "ends_farther",
           "settled_span_m")


def _label_of(table: dict, i: int) -> str:
    """Label of a controller table that may not be valid."""
    label = table.get("label") if isinstance(table, dict) else None
    if isinstance(label, str) and label:
        return label
    try:
        t = float(table.get("t_p_max", math.inf))
        kind = str(table.get("kind"))
    except (TypeError, ValueError, AttributeError):
        return f"controller{i + 1}"
    return controller_label(ControllerSettings(kind=kind, t_p_max=t))


def result_rows(batteries: list[Battery], runs: list[RunSpec], records: dict) -> list[dict]:
    """Rows of results.csv: per run, controller and iteration, in run order."""
    by_name = {b.name: b for b in batteries}
    rows = []
    for spec in runs:
        rec = records[(spec.battery, spec.run_id)]
        battery = by_name[spec.battery]
        base = {"battery": spec.battery, "run_id": spec.run_id, "run_hash": spec.run_hash}
        if battery.cases:
            base["case"] = spec.case
        ctrls = rec["controllers"]
        if not ctrls:
            for i, table in enumerate(controller_tables(spec.data)):
                row = {**base, "controller": _label_of(table, i),
                       "kind": table.get("kind", "") if isinstance(table, dict) else "",
                       "iteration": "", "last_iteration": True}
                row.update({p: _varied_value(spec.data, p, i) for p in battery.varied})
                row.update({"success": False, "false_settled": False, "status": "error",
                            "message": rec["message"]})
                rows.append(row)
            continue
        for i, c in enumerate(ctrls):
            tol = (battery.success_tolerance if battery.success_tolerance is not None
                   else c["tolerance"])
            entries = [dict(it) for it in c["iterations"]]
            if c["error"] and (not entries or not entries[-1]["error"]):
                entries.append({"iteration": len(entries) + 1, "error": c["error"]})
            for j, it in enumerate(entries):
                row = {**base, "controller": c["label"], "kind": c["kind"],
                       "iteration": it["iteration"], "last_iteration": j == len(entries) - 1}
                row.update({p: _varied_value(spec.data, p, i) for p in battery.varied})
                row.update({m: it.get(m, "") for m in METRICS})
                ok = not it["error"]
                row["success"] = bool(ok and abs(it["final_error_m"]) <= tol
                                      and not it["limit_cycle"])
                row["false_settled"] = bool(ok and it.get("outcome") == "settled"
                                            and not abs(it["final_error_m"]) <= tol)
                row["status"] = "ok" if ok else "error"
                row["message"] = it["error"] or c.get("warning", "")
                rows.append(row)
    return rows


def _varied_value(data: dict, path: str, table: int):
    return get_field(data, path, table if path.startswith("controller.") else None)


def _flatten(data: dict) -> dict:
    out = {f"plant.{k}": v for k, v in PLANT_FIELDS.items()}
    out.update({f"plant.{k}": v for k, v in data.get("plant", {}).items()})
    out.update({f"maneuver.{k}": v for k, v in data.get("maneuver", {}).items()})
    for i, table in enumerate(controller_tables(data), start=1):
        if isinstance(table, dict):
            out.update({f"controller.{i}.{k}": v for k, v in table.items()})
    return out


def _stats(values: list[float]) -> tuple[float, float, float]:
    import numpy as np

    if not values:
        return (math.nan, math.nan, math.nan)
    a = np.asarray(values, dtype=float)
    return float(np.median(a)), float(np.percentile(a, 95)), float(a.max())


def _fmt(x: float, spec: str) -> str:
    return "–" if isinstance(x, float) and math.isnan(x) else format(x, spec)


def pulse_rows(runs: list[RunSpec], records: dict, has_cases: bool) -> list[dict]:
    """Rows of pulses.csv: every pulse of every run, controller and iteration, in run order.

    The columns of ``papwc run``'s pulses.csv (:data:`papwc.results.folder.PULSE_COLUMNS`) after
    the run's battery, id, hash (and case).
    """
    out = []
    for spec in runs:
        base = {"battery": spec.battery, "run_id": spec.run_id, "run_hash": spec.run_hash}
        if has_cases:
            base["case"] = spec.case
        for c in records[(spec.battery, spec.run_id)]["controllers"]:
            out += [{**base, "controller": c["label"], "kind": c["kind"], **p}
                    for p in c.get("pulses", [])]
    return out


def summary_markdown(batteries: list[Battery], runs: list[RunSpec], rows: list[dict],
                     fmu_sha256: str, spec_table: list[dict] | None = None) -> str:
    """The text of summary.md (with ``spec_table``, from :func:`spec_rows`: each battery's
    spec table after its summary table, and every controller of a battery and its companions
    side by side, :func:`papwc.battery.spec.beside_markdown`)."""
    lines = ["# Battery results", ""]
    failed_keys = {(r["battery"], r["run_id"]) for r in rows if r["status"] == "error"}
    n_err = len(failed_keys)
    lines.append(f"{len(runs)} runs, {n_err} with status error. Plant FMU SHA-256: "
                 f"`{fmu_sha256[:16]}…`.")
    lines += ["", "**Success**: a controller succeeds in a run when, in the last iteration, "
              "the run has status ok, |final error| <= the success tolerance (the battery's "
              "`success_tolerance`, else the controller's `tolerance`) and there is no limit "
              "cycle (pulses in both directions in the final quarter of the iteration). "
              "Errors and pulses are taken over the runs with status ok, in the last "
              "iteration. *At rest*: the runs whose controller held u = 0 to the end "
              "(settled or stopped), with the time from which it did.", "",
              "**Outcome** (last iteration): `settled` when the controller ended settled (|e| "
              "within its tolerance at rest, as it measured), else `stopped` with its reason; "
              "*false settled* counts the runs it called settled while the true |final error| "
              "exceeds the success tolerance. **No runaway**, over every iteration: *pulse "
              "ratio* is the largest ratio of a pulse's displacement (to the next rest) to its "
              "bound, the larger of 1.5*|e| + one encoder count and the table's quantum (one "
              "sample at the highest breakaway force the table's parameters allow, from "
              "rest; it depends on the table only, `papwc.results.pulses`), > 1 a pulse "
              "beyond its bound; *runaway maneuvers* counts the maneuvers (iterations) with "
              "a pulse beyond its bound (a ratio above 1 + 1e-9: rounding); *farther* counts "
              "the maneuvers that ended farther from the target than they started. Which of "
              "those pulses the spec forbids outright: the spec tables.", ""]
    last = [r for r in rows if r["last_iteration"]]
    for battery in batteries:
        b_runs = [s for s in runs if s.battery == battery.name]
        tol = (f"{battery.success_tolerance:g} m" if battery.success_tolerance is not None
               else "each controller's tolerance")
        grid = math.prod(len(v) for _, v in battery.sweep)
        cases = f"{len(battery.cases)} case(s) × " if battery.cases else ""
        lines += [f"## {battery.name}", "",
                  f"File `{battery.source}`: {len(b_runs)} runs ({cases}{grid} grid point(s) × "
                  f"{battery.n} draw(s)"
                  + (f", seed {battery.seed}" if battery.monte_carlo else "")
                  + (f"; every seed offset by {battery.seed_offset} (--seed-offset)"
                     if battery.seed_offset else "")
                  + f"); success tolerance: {tol}.", ""]
        if battery.varied:
            lines += ["Varied: " + ", ".join(f"`{p}`" for p in battery.varied) + ".", ""]
        first = "| case " if battery.cases else ""
        lines += [first + "| controller | runs | errors | success | limit cycles | "
                  "abs(e) median (m) | abs(e) p95 (m) | abs(e) max (m) | pulses median | p95 | "
                  "max | at rest | at rest from, median (s) | p95 | max | outcome settled | "
                  "stopped (reasons) | false settled | pulse ratio max | runaway maneuvers | "
                  "farther |",
                  ("|---" if battery.cases else "")
                  + "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:"
                  + "|---:|---|---:|---:|---:|---:|"]
        b_rows = [r for r in last if r["battery"] == battery.name]
        b_all = [r for r in rows if r["battery"] == battery.name]
        groups = [(name, [r for r in b_rows if r["case"] == name],
                   [r for r in b_all if r["case"] == name]) for name, _ in battery.cases
                  ] if battery.cases else [("", b_rows, b_all)]
        for case, case_rows, all_rows in groups:
            for label in dict.fromkeys(r["controller"] for r in case_rows):
                cr = [r for r in case_rows if r["controller"] == label]
                ar = [r for r in all_rows if r["controller"] == label]
                lines.append((f"| {case} " if battery.cases else "") + _summary_cells(label, cr)
                             + _safety_cells(cr, ar))
        lines += ["", f"Distribution of |final error|: `final_error_{battery.name}.png`.", ""]
        if spec_table is not None:
            lines += spec_markdown(battery, spec_table)
        failed = [s for s in b_runs if (s.battery, s.run_id) in failed_keys]
        if failed:
            lines += [f"Runs with status error ({len(failed)}):", ""]
            for s in failed[:20]:
                msg = next(r["message"] for r in rows if r["battery"] == s.battery
                           and r["run_id"] == s.run_id and r["status"] == "error")
                lines.append(f"- `{s.run_id}`: {msg}")
            if len(failed) > 20:
                lines.append(f"- … and {len(failed) - 20} more (see results.csv)")
            lines.append("")
    if spec_table is not None:
        lines += beside_markdown(spec_table)
    return "\n".join(lines)


def _summary_cells(label: str, cr: list[dict]) -> str:
    """One row of a summary table: a controller's statistics over the rows ``cr``."""
    ok = [r for r in cr if r["status"] == "ok"]
    succ = sum(1 for r in cr if r["success"])
    cycles = sum(1 for r in ok if r["limit_cycle"])
    e = _stats([abs(r["final_error_m"]) for r in ok])
    p = _stats([float(r["pulses"]) for r in ok])
    settled = [r["settle_time_s"] for r in ok if not math.isnan(r["settle_time_s"])]
    s = _stats(settled)
    return (f"| {label} | {len(cr)} | {len(cr) - len(ok)} | {succ / len(cr):.1%} | "
            f"{cycles} | {_fmt(e[0], '.3g')} | {_fmt(e[1], '.3g')} | {_fmt(e[2], '.3g')} | "
            f"{_fmt(p[0], '.0f')} | {_fmt(p[1], '.1f')} | {_fmt(p[2], '.0f')} | "
            f"{len(settled)} | {_fmt(s[0], '.3f')} | {_fmt(s[1], '.3f')} | "
            f"{_fmt(s[2], '.3f')} |")


def _safety_cells(cr: list[dict], ar: list[dict]) -> str:
    """Outcome (last iteration, rows ``cr``) and no-runaway (every iteration, ``ar``) cells."""
    import collections

    ok = [r for r in cr if r["status"] == "ok"]
    settled = sum(1 for r in ok if r.get("outcome") == "settled")
    reasons = collections.Counter(r.get("outcome_reason") or "?" for r in ok
                                  if r.get("outcome") != "settled")
    why = ", ".join(f"{n} {reason}" for reason, n in reasons.most_common())
    false = sum(1 for r in cr if r.get("false_settled"))
    ratios = [float(r["pulse_ratio"]) for r in ar
              if r["status"] == "ok" and r.get("pulse_ratio", "") != ""]
    worst = max(ratios, default=math.nan)
    runaway = sum(1 for q in ratios if q > 1.0 + RATIO_SLACK)
    farther = sum(1 for r in ar if r["status"] == "ok" and r.get("ends_farther") is True)
    return (f" {settled} | {sum(reasons.values())}" + (f" ({why})" if why else "")
            + f" | {false} | {_fmt(worst, '.3g')} | {runaway} | {farther} |")


def plot_final_errors(battery: Battery, rows: list[dict], path: Path) -> None:
    """Empirical CDF of ``|final error|`` per controller (last iteration), log x axis, as PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    floor = 1e-12
    last = [r for r in rows if r["last_iteration"] and r["battery"] == battery.name
            and r["status"] == "ok"]
    tols = {}
    keys = dict.fromkeys((r.get("case", ""), r["controller"]) for r in last)
    for case, label in keys:
        errs = sorted(max(abs(r["final_error_m"]), floor) for r in last
                      if r["controller"] == label and r.get("case", "") == case)
        n = len(errs)
        name = f"{case}: {label}" if case else label
        ax.step(errs, [(i + 1) / n for i in range(n)], where="post", label=f"{name} ({n})")
    if battery.success_tolerance is not None:
        tols["success tolerance"] = battery.success_tolerance
    for name, tol in tols.items():
        if tol > 0:
            ax.axvline(tol, color="k", ls=":", lw=1, label=f"{name} {tol:g} m")
    ax.set_xscale("log")
    ax.set_xlabel(f"|final error| in the last iteration, m (values below {floor:g} drawn at it)")
    ax.set_ylabel("fraction of runs")
    ax.set_ylim(0.0, 1.02)
    ax.set_title(f"{battery.name}: final error per controller")
    ax.grid(True, which="both", alpha=0.3)
    if last:
        ax.legend(loc="lower right", fontsize=8 if len(keys) <= 8 else 5,
                  ncol=1 if len(keys) <= 12 else 2)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


#: The table's own values that identified.csv puts beside the identified ones.
IDENTIFIED_TRUTH = ("m", "f_c", "f_s", "c", "f_s_spread", "v_s", "tau_u", "ripple",
                    "ripple_period", "ripple_phase", "x_resolution", "noise_std", "seed")


def identified_rows(runs: list[RunSpec], records: dict, has_cases: bool) -> list[dict]:
    """Rows of identified.csv (batteries with ``identify_first``): per run, what was
    identified of its table (the identified values, the band, the deviations chosen, the
    processor time of the identification, whether another run's was taken), then the
    table's own values (``table.<name>``)."""
    out = []
    for spec in runs:
        rec = records[(spec.battery, spec.run_id)]
        found = rec.get("identified")
        if found is None:
            continue
        row = {"battery": spec.battery, "run_id": spec.run_id, "run_hash": spec.run_hash}
        if has_cases:
            row["case"] = spec.case
        row.update({"table_key": found.get("key", ""), "cached": bool(found.get("cached")),
                    "error": found.get("error", "")})
        row.update({k: v for k, v in found.items() if k not in ("key", "cached", "error")})
        plant = {**PLANT_FIELDS, **spec.data.get("plant", {})}
        row.update({f"table.{name}": plant[name] for name in IDENTIFIED_TRUTH})
        out.append(row)
    return out


def write_outputs(out: Path, batteries: list[Battery], runs: list[RunSpec], records: dict,
                  fmu_sha256: str) -> list[Path]:
    """Write results.csv, runs.csv, pulses.csv, spec.csv, summary.md and the plots from the
    records (each file atomically); identified.csv where a battery identifies its tables
    first."""
    from papwc.output_files import write_rows, write_text

    rows = result_rows(batteries, runs, records)
    varied = list(dict.fromkeys(p for b in batteries for p in b.varied))
    has_cases = any(b.cases for b in batteries)
    columns = (["battery", "run_id", "run_hash"] + (["case"] if has_cases else [])
               + ["controller", "kind", "iteration", "last_iteration"] + varied + list(METRICS)
               + ["success", "false_settled", "status", "message"])
    paths = [out / "results.csv", out / "runs.csv", out / "summary.md", out / "pulses.csv",
             out / "spec.csv"]
    write_rows(paths[0], rows, columns)
    write_rows(paths[3], pulse_rows(runs, records, has_cases),
               ["battery", "run_id", "run_hash"] + (["case"] if has_cases else [])
               + ["controller", "kind", "iteration", *ROW_COLUMNS])
    spec_table = spec_rows(batteries, runs, records, rows)
    write_rows(paths[4], spec_table, SPEC_COLUMNS)
    by_name = {b.name: b for b in batteries}
    run_rows = []
    for spec in runs:
        rec = records[(spec.battery, spec.run_id)]
        row = {"battery": spec.battery, "run_id": spec.run_id, "run_hash": spec.run_hash}
        if has_cases:
            row["case"] = spec.case
        row.update({"status": rec["status"], "message": rec["message"],
                    "seed_offset": by_name[spec.battery].seed_offset, **_flatten(spec.data)})
        run_rows.append(row)
    run_columns = ["battery", "run_id", "run_hash"] + (["case"] if has_cases else []) + [
        "status", "message", "seed_offset"]
    run_columns += list(dict.fromkeys(k for r in run_rows for k in r if k not in run_columns))
    write_rows(paths[1], run_rows, run_columns)
    write_text(paths[2], summary_markdown(batteries, runs, rows, fmu_sha256, spec_table))
    identified = identified_rows(runs, records, has_cases)
    if identified:
        paths.append(out / "identified.csv")
        write_rows(paths[-1], identified, list(dict.fromkeys(k for r in identified for k in r)))
    for battery in batteries:
        png = out / f"final_error_{battery.name}.png"
        plot_final_errors(battery, rows, png)
        paths.append(png)
    return paths
