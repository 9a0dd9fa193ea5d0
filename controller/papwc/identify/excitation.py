"""The excitation applied to a machine to identify it, and its application to a plant or an FMU.

The design (:func:`design`), for an expected plant (``m``, ``f_c``, ``f_s``, ``c``) that
may be off by up to :data:`SPREAD` (+-50 %) in each parameter, is a force per sample:

1. a rest of :data:`LEAD_SAMPLES` samples;
2. a staircase of one-sample pulses whose heights rise geometrically by
   :data:`LEVEL_RATIO` from ``0.4*f_s`` to ``min(f_p_max, 1.6*f_s)``, alternately
   positive and negative (the plant is symmetric: each direction tests every other
   level), each followed by a rest long enough for every plant within the spread to
   stop: the largest height that held the table and the smallest that moved it bracket
   the breakaway force to one step of the staircase;
3. repeated until ``duration``: pulses of :data:`SLIDE_HEIGHTS` heights and
   :data:`SLIDE_WIDTHS` widths (samples), each followed by its mirror image, with rests
   in between: sliding at many speeds and accelerations, for ``m``, ``f_c`` and ``c``
   and the deviations. A width whose move would exceed half the travel on some plant
   within the spread is left out.

Each move is followed by its mirror image, so the table stays near its start; the design
is refused if any plant within the spread would leave ``+-travel``.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from papwc.identify import IdentifyError
from papwc.identify.log_file import Columns, Log
from papwc.model.plant import PLANT_DEFAULTS
from papwc.model.stickslip import step as exact_step

__all__ = [
    "LEAD_SAMPLES",
    "LEVEL_RATIO",
    "SLIDE_HEIGHTS",
    "SLIDE_WIDTHS",
    "SPREAD",
    "apply_to_fmu",
    "apply_to_plant",
    "check_fmu",
    "design",
    "excitation_rows",
]

#: Relative spread of each expected parameter the design holds for (+-50 %).
SPREAD = 0.5
#: Ratio of two heights of the staircase: the breakaway force is bracketed to 0.4 %.
LEVEL_RATIO = 1.004
#: Samples at rest at the start.
LEAD_SAMPLES = 10
#: Heights of the sliding pulses, as fractions of the way from the staircase's top to f_p_max.
SLIDE_HEIGHTS = (0.0, 0.5, 1.0)
#: Widths of the sliding pulses, samples.
SLIDE_WIDTHS = (2, 5, 10, 20, 40)
#: Samples of rest after the slowest plant has stopped.
REST_MARGIN = 4


def _corners(expected: Mapping[str, float]) -> list[tuple[float, float, float]]:
    """(m, f_c, c) of the corners of the spread around the expected plant."""
    lo, hi = 1.0 - SPREAD, 1.0 + SPREAD
    return [(expected["m"] * a, expected["f_c"] * b, expected["c"] * d)
            for a, b, d in itertools.product((lo, hi), repeat=3)]


def _move(u: Sequence[float], h: float, m: float, f_c: float, c: float,
          limit: int = 100_000) -> tuple[float, int]:
    """Distance (m) a pulse moves a plant that breaks away at once, and samples to rest."""
    x = v = 0.0
    k = 0
    for k, force in enumerate(itertools.chain(u, itertools.repeat(0.0, limit)), start=1):
        x, v = exact_step(x, v, force, h, m, f_c, f_c, c)
        if v == 0.0 and k >= len(u):
            break
    return abs(x), k - len(u)


def design(h: float, f_p_max: float, travel: float, duration: float,
           expected: Mapping[str, float] | None = None) -> np.ndarray:
    """The force to apply at each sample, N (see the module's description).

    Parameters
    ----------
    h : float
        Sample period, s.
    f_p_max : float
        Largest force to apply, N.
    travel : float
        The table must stay within +-travel (m) of its start.
    duration : float
        Length of the excitation, s.
    expected : mapping, optional
        Expected ``m`` (kg), ``f_c``, ``f_s`` (N), ``c`` (N.s/m); default: the plant's
        defaults (Table 1).

    Raises
    ------
    IdentifyError
        If the design cannot be made: f_p_max does not exceed the lowest breakaway,
        the travel is too short for the moves, or the duration too short for the
        staircase and one round of sliding pulses.
    """
    p = {k: float(PLANT_DEFAULTS[k]) for k in ("m", "f_c", "f_s", "c")}
    p.update(expected or {})
    f_lo = 0.4 * p["f_s"]
    f_hi = min(f_p_max, (1.0 + SPREAD + 0.1) * p["f_s"])
    if not f_p_max > (1.0 + 0.1) * p["f_s"]:
        raise IdentifyError(f"--f-p-max {f_p_max!r} N: must exceed 1.1*f_s = "
                            f"{1.1 * p['f_s']!r} N (the expected breakaway) to move the table")
    corners = _corners(p)
    levels = [f_lo * LEVEL_RATIO**j for j in range(
        int(math.log(f_hi / f_lo) / math.log(LEVEL_RATIO)) + 2)]
    levels[-1] = f_hi
    # Rests after a one-sample pulse at the top of the staircase.
    worst = [_move([f_hi], h, *corner) for corner in corners]
    rest_a = max(k for _, k in worst) + REST_MARGIN
    if max(d for d, _ in worst) > travel / 2.0:
        raise IdentifyError(f"--travel {travel!r} m: too short for one pulse of {f_hi:.6g} N "
                            f"over one sample ({max(d for d, _ in worst):.3g} m on a plant "
                            "within +-50 % of the expected one); give a longer travel")
    u: list[float] = [0.0] * LEAD_SAMPLES
    for j, level in enumerate(levels):
        u += [level if j % 2 == 0 else -level] + [0.0] * rest_a
    heights = sorted({f_hi + s * (f_p_max - f_hi) for s in SLIDE_HEIGHTS})
    cycle: list[float] = []
    for width in SLIDE_WIDTHS:
        for height in heights:
            moves = [_move([height] * width, h, *corner) for corner in corners]
            if max(d for d, _ in moves) > travel / 2.0:
                continue
            rest = max(k for _, k in moves) + REST_MARGIN
            cycle += [height] * width + [0.0] * rest + [-height] * width + [0.0] * rest
    if not cycle:
        raise IdentifyError(f"--travel {travel!r} m: too short for the sliding pulses; give a "
                            "longer travel")
    n = int(round(duration / h))
    if len(u) + len(cycle) > n:
        raise IdentifyError(f"--duration {duration!r} s: too short; the staircase and one round "
                            f"of sliding pulses take {(len(u) + len(cycle)) * h:.4g} s")
    while len(u) + len(cycle) <= n:
        u += cycle
    u += [0.0] * (n - len(u))
    out = np.array(u, dtype=float)
    for corner in corners:
        x = v = 0.0
        far = 0.0
        for force in out:
            x, v = exact_step(x, v, force, h, corner[0], corner[1], corner[1], corner[2])
            far = max(far, abs(x))
        if far > travel:
            raise IdentifyError(f"--travel {travel!r} m: a plant within +-50 % of the expected "
                                f"one would move {far:.3g} m from the start; give a longer "
                                "travel or a lower --f-p-max")
    return out


def excitation_rows(u: np.ndarray, h: float) -> list[dict[str, float]]:
    """Rows ``time`` (s), ``u`` (N) of the excitation CSV."""
    return [{"time": k * h, "u": float(f)} for k, f in enumerate(u)]


def apply_to_plant(u: np.ndarray, h: float, params: Mapping[str, Any]) -> Log:
    """Apply the force ``u`` to :class:`papwc.model.dynamics.Plant` and log it.

    Returns a log of ``len(u) + 1`` samples (the last force is 0); the position is the
    plant's ``x_meas`` (its encoder). Raises IdentifyError if the plant refuses a step.
    """
    from papwc.model.dynamics import Plant

    plant = Plant(params)
    x = [plant.x_meas()]
    for k, force in enumerate(u):
        reason = plant.step(float(force), h)
        if reason is not None:
            raise IdentifyError(f"the plant refused the step at t = {k * h!r} s: {reason}")
        x.append(plant.x_meas())
    n = len(u) + 1
    return Log(np.arange(n) * h, np.append(np.asarray(u, dtype=float), 0.0), np.array(x), None,
               float(h), "the plant", Columns(position="x"))


def _check_variables(kinds: Mapping[str, tuple[str, str]], where: str, force: str,
                     position: str) -> None:
    """Refuse (FmuError) an FMU whose ``force`` is not a Real input or whose ``position``
    is not a Real output; ``kinds`` maps each variable to (causality, type)."""
    from papwc.errors import FmuError

    for name, want, what, option in ((force, "input", "force", "--force-variable"),
                                     (position, "output", "position", "--position-variable")):
        causality, typ = kinds.get(name, ("", ""))
        if typ != "Real":
            raise FmuError(f"{where}: has no Real variable {name!r} (the {what}; {option})")
        if causality != want:
            article = "an" if causality[:1] in ("i", "o") else "a"
            raise FmuError(f"{where}: {option} {name}: {name} is {article} {causality} of the FMU; "
                           f"the {what} is a Real {want} (e.g. "
                           f"{'u' if want == 'input' else 'x_meas'})")


def check_fmu(fmu: str | os.PathLike, start_values: Mapping[str, Any], force: str = "u",
              position: str = "x_meas") -> None:
    """Refuse, before anything is written, an FMU that cannot be identified (FmuError): not
    FMI 2.0 Co-Simulation or not loadable, ``force`` not a Real input, ``position`` not a
    Real output, a start value of a variable it lacks, or start values it refuses.

    The FMU is opened as the master opens it and initialized with ``start_values`` once
    (its own checks of the parameters), then freed.
    """
    from papwc.errors import FmuError
    from papwc.master.fmu import FmuSlave

    path = Path(fmu)
    if not path.is_file():
        raise FmuError(f"FMU file {str(path)!r} " + ("is not a file" if path.exists()
                                                      else "does not exist"))
    with FmuSlave(path, name="check", where=str(path)) as slave:
        kinds = {name: (v.causality, v.type) for name, v in slave.vars.items()}
        _check_variables(kinds, str(path), force, position)
        for name in start_values:
            if name not in kinds:
                raise FmuError(f"{path}: --start-values: the FMU has no variable {name!r}")
            if kinds[name][0] not in ("parameter", "input"):
                raise FmuError(f"{path}: --start-values: {name} is an {kinds[name][0]} of the "
                               "FMU; start values are for its parameters (and inputs)")
        slave.set_start_values(dict(start_values))
        try:
            slave.initialize(0.0)
        except FmuError as exc:
            raise FmuError(f"{path}: --start-values: the FMU refused them: "
                           f"{str(exc).split(': ', 1)[-1]}") from None


def apply_to_fmu(fmu: str | os.PathLike, u: np.ndarray, h: float,
                 start_values: Mapping[str, Any], force: str = "u",
                 position: str = "x_meas") -> Log:
    """Apply the force ``u`` to an FMI 2.0 Co-Simulation FMU and log it.

    The FMU gets ``start_values``, is initialized at t = 0 and stepped by ``h`` with
    ``force`` (a Real input) held over each step; ``position`` (a Real output) is read at
    every communication point. Ctrl-C stops it between two steps (KeyboardInterrupt).

    Raises
    ------
    papwc.errors.FmuError
        If the FMU cannot be loaded, has no such variable, or refuses a call.
    """
    from papwc.interrupts import deferred_interrupt
    from papwc.master.fmu import FmuSlave
    from papwc.master.observers import StepGuard

    slave = FmuSlave(fmu)
    try:
        _check_variables({name: (v.causality, v.type) for name, v in slave.vars.items()},
                         str(fmu), force, position)
        slave.set_start_values(dict(start_values))
        slave.watch([position])
        set_force = slave.input_setter([force])
        slave.initialize(0.0)
        x = [float(slave.values[0])]
        guard = StepGuard()
        with deferred_interrupt():
            for k, f in enumerate(u):
                set_force(float(f))
                slave.do_step(k * h, h)
                guard.check((k + 1) * h)
                x.append(float(slave.values[0]))
    finally:
        slave.close()
    n = len(u) + 1
    return Log(np.arange(n) * h, np.append(np.asarray(u, dtype=float), 0.0), np.array(x), None,
               float(h), str(fmu), Columns(position="x"))
