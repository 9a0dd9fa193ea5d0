"""``papwc reproduce``: Figures 1 and 3-9 of the paper, its numbers, and a report."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from papwc.analysis import claims, paper  # noqa: E402
from papwc.errors import ScenarioError  # noqa: E402
from papwc.master import RunResult  # noqa: E402
from papwc.model.pulse import b_coulomb, pulse_displacement, pulse_width  # noqa: E402
from papwc.output_files import (  # noqa: E402
    lock_folder,
    make_folder,
    remove_file,
    save_figure,
    write_rows,
    write_text,
)
from papwc.resources import scenario_file  # noqa: E402
from papwc.results import plots  # noqa: E402
from papwc.results.folder import INCOMPLETE, ResultsFolder, run_into_folder  # noqa: E402
from papwc.results.summary import summarize  # noqa: E402
from papwc.scenario import load_scenario  # noqa: E402
from papwc.scenario_run import ensure_plant_fmu, run_scenario  # noqa: E402

#: The paper's scenario (a shipped file).
DEFAULT_SCENARIO = "paper.toml"
#: Further shipped scenarios reproduced beside the paper's.
EXTRA_SCENARIOS = ("exact.toml", "exact_encoder.toml")
#: Files ``papwc reproduce`` writes into its folder (besides runs/ and fmu/).
OUTPUTS = ("fig1.png", *(f"fig{i}.png" for i in range(3, 10)), "fig_exact.png",
           "paper_numbers.csv", "claims.csv", "readings.csv", "report.md")


def fig1(path: Path, p: dict[str, float] = paper.TABLE_1) -> None:
    """Figure 1: displacement d against pulse width t_p, Eq. (3), Eq. (4) and the b_hat line."""
    m, f_c, c, f_s, f_p = (p[k] for k in ("m", "f_c", "c", "f_s", "f_p"))
    b = b_coulomb(f_p, m, f_c)
    t3 = pulse_width(0.01, f_p, m, f_c, c)
    b_line = 0.01 / t3**2
    ts = [i * 0.12 / 400 for i in range(401)]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(ts, [pulse_displacement(f_p, t, m, f_c, c) * 1e3 for t in ts],
            "-", label="Eq. (3), exact")
    ax.plot(ts, [b * t * t * 1e3 for t in ts], ":", label=f"Eq. (4), b = {b:.3g} m/s²")
    ax.plot(ts, [b_line * t * t * 1e3 for t in ts], "-.",
            label=f"Eq. (4) with b_hat = {b_line / b:.4f} b (hits 0.01 m)")
    ax.axhline(10.0, color="k", lw=0.6, ls="--")
    ax.set_xlabel("pulse width t_p (s)")
    ax.set_ylabel("displacement d (mm)")
    ax.set_title("Figure 1: displacement as a function of the pulse width (Table 1)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)


def _by_kind(results, kind):
    return [r for r in results if r.settings.kind == kind]


def _last(result):
    return summarize(result.traces[-1], result.settings.tolerance)


def _adaptation_per_pulse(trace, n_pulses: int) -> float:
    """Mean ``|change of b_hat|`` per pulse over the first ``n_pulses`` pulses of a trace."""
    b = trace.column("b_hat")
    pulses = trace.column("pulses")
    k = next((i for i, p in enumerate(pulses) if p > n_pulses), len(pulses) - 1)
    done = min(n_pulses, pulses[k] - (1 if pulses[k] > n_pulses else 0))
    return abs(b[k] - b[0]) / done if done else math.nan


def simulation_numbers(results: list[RunResult], p: dict[str, float] = paper.TABLE_1
                       ) -> list[tuple[str, str, float]]:
    """The paper's statements about its simulations beside the values measured here."""
    m, f_c, c, f_s, f_p, T = (p[k] for k in ("m", "f_c", "c", "f_s", "f_p", "T"))
    b = b_coulomb(f_p, m, f_c)
    d19 = paper.d_min(f_p, T, m, f_c, c)
    rows: list[tuple[str, str, float]] = []
    for r in results:
        name = r.label
        if not r.traces:
            continue
        n = r.traces[-1].iteration
        last = _last(r)
        if r.settings.kind == "pwc":
            bounded = math.isfinite(r.settings.t_p_max)
            rows.append((f"{name}: limit-cycle peak-to-peak, iteration {n} (m)",
                         "1.9e-4 (= d_min, Eq. (19))" if bounded else "> d_min (2T pulses)",
                         last["cycle_p2p_m"]))
            rows.append((f"{name}: limit-cycle peak-to-peak / d_min Eq. (19)",
                         "1" if bounded else "> 1", last["cycle_p2p_m"] / d19))
        elif r.settings.kind == "papwc":
            rows.append((f"{name}: |final error|, iteration {n} (m)",
                         "<= 2e-5 (tolerance); Eq. (20) 1.3e-5", abs(last["final_error_m"])))
            rows.append((f"{name}: limit cycle in iteration {n} (1 = yes)", "0",
                         float(last["limit_cycle"])))
            rows.append((f"{name}: pulses in iteration {n}",
                         "2" if not math.isfinite(r.settings.t_p_max) else "", last["pulses"]))
            rows.append((f"{name}: f_c_hat at the end of iteration {n} (N)", "", last["f_c_hat"]))
        else:
            rows.append((f"{name}: |final error|, iteration {n} (m)", "",
                         abs(last["final_error_m"])))
            rows.append((f"{name}: pulses in iteration {n}", "", last["pulses"]))
        rows.append((f"{name}: b_hat/b at the end of iteration {n}", "", last["b_hat"] / b))
        if r.settings.kind in ("pwc", "papwc"):
            rows.append((f"{name}: adaptation speed, mean |change of b_hat| per pulse over the "
                         "first 5 pulses of iteration 1 (m/s^2)", "PAPWC much faster than PWC",
                         _adaptation_per_pulse(r.traces[0], 5)))
    return rows


