"""The base of the pulse controllers: a control law on rest detection, trust region and sequencer.

A pulse controller is built from three parts, each a class with named state:

* :class:`~.rest.RestDetector`: band, dwell, noise estimate, averaged reading;
* :class:`~.trust.TrustRegion`: how far a planned pulse may go, as a fraction of abs(e);
* :class:`~.sequencer.PulseSequencer`: coarse move, hand-over, pulse and wait,
  safeguards, outcome (see that module for the sequence of a maneuver).

A control law subclasses :class:`PulseControllerBase` and implements
:meth:`~PulseControllerBase.plan_pulse` and :meth:`~PulseControllerBase.learn`;
it may predict a pulse's displacement (:meth:`~PulseControllerBase.predict`, its model,
which the trust region judges; :meth:`~PulseControllerBase.reach`, on all its evidence,
which the sequencer's farther-than-the-start test reads),
say how exactly the error must be known before a move
(:meth:`~PulseControllerBase.precision`), add observables in ``estimates`` and
state of its own in :meth:`~PulseControllerBase.law_state`. Its pulses stay inside
the trust region: the displacement planned is at most ``trust()*|e|``.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from ..model.controller_settings import MODE_PERIODS
from .interface import Controller, Mode, Outcome, Reason
from .rest import BAND_SIGMAS, NOISE_DWELL, NOISE_MEMORY, NOISE_WINDOW, RestDetector
from .sequencer import PRECISION_MIN, X_LIMIT, Z_ACT, Z_DECIDE, PulseSequencer
from .settings import ControllerSettings
from .trust import TRUST_FLEXIBLE, TRUST_GOOD, TRUST_GROWTH, TRUST_MIN, TrustRegion

__all__ = [
    "BAND_SIGMAS", "NOISE_DWELL", "NOISE_MEMORY", "NOISE_WINDOW", "PRECISION_MIN",
    "TRUST_FLEXIBLE", "TRUST_GOOD", "TRUST_GROWTH", "TRUST_MIN", "X_LIMIT", "Z_ACT",
    "Z_DECIDE", "CUT_BY_ONE_UP_TO", "Mode", "Outcome", "PulseControllerBase", "Reason",
    "cut_width",
]  # fmt: skip

#: Widest pulse (samples) that :func:`cut_width` cuts one sample at a time; a wider one is
#: halved first (a law without ``t_p_max`` may plan millions of samples on a poor estimate,
#: and cutting those one by one would take longer than a sample).
CUT_BY_ONE_UP_TO = 64


def cut_width(n: int, too_far: Callable[[int], bool]) -> int:
    """The width ``n`` (samples) cut while ``too_far(n)`` and ``n > 1``.

    One sample at a time from at most :data:`CUT_BY_ONE_UP_TO` samples (the largest width
    below ``n`` that is not too far); from a wider pulse, halved first until it is not too
    far or within that width (a shorter pulse than the largest allowed, never a longer one),
    so that the cut takes at most about ``log2(n) + CUT_BY_ONE_UP_TO`` tests.
    """
    while n > 1 and too_far(n):
        n = n // 2 if n > CUT_BY_ONE_UP_TO else n - 1
    return n


class PulseControllerBase(Controller):
    """Base of the pulse controllers: the parts, and the control law's hooks.

    Attributes
    ----------
    rest : RestDetector
        Rest detection.
    trust : TrustRegion
        The trust region; ``trust()`` is the one in force.
    seq : PulseSequencer
        The sequencer; ``mode``, ``pulses``, ``outcome`` and ``outcome_reason`` are its.
    f_p_floor : float
        Amplitude floor of the law, N (PAPWC raises it).
    n_max : int
        Largest pulse width, whole samples.
    mode_samples : int
        Dwell from the machine's slowest mode, sample intervals (0: rigid).

    Parameters
    ----------
    settings : ControllerSettings
        The controller's settings (validated by the caller).
    T : float
        Sample period, s.
    """

    kind = "base"
    #: The sequencer of the kind (a subclass may change its coarse move or its decisions).
    sequencer_class = PulseSequencer

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        super().__init__(settings, T)
        # Largest pulse width in whole samples (t_p_max rounded down, at least one).
        if math.isinf(settings.t_p_max):
            self.n_max = 1 << 30
        else:
            self.n_max = max(1, int(math.floor(settings.t_p_max / self.T + 1e-9)))
        self.f_p_floor = settings.f_p_floor0
        self.guarded = bool(settings.safeguards)
        self.max_pulses = int(settings.max_pulses)
        # Dwell from the slowest mode: MODE_PERIODS periods, in whole samples.
        f_mode = float(settings.f_mode)
        self.mode_samples = (int(math.ceil(MODE_PERIODS / (f_mode * self.T) - 1e-9))
                             if f_mode > 0.0 else 0)
        self.rest = RestDetector(settings.rest_band, settings.rest_samples,
                                 settings.rest_auto, self.mode_samples)
        self.trust = TrustRegion(self.trust0(settings), self.guarded, self.mode_samples > 0)
        self.seq = self.sequencer_class(self, self.rest, self.trust)

    # -- the interface -----------------------------------------------------------------
    def reset(self) -> None:
        """Start a new maneuver from rest; learned estimates are kept."""
        self.seq.reset()

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force u (N) to hold over the next sample.

        Parameters
        ----------
        t : float
            Time of the sample, s.
        x_meas : float
            Measured position, m.
        x_ref : float
            Reference position, m.
        """
        return self.seq.update(x_meas, x_ref)

    @property
    def mode(self) -> int:
        """:class:`Mode` code after the last sample."""
        return self.seq.mode

    @property
    def pulses(self) -> int:
        """Pulses started in this maneuver."""
        return self.seq.pulses

    @property
    def outcome(self) -> int:
        """:class:`Outcome` code of the maneuver so far."""
        return self.seq.outcome

    @property
    def outcome_reason(self) -> int:
        """:class:`Reason` code of the outcome."""
        return self.seq.outcome_reason

    @property
    def idle_samples(self) -> int:
        """Samples only counted since the state was last brought up to date."""
        return self.seq.idle_samples

    @idle_samples.setter
    def idle_samples(self, value: int) -> None:
        if hasattr(self, "seq"):
            self.seq.idle_samples = value

    # -- to implement ------------------------------------------------------------------
    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Pulse for error ``e`` (m): width in samples (>= 1) and signed height (N).

        A height of 0 refuses: the controller stops with the reason ``seq.refusal``.
        """
        raise NotImplementedError

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Take the displacement ``d`` (m) of the pulse (``n`` samples, ``f_p`` N)."""
        raise NotImplementedError

    def predict(self, n: int, f_p: float) -> float:
        """Displacement (m, >= 0, along f_p) the model predicts for the pulse; NaN: no model."""
        return math.nan

    def reach(self, n: int, f_p: float) -> float:
        """Displacement (m, >= 0, along f_p) the pulse is expected to make on the evidence the
        law has (the sequencer fires no pulse that may end farther than it started, should
        it move this over the trust); by default :meth:`predict`."""
        return self.predict(n, f_p)

    @property
    def f_low(self) -> float:
        """Lowest pulse height it plans with now, N: one sample at it is its smallest pulse."""
        return min(self.f_p_floor, self.settings.f_p_max)

    def budget_spent(self) -> bool:
        """Whether this maneuver's pulse budget (``max_pulses``) is spent."""
        return self.seq.pulses >= self.max_pulses

    def precision(self, e: float) -> float:
        """Relative error expected of the move for error e (m): how exactly e need be known."""
        return 0.1

    def law_state(self) -> dict[str, Any]:
        """State of the control law by name (numbers or lists of numbers)."""
        return {"f_p_floor": self.f_p_floor}

    def set_law_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`law_state`."""
        self.f_p_floor = float(values["f_p_floor"])

    # -- state -------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """Everything that evolves, by part and name (``sequencer.mode``, ``rest.ring``, ...)."""
        out: dict[str, Any] = {}
        for part, values in (("sequencer", self.seq.state()), ("rest", self.rest.state()),
                             ("trust", self.trust.state()), ("law", self.law_state())):
            for name, value in values.items():
                out[f"{part}.{name}"] = value
        return out

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state` (ValueError if its names differ)."""
        mine = self.state()
        if set(values) != set(mine):
            missing = sorted(set(mine) - set(values))
            extra = sorted(set(values) - set(mine))
            raise ValueError(f"a {self.kind!r} controller's state: missing {missing}, "
                             f"unknown {extra}")
        self.revision += 1  # the estimates (and f_low) may differ
        parts: dict[str, dict[str, Any]] = {}
        for key, value in values.items():
            part, name = key.split(".", 1)
            parts.setdefault(part, {})[name] = value
        self.seq.set_state(parts["sequencer"])
        self.rest.set_state(parts["rest"])
        self.trust.set_state(parts["trust"])
        self.set_law_state(parts["law"])

    # -- shared pieces -----------------------------------------------------------------
    def width_samples(self, t_p: float) -> int:
        """Pulse width t_p (s) rounded up to whole samples, within [1, n_max]."""
        n_max = self.n_max
        if not math.isfinite(t_p):
            return n_max
        n = math.ceil(t_p / self.T - 1e-9)
        return 1 if n < 1 else n_max if n > n_max else n
