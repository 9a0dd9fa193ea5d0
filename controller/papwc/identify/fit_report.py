"""What ``papwc identify`` writes into its output folder, every file atomically.

``plant.toml`` (a scenario: the identified ``[plant]`` table, the log's sample period as
``T`` and one papwc controller, ready for ``papwc run``, ``battery`` and ``build
--scenario``), ``identified.csv`` (each parameter with its estimate, 95 % interval, unit
and method), ``report.md`` with ``position.png`` (measured and simulated position),
``residual.png`` and ``friction.png`` (force-velocity points and the fitted friction
curve); ``excitation.csv`` with ``--design``, and ``log.csv`` with ``--fmu``.

While the command runs, the folder holds ``INCOMPLETE`` saying what is missing
(:class:`IdentifyFolder`); a run first removes what an earlier one wrote there, and
nothing else.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from papwc.identify.fit import DEVIATIONS, NOT_TRIED, Identification
from papwc.identify.log_file import Log
from papwc.output_files import make_folder, remove_file, save_figure, write_rows, write_text
from papwc.results.folder import INCOMPLETE

__all__ = [
    "FIGURES",
    "OWN_FILES",
    "IdentifyFolder",
    "plant_toml",
    "write_excitation",
    "write_identification",
    "write_log",
]

#: The figures of report.md.
FIGURES = ("position.png", "residual.png", "friction.png")
#: Every file ``papwc identify`` writes (removed from the folder when a run starts).
OWN_FILES = ("excitation.csv", "log.csv", "identified.csv", "plant.toml", "report.md",
             *FIGURES, INCOMPLETE)
#: Columns of identified.csv.
IDENTIFIED_COLUMNS = ("parameter", "estimate", "ci_low", "ci_high", "unit", "method")


class IdentifyFolder:
    """The output folder: cleared of an earlier run's files, marked incomplete until done."""

    def __init__(self, out: str | os.PathLike, planned: Sequence[str]) -> None:
        self.out = Path(out)
        self.planned = list(planned)
        self.written: list[str] = []

    def start(self) -> None:
        """Create the folder, remove an earlier run's files, write INCOMPLETE."""
        make_folder(self.out)
        for name in OWN_FILES:
            for path in (self.out / name, self.out / (name + ".tmp"),
                         self.out / (Path(name).stem + ".tmp.png")):
                if path.is_file():
                    remove_file(path)
        self.mark(f"papwc identify started at {time.strftime('%Y-%m-%d %H:%M:%S')} and has not "
                  "finished (or was stopped)")

    def mark(self, reason: str) -> None:
        """Write INCOMPLETE: ``reason``, what is written, what is missing."""
        missing = [name for name in self.planned if name not in self.written]
        text = [f"This folder is incomplete: {reason}.", ""]
        text += ["Written:"] + [f"- {n}" for n in self.written] if self.written else [
            "Written: nothing yet."]
        text += ["", "Missing:"] + [f"- {n}" for n in missing] + [""]
        write_text(self.out / INCOMPLETE, "\n".join(text))

    def wrote(self, name: str) -> None:
        """Record ``name`` as written (complete)."""
        self.written.append(name)

    def finish(self) -> None:
        """Everything is written: remove INCOMPLETE."""
        remove_file(self.out / INCOMPLETE)

    def abort(self, reason: str) -> str:
        """Mark the folder incomplete with ``reason``; a line saying what was kept. Never raises.

        A file left half-written by the stop (``<name>.tmp``, ``<stem>.tmp.png``) is removed.
        """
        for name in OWN_FILES:
            for path in (self.out / (name + ".tmp"), self.out / (Path(name).stem + ".tmp.png")):
                with contextlib.suppress(OSError):
                    path.unlink(missing_ok=True)
        try:
            self.mark(reason)
            marked = f"; see {self.out / INCOMPLETE}"
        except OSError:
            marked = ""
        kept = ", ".join(self.written) or "nothing"
        return f"kept in {self.out}: {kept}{marked}"


def write_excitation(path: Path, u: np.ndarray, h: float) -> None:
    """The excitation CSV: ``time`` (s), ``u`` (N, held until the next row)."""
    write_rows(path, [{"time": k * h, "u": float(f)} for k, f in enumerate(u)], ("time", "u"))