def reproduce(out: Path, scenario_path: str | None = None, fmu: str | None = None,
              readings: bool = False, workers: int | None = None) -> int:
    """Run the paper's scenario on FrictionPlant.fmu and write figures, tables and a report.

    ``readings``: also search the readings of each claim the scenario does not
    reproduce, in ``workers`` processes (see :mod:`papwc.analysis.claims`).
    """
    path = Path(scenario_path) if scenario_path else scenario_file(DEFAULT_SCENARIO)
    if not path.is_file():
        raise ScenarioError(f"{path}: no such scenario file")
    scenario = load_scenario(path)
    extra_scenarios = [] if scenario_path else [load_scenario(scenario_file(name))
                                                for name in EXTRA_SCENARIOS]
    fmu = ensure_plant_fmu(fmu, out)
    make_folder(out)
    with lock_folder(out, "papwc reproduce"):
        return _reproduce(out, path, scenario, extra_scenarios, fmu, readings, workers)


def _reproduce(out: Path, path: Path, scenario, extra_scenarios: list, fmu: Path,
               readings: bool, workers: int | None) -> int:
    """:func:`reproduce` once its inputs are checked and its folder locked."""
    # Results go to disk as they come: runs/ per controller (see papwc.scenario_run), the
    # figures and tables at the end; INCOMPLETE marks the folder until then.
    for name in OUTPUTS:
        remove_file(out / name)
    write_text(out / INCOMPLETE, "papwc reproduce has not finished (or was stopped): the "
               "figures, paper_numbers.csv and report.md are missing; the controllers that "
               "finished are in runs/ (see runs/INCOMPLETE).\n")
    scenarios = [scenario, *extra_scenarios]
    folder = ResultsFolder(out / "runs", [label for s in scenarios for label in s.labels],
                           {label: s.warnings_of(label) for s in scenarios for label in s.labels},
                           what="papwc reproduce", own=True)
    folder.start()
    print(f"running {path} ({len(scenario.controllers)} controllers x "
          f"{scenario.maneuver.iterations} iterations) on {fmu} ...")
    results = run_into_folder(folder, lambda progress: run_scenario(
        scenario, "fmu", fmu, progress=progress))
    extra = []
    for other in extra_scenarios:
        print(f"running {other.source} ...")
        extra += run_into_folder(folder, lambda progress, other=other: run_scenario(
            other, "fmu", fmu, progress=progress))
    run_into_folder(folder, lambda progress: folder.finish())

    fig1(out / "fig1.png")
    pwc, papwc = _by_kind(results, "pwc"), _by_kind(results, "papwc")
    b = b_coulomb(paper.TABLE_1["f_p"], paper.TABLE_1["m"], paper.TABLE_1["f_c"])
    plots.time_panels(pwc, "e", "error e (mm)", "Figure 3: error, adaptive PWC",
                      out / "fig3.png", 1e3)
    plots.time_panels(papwc, "e", "error e (mm)", "Figure 4: error, adaptive PAPWC",
                      out / "fig4.png", 1e3)
    plots.time_panels(pwc, "u", "f_p (N)", "Figure 5: f_p, adaptive PWC", out / "fig5.png",
                      step=True)
    plots.time_panels(papwc, "u", "f_p (N)", "Figure 6: f_p, adaptive PAPWC", out / "fig6.png",
                      step=True)
    plots.time_panels(pwc, "b_hat", "b_hat (m/s²)", "Figure 7: b_hat, adaptive PWC",
                      out / "fig7.png", hlines={"theoretical b": b})
    plots.time_panels(papwc, "b_hat", "b_hat (m/s²)", "Figure 8: b_hat, adaptive PAPWC",
                      out / "fig8.png", hlines={"theoretical b": b})
    plots.time_panels(papwc, "f_c_hat", "f_c_hat (N)", "Figure 9: f_c_hat, adaptive PAPWC",
                      out / "fig9.png", hlines={"f_c": paper.TABLE_1["f_c"]})
    if extra:
        plots.time_panels(extra, "e", "error e (mm)", "Beyond the paper: error",
                          out / "fig_exact.png", 1e3)

    numbers = paper.formula_numbers() + simulation_numbers(results + extra)
    write_rows(out / "paper_numbers.csv",
               [{"quantity": q, "paper": p, "computed": v} for q, p, v in numbers],
               ["quantity", "paper", "computed"])
    claims_md = claims.write_claims(out, scenario, results, fmu, readings, workers)
    # Every output was removed at the start: a figure there now was drawn by this run (a
    # scenario without a PWC or PAPWC controller has no figures 3-9).
    figures = [name for name in OUTPUTS if name.endswith(".png") and (out / name).is_file()]
    write_text(out / "report.md", _report(path, numbers, results + extra, figures) + "\n"
               + claims_md)
    remove_file(out / INCOMPLETE)
    print(f"wrote {out}/{', '.join(figures)}, paper_numbers.csv, claims.csv, "
          f"{'readings.csv, ' if readings else ''}report.md, runs/")
    failed = [r for r in results + extra if r.error]
    for r in failed:
        print(f"error: {r.label}: {r.error}")
    return 1 if failed else 0


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _cell(text: str) -> str:
    """Text for a Markdown table cell."""
    return text.replace("|", "\\|")


