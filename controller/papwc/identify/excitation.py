"""The excitation applied to a machine to identify it, and its application to a plant or an FMU.

The design (:func:`design`), for an expected plant (``m``, ``f_c``, ``f_s``, ``c``) that
may be off by up to :data:`SPREAD` (+-50 %) in each parameter, is a force per sample:

1. a rest of :data:`LEAD_SAMPLES` samples;
2. :data:`TEETH` *teeth*, each followed by one sliding pulse of the walk (3.): a tooth is a
   staircase of one-sample pulses whose heights rise geometrically by :data:`TOOTH_RATIO`
   from ``TOOTH_LOW*f_s`` to ``min(f_p_max, TOOTH_HIGH*f_s)``, alternately positive and
   negative (the plant is symmetric), each followed by :data:`TOOTH_GAP` sample(s) of no
   force, then a rest long enough for every plant within the spread to stop. A tooth starts
   on a stuck table and rises until it breaks it away: each tooth brackets the breakaway force
   of one stick (the draw of random stiction, :mod:`papwc.model.effects.stiction`, at the
   place the walk left the table), and the band of those draws (:mod:`.band`) needs
   :func:`papwc.identify.band.sticks_needed` of them. The teeth's levels are staggered by
   ``1/TEETH`` of a step from one tooth to the next, so that together they bracket a fixed
   breakaway force far finer than one step;
3. then, until ``duration``, the *walk*: single pulses of :data:`WALK_HEIGHTS` heights and
   :data:`WALK_WIDTHS` widths (samples) in turn, each from rest and followed by a rest
   long enough for every plant within the spread to stop, all in one direction until the
   plant of the spread that moves farthest would pass ``0.8*travel``, then back: sliding at
   many speeds and accelerations over many places, for ``m``, ``f_c``, ``c`` and the
   deviations, the friction ripple's wavelength among them (:mod:`.ripple`). A width whose
   move would exceed a quarter of the travel on some plant within the spread is left out.

The design is refused if any plant within the spread would leave ``+-travel``, or if the
duration does not hold the teeth and two rounds of the walk's pulses.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from papwc.identify import IdentifyError
from papwc.identify.log_file import Columns, Log
from papwc.model.plant import PLANT_DEFAULTS
from papwc.model.stickslip import step as exact_step

__all__ = [
    "LEAD_SAMPLES",
    "SPREAD",
    "TEETH",
    "TOOTH_GAP",
    "TOOTH_HIGH",
    "TOOTH_LOW",
    "TOOTH_RATIO",
    "WALK_HEIGHTS",
    "WALK_WIDTHS",
    "Design",
    "apply_to_fmu",
    "apply_to_plant",
    "check_fmu",
    "design",
    "design_plan",
    "excitation_rows",
]

#: Relative spread of each expected parameter the design holds for (+-50 %).
SPREAD = 0.5
#: Ratio of two levels of a tooth: a tooth brackets the breakaway of its stick to 1 %.
TOOTH_RATIO = 1.01
#: A tooth rises from this fraction of the expected f_s ...
TOOTH_LOW = 0.6
#: ... to this one (or f_p_max): the breakaway drawn within +-15 % of f_s on a friction
#: ripple of +-15 %, through an actuator lag of up to half the sample period (whose force
#: reaches 1 - exp(-2) of one sample's height), with a margin.
TOOTH_HIGH = 1.6
#: Samples of no force after each level of a tooth.
TOOTH_GAP = 1
#: Samples at rest at the start.
LEAD_SAMPLES = 10
#: Heights of the walk's pulses, as fractions of the way from the teeth's top to f_p_max.
WALK_HEIGHTS = (0.0, 0.5, 1.0)
#: Widths of the walk's pulses, samples.
WALK_WIDTHS = (1, 2, 3, 5, 8, 12)
#: Samples of rest after the slowest plant has stopped.
REST_MARGIN = 4
#: The walk turns back where the plant of the spread that moves farthest would pass this
#: fraction of the travel.
WALK_TURN = 0.8


def _teeth() -> int:
    from papwc.identify.band import sticks_needed

    return sticks_needed()


#: Teeth of the design: the sticks the band needs (:func:`papwc.identify.band.sticks_needed`).
TEETH = _teeth()


@dataclass(frozen=True)
class Design:
    """What :func:`design_plan` makes: the force and where its parts are.

    Attributes
    ----------
    u : ndarray
        Force per sample, N.
    h : float
        Sample period, s.
    teeth : int
        Teeth (sticks bracketed for the band).
    teeth_end : int
        Sample where the teeth (with their walk pulses between them) end.
    levels : int
        Levels of one tooth.
    walk_pulses : int
        Pulses of the walk, those between the teeth included.
    """

    u: np.ndarray
    h: float
    teeth: int
    teeth_end: int
    levels: int
    walk_pulses: int

    def summary(self) -> str:
        """One line: the design's parts and their durations."""
        return (f"{self.teeth} teeth of {self.levels} one-sample levels (the stiction band "
                f"needs {self.teeth} sticks) in the first {self.teeth_end * self.h:.4g} s, "
                f"{self.walk_pulses} sliding pulses in all, {self.u.size * self.h:.4g} s")


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

    Returns
    -------
    ndarray
        ``round(duration/h)`` forces, N (:func:`design_plan` says where its parts are).

    Raises
    ------
    IdentifyError
        If the design cannot be made: f_p_max does not exceed the lowest breakaway,
        the travel is too short for the moves, or the duration too short for the
        teeth and two rounds of the walk's pulses.
    """
    return design_plan(h, f_p_max, travel, duration, expected).u


def design_plan(h: float, f_p_max: float, travel: float, duration: float,
                expected: Mapping[str, float] | None = None) -> Design:
    """:func:`design`, with where its parts are (:class:`Design`); the same parameters."""
    p = {k: float(PLANT_DEFAULTS[k]) for k in ("m", "f_c", "f_s", "c")}
    p.update(expected or {})
    f_lo = TOOTH_LOW * p["f_s"]
    f_hi = min(f_p_max, TOOTH_HIGH * p["f_s"])
    if not f_p_max > (1.0 + 0.1) * p["f_s"]:
        raise IdentifyError(f"--f-p-max {f_p_max!r} N: must exceed 1.1*f_s = "
                            f"{1.1 * p['f_s']!r} N (the expected breakaway) to move the table")
    corners = _corners(p)
    levels = int(math.log(f_hi / f_lo) / math.log(TOOTH_RATIO)) + 1
    # The rest after a tooth: a one-sample pulse at its top on the slowest plant.
    worst = [_move([f_hi], h, *corner) for corner in corners]
    rest_tooth = max(k for _, k in worst) + REST_MARGIN
    if max(d for d, _ in worst) > travel / 4.0:
        raise IdentifyError(f"--travel {travel!r} m: too short for one pulse of {f_hi:.6g} N "
                            f"over one sample ({max(d for d, _ in worst):.3g} m on a plant "
                            "within +-50 % of the expected one); give a longer travel")
    heights = sorted({f_hi + s * (f_p_max - f_hi) for s in WALK_HEIGHTS})
    kinds: list[tuple[int, float, float, int]] = []
    for width in WALK_WIDTHS:
        for height in heights:
            moves = [_move([height] * width, h, *corner) for corner in corners]
            far = max(d for d, _ in moves)
            if far > travel / 4.0:
                continue
            kinds.append((width, height, far, max(k for _, k in moves) + REST_MARGIN))
    if not kinds:
        raise IdentifyError(f"--travel {travel!r} m: too short for the sliding pulses; give a "
                            "longer travel")
    walk = _Walk(kinds, WALK_TURN * travel)
    u: list[float] = [0.0] * LEAD_SAMPLES
    for tooth in range(TEETH):
        for i in range(levels):
            level = min(f_lo * TOOTH_RATIO ** (i + tooth / TEETH), f_hi)
            u += [level if i % 2 == 0 else -level] + [0.0] * TOOTH_GAP
        u += [0.0] * rest_tooth
        u += walk.pulse()
    teeth_end = len(u)
    n = int(round(duration / h))
    rounds = 2 * len(kinds) - TEETH
    need = teeth_end + sum(walk.peek(j) for j in range(max(rounds, 0)))
    if need > n:
        raise IdentifyError(f"--duration {duration!r} s: too short; the {TEETH} teeth the "
                            f"stiction band needs and two rounds of the sliding pulses take "
                            f"{need * h:.4g} s")
    while True:
        piece = walk.pulse()
        if len(u) + len(piece) > n:
            break
        u += piece
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
    return Design(out, float(h), TEETH, teeth_end, levels, walk.count - 1)


class _Walk:
    """The walk's pulses in turn, one direction until the farthest plant would pass ``turn``
    (m), then back."""

    def __init__(self, kinds: list[tuple[int, float, float, int]], turn: float) -> None:
        self.kinds = kinds
        self.turn = turn
        self.count = 0
        self.far = 0.0
        self.direction = 1.0

    def peek(self, j: int) -> int:
        """Samples of the ``j``-th pulse from now (with its rest)."""
        width, _, _, rest = self.kinds[(self.count + j) % len(self.kinds)]
        return width + rest

    def pulse(self) -> list[float]:
        """The next pulse and its rest (forces, N)."""
        width, height, far, rest = self.kinds[self.count % len(self.kinds)]
        self.count += 1
        if abs(self.far + self.direction * far) > self.turn:
            self.direction = -self.direction
        self.far += self.direction * far
        return [self.direction * height] * width + [0.0] * rest


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
                 position: str = "x_meas", unzip_dir: str | os.PathLike | None = None) -> Log:
    """Apply the force ``u`` to an FMI 2.0 Co-Simulation FMU and log it.

    The FMU gets ``start_values``, is initialized at t = 0 and stepped by ``h`` with
    ``force`` (a Real input) held over each step; ``position`` (a Real output) is read at
    every communication point. Ctrl-C stops it between two steps (KeyboardInterrupt).
    ``unzip_dir``: an extracted copy of the FMU to use (a battery worker's).

    Raises
    ------
    papwc.errors.FmuError
        If the FMU cannot be loaded, has no such variable, or refuses a call.
    """
    from papwc.interrupts import deferred_interrupt
    from papwc.master.fmu import FmuSlave
    from papwc.master.observers import StepGuard

    slave = FmuSlave(fmu, unzip_dir=unzip_dir)
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