def write_log(path: Path, log: Log) -> None:
    """A log CSV (``time``, ``u``, ``x``) that ``papwc identify`` reads with its defaults."""
    write_rows(path, [{"time": float(t), "u": float(f), "x": float(x)}
                      for t, f, x in zip(log.t, log.u, log.x, strict=True)], ("time", "u", "x"))


def plant_toml(ident: Identification) -> str:
    """The scenario file of the identified plant (TOML text): its ``[plant]`` table, and the
    ``[identified]`` table of :mod:`papwc.identify.plant_model` (intervals, the band)."""
    import json

    from papwc.identify.plant_model import IDENTIFIED, plant_model_of
    from papwc.model.maneuver import MANEUVER_DEFAULTS
    from papwc.model.plant import SCENARIO_PLANT_FIELDS

    h = ident.log.h
    duration = max(round(MANEUVER_DEFAULTS["duration"] / h), 1) * h
    lines = ["# The plant identified by papwc identify from " + ident.log.source.replace("\n", " "),
             "# (see identified.csv and report.md beside this file).",
             'name = "identified"', "", "[plant]"]
    for name in SCENARIO_PLANT_FIELDS:
        if name in ident.plant:
            lines.append(f"{name} = {float(ident.plant[name])!r}")
    lines += ["", "[maneuver]", f"T = {h!r}", f"duration = {duration!r}", "",
              "[[controller]]", 'kind = "papwc"', ""]
    model = plant_model_of(ident, ident.log.source)
    lines += ["# What papwc identify found beside the [plant] values: 95 % intervals and the",
              "# stiction band (breakaway forces, N, the ripple's factor removed); papwc run",
              "# --plant-model gives the controllers this plant.",
              f"[{IDENTIFIED}]", f"log = {json.dumps(ident.log.source)}",
              f"sample_period = {h!r}",
              "chosen = [" + ", ".join(json.dumps(c) for c in model.chosen) + "]",
              f"cpu_s = {model.cpu_s!r}", "", f"[{IDENTIFIED}.intervals]"]
    lines += [f"{name} = [{low!r}, {high!r}]" for name, (low, high) in model.intervals.items()]
    if model.band is not None:
        lines += ["", f"[{IDENTIFIED}.band]"]
        lines += [f"{name} = {value!r}" for name, value in model.band.items()]
    return "\n".join(lines) + "\n"


def write_identification(folder: IdentifyFolder, ident: Identification, command: str) -> None:
    """identified.csv, plant.toml, the figures and report.md, each recorded as written."""
    import tomllib

    from papwc.identify.plant_model import check_identified
    from papwc.scenario import parse_scenario

    out = folder.out
    rows = [{"parameter": e.name, "estimate": e.value, "ci_low": e.low, "ci_high": e.high,
             "unit": e.unit, "method": e.method} for e in ident.estimates]
    write_rows(out / "identified.csv", rows, IDENTIFIED_COLUMNS)
    folder.wrote("identified.csv")
    text = plant_toml(ident)
    data = tomllib.loads(text)  # it loads as a plant model, or this is a bug
    parse_scenario(data, str(out / "plant.toml"))
    check_identified(data["identified"], str(out / "plant.toml"))
    write_text(out / "plant.toml", text)
    folder.wrote("plant.toml")
    for name in _figures(out, ident):
        folder.wrote(name)
    write_text(out / "report.md", report_text(ident, command))
    folder.wrote("report.md")