def _report(path: Path, numbers, results, figures: list[str] | None = None) -> str:
    lines = [
        "# The paper reproduced",
        "",
        f"Scenario: `{path}`; plant: FrictionPlant.fmu (exact stick–slip), stepped by the "
        "Python master through fmpy at T = 0.01 s.",
        "Regenerate with `papwc reproduce`.",
        "",
        "## Every quantitative statement of the paper beside this project's value",
        "",
        "| quantity | paper | computed |",
        "|---|---|---|",
    ]
    lines += [f"| {_cell(q)} | {p} | {_fmt(v)} |" for q, p, v in numbers]
    lines += ["", "## Single pulses from rest (exact plant, Table 1)", "",
              "| t_p (s) | d (m) | velocity at pulse end (m/s) | time back at rest (s) |",
              "|---|---|---|---|"]
    lines += [f"| {r['t_p']:g} | {r['d']:.4g} | {r['v_end']:.4g} | {r['t_rest']:.4g} |"
              for r in paper.single_pulses()]
    lines += ["", "## Per iteration", "",
              "| controller | iteration | final error (m) | pulses | settle time (s) | "
              "limit cycle | b_hat | f_c_hat |", "|---|---|---|---|---|---|---|---|"]
    for r in results:
        for tr in r.traces:
            s = summarize(tr, r.settings.tolerance)
            lines.append(f"| {r.label} | {tr.iteration} | {s['final_error_m']:.3e} | "
                         f"{s['pulses']} | {_fmt(s['settle_time_s'])} | {s['limit_cycle']} | "
                         f"{_fmt(s['b_hat'])} | {_fmt(s['f_c_hat'])} |")
    what = {"fig1.png": "Eq. (3) and (4)", "fig3.png": "error, PWC", "fig4.png": "error, PAPWC",
            "fig5.png": "f_p, PWC", "fig6.png": "f_p, PAPWC", "fig7.png": "b_hat, PWC",
            "fig8.png": "b_hat, PAPWC", "fig9.png": "f_c_hat, PAPWC",
            "fig_exact.png": "error, beyond the paper"}
    shown = [f"{name} ({what.get(name, '')})" for name in figures or []]
    lines += ["", "Figures: " + (", ".join(shown) or "none") + "; 1st and last iteration. "
              "Traces and summary.csv in runs/.", ""]
    return "\n".join(lines)