def _figures(out: Path, ident: Identification) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    log = ident.log
    t = log.t
    written = []
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(t, log.x * 1e3, lw=1.2, label="measured")
    ax.plot(t, ident.replay_x * 1e3, lw=0.8, ls="--", label="simulated (identified plant)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position (mm)")
    ax.legend()
    ax.set_title("Measured and simulated position (force replayed from the log)")
    fig.tight_layout()
    save_figure(fig, out / "position.png", dpi=110)
    plt.close(fig)
    written.append("position.png")

    fig, ax = plt.subplots(figsize=(9, 3.5))
    ax.plot(t, (ident.replay_x - log.x) * 1e6, lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("simulated - measured (um)")
    ax.set_title(f"Residual of the replay: rms {ident.replay_rms:.3g} m")
    fig.tight_layout()
    save_figure(fig, out / "residual.png", dpi=110)
    plt.close(fig)
    written.append("residual.png")

    v, f = force_velocity_points(ident)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(v * 1e3, f, ".", ms=3, alpha=0.6, label="sliding samples: u - m*a")
    held = ident.motion.held
    ax.plot(np.zeros(held.size), np.abs(log.u[held]) * np.sign(log.u[held]), "x", ms=4,
            label="forces held at rest")
    vmax = float(np.max(np.abs(v))) if v.size else 0.01
    grid = np.linspace(-vmax, vmax, 801)
    ax.plot(grid * 1e3, friction_curve(grid, ident.plant), "k", lw=1.2,
            label="fitted friction + damping")
    ax.set_xlabel("velocity (mm/s)")
    ax.set_ylabel("force (N)")
    ax.legend(fontsize=8)
    ax.set_title("Force-velocity points and the fitted friction curve")
    fig.tight_layout()
    save_figure(fig, out / "friction.png", dpi=110)
    plt.close(fig)
    written.append("friction.png")
    return written


def friction_curve(v: np.ndarray, plant: dict) -> np.ndarray:
    """Steady sliding friction plus damping at velocity ``v`` (m/s), N."""
    f_c, f_s, c = plant["f_c"], plant["f_s"], plant["c"]
    level = np.full_like(v, f_c)
    v_s = plant.get("v_s", 0.0)
    if v_s > 0.0:
        level = f_c + (f_s - f_c) * np.exp(-(np.abs(v) / v_s) ** plant.get("delta_s", 2.0))
    return np.sign(v) * level + c * v


def force_velocity_points(ident: Identification) -> tuple[np.ndarray, np.ndarray]:
    """Velocity (central difference) and the force not spent accelerating, at sliding samples."""
    from papwc.identify.fit import sliding_triples

    log = ident.log
    k = sliding_triples(ident.motion)
    h = log.h
    v = (log.x[k + 2] - log.x[k]) / (2.0 * h)
    acc = (log.x[k + 2] - 2.0 * log.x[k + 1] + log.x[k]) / (h * h)
    force = 0.5 * (log.u[k] + log.u[k + 1]) - ident.plant["m"] * acc
    return v, force


def _g(value: float) -> str:
    return "-" if isinstance(value, float) and math.isnan(value) else f"{value:.6g}"


def report_text(ident: Identification, command: str) -> str:
    """report.md."""
    log, motion, b = ident.log, ident.motion, ident.bracket
    lines = [
        "# Identified plant", "",
        f"Log: `{log.source}`: {log.x.size} samples, sample period {log.h:.6g} s "
        f"({log.x.size * log.h:.4g} s).", "",
        f"Command: `{command}`", "",
        f"Identified in {ident.seconds:.3g} s.", "",
        "## Parameters", "",
        "| parameter | estimate | 95 % interval | unit | method |", "|---|---|---|---|---|",
    ]
    for e in ident.estimates:
        lines.append(f"| `{e.name}` | {_g(e.value)} | {_g(e.low)} .. {_g(e.high)} | {e.unit} | "
                     f"{e.method} |")
    lines += [
        "", "## How", "",
        f"1. Motion: an interval moved when its position difference exceeds "
        f"{motion.threshold:.3g} m (6 standard deviations of the differences at rest and "
        f"1.5 encoder counts); encoder count {motion.resolution:.3g} m, noise "
        f"{motion.noise:.3g} m (scatter within the rests).",
        f"2. Start: linear regression of Eq. (1)'s exact sampled form on "
        f"{ident.regression_rows} runs of three sliding intervals: m = "
        f"{ident.start['m']:.6g} kg, f_c = {ident.start['f_c']:.6g} N, c = "
        f"{ident.start['c']:.6g} N.s/m.",
        f"3. Rests: the largest force held at rest was {b.low:.6g} N"
        + (f" (row {b.low_k + 1})" if b.low_k >= 0 else " (none held: f_c)")
        + f", the smallest that moved the table {b.high:.6g} N (row {b.high_k + 1}); the "
        "stiction band is below.",
        f"4. Output error: the {ident.sliding_moves} sliding moves (pulses from rest well "
        "above every force the table held) simulated from their rests through the model "
        "layer's plant (its C twin where papwc has it) with the logged force replayed; "
        "`scipy.optimize.least_squares`; 95 % intervals from the Jacobian at the optimum "
        "(Student's t).",
        "5. Deviations: the Stribeck curve, the lag and the friction ripple (its wavelength "
        "searched over a grid first) are fitted together, each then tested against the "
        "model without it (every other parameter free): kept when the F-test of the nested "
        "models has p < 0.01 and its parameters' intervals exclude 0, the least "
        "significant dropped first. Where the model depends on where a stick breaks away "
        "(Stribeck, a lag), it is fitted once more with each sliding move at its own draw "
        "of random stiction.",
        "", "## Deviations tried", "",
        "| model | residual sum of squares (m^2) | samples | F | p | chosen | why |",
        "|---|---|---|---|---|---|---|",
    ]
    for tr in ident.trials:
        lines.append(f"| {tr.label} | {tr.rss:.4g} | {tr.n} | {_g(tr.f_stat)} | "
                     f"{_g(tr.p_value)} | {'yes' if tr.chosen else 'no'} | {tr.why or '-'} |")
    tried = {d.name for d in DEVIATIONS}
    lines += ["", "Chosen: " + (", ".join(ident.chosen) if ident.chosen else
                                "none (Eq. (1) explains the log within its noise)") + ".", "",
              "Not tried:"]
    lines += [f"- {name}: {why}" for name, why in NOT_TRIED if name not in tried]
    if ident.ripple_peaks:
        lines += ["", "The friction ripple's wavelength, searched over a grid (the share of the "
                  "residual of Eq. (1) a ripple of that wavelength removes, to first order):", "",
                  "| wavelength (mm) | amplitude | phase (rad) | share |", "|---|---|---|---|"]
        lines += [f"| {p.wavelength * 1e3:.6g} | {p.amplitude:.4g} | {p.phase:.4g} | "
                  f"{p.share:.2%} |" for p in ident.ripple_peaks]
    lines += ["", "## Stiction band", ""]
    if ident.band is None:
        lines.append("None: too few breakaways from rest by a one-sample pulse (see Notes).")
    else:
        from papwc.identify.band import COVERAGE, NEXT_DRAWS

        b = ident.band
        near = sum(1 for br in ident.breakaways if br.low > 0.0)
        lines += [
            f"Breakaway forces (N, the ripple's factor removed): {b.sticks} draws, {near} of "
            "them from one-sample pulses just above a force the stick held (the force at "
            "which each broke away: where the identified plant moves as far as the table "
            "did, or the bracket's middle on Eq. (1)), the others the sliding moves' own "
            "draws, placed by those.", "",
            "| | N |", "|---|---|",
            f"| lowest seen | {b.lowest:.6g} |", f"| highest seen | {b.highest:.6g} |",
            f"| the band for the next draws: low | {b.low:.6g} |",
            f"| the band for the next draws: high | {b.high:.6g} |",
            f"| f_s (its middle) | {b.f_s:.6g} [{b.f_s_low:.6g}, {b.f_s_high:.6g}] |",
            f"| f_s_spread | {b.spread:.4g} [{b.spread_low:.4g}, {b.spread_high:.4g}] |", "",
            f"The band for the next draws holds the next {NEXT_DRAWS} draws all together with "
            f"probability {COVERAGE:g} where the draws are uniform (as random stiction draws "
            f"them): it extends {b.factor:.3g} times the range seen beyond each end "
            f"(papwc.identify.band)."]
    if ident.notes:
        lines += ["", "Notes:"] + [f"- {note}" for note in ident.notes]
    verdict = "within" if ident.replay_rms <= ident.replay_bound else "NOT within"
    count = (f" = {ident.replay_rms / motion.resolution:.3g} counts"
             if motion.resolution > 0 else "")
    lines += [
        "", "## Replay", "",
        f"The whole log simulated with the identified plant from its first position "
        f"(force replayed, encoder count applied, no noise): rms difference "
        f"{ident.replay_rms:.3g} m{count}, {verdict} the bound {ident.replay_bound:.3g} m "
        "(3 counts, twice the noise, or 1 nm). Output error rms over the moves: "
        f"{ident.residual_rms:.3g} m.", "",
        "![measured and simulated position](position.png)", "",
        "![residual](residual.png)", "",
        "![force-velocity points and the fitted friction curve](friction.png)", "",
    ]
    return "\n".join(lines)
