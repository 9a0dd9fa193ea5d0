"""Rest detection of a controller that reads only the measured position.

At rest means the reading has stayed within a band of width B over a dwell of D
sample intervals. B and D are ``rest_band`` and ``rest_samples`` (0 and 1 by
default: exactly unchanged over one interval); with ``rest_auto`` they grow to
``6*sigma`` and 5 samples once encoder noise sigma has been measured, and D to
2.5 periods of ``f_mode``. The noise sigma is estimated from samples at rest:
from the spread of the readings over each rest, and, before any rest could be
seen, from force-free windows of 16 readings whose net drift is within 3 times
their sample-to-sample scatter (a moving mass drifts by more). With an ideal,
noiseless encoder the readings at rest are equal, sigma stays 0 and the test is
the one of rest_band and rest_samples.

A machine whose slowest mode the controller is not told (``f_mode`` = 0; a told one is
not looked for) still shows it
when it rings: after a force the reading goes forward and then back (a mass under
friction alone moves one way only). A force-free reading that has turned back by more
than :data:`RING_LEG` and the band is *ringing seen*: the dwell becomes
:data:`RING_PERIODS` periods of the ring (its period taken as the force-free samples
until then, about three quarters of one), kept for the controller's life, and the
controller shrinks its pulses (:class:`~.trust.TrustRegion`).

While at rest the readings are averaged: :meth:`RestDetector.x_hat` is the mean
of the readings since the rest began, whose uncertainty is ``sigma/sqrt(N)``.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["BAND_SIGMAS", "NOISE_DRIFT", "NOISE_DWELL", "NOISE_MEMORY", "NOISE_WINDOW",
           "RING_LEG", "RING_PERIODS", "RestDetector"]

#: Readings of the force-free window in which noise is looked for before any rest.
NOISE_WINDOW = 16
#: Largest net drift of that window, in units of sqrt(2)*sigma of its scatter.
NOISE_DRIFT = 3.0
#: Band of rest detection in units of the measured noise.
BAND_SIGMAS = 6.0
#: Dwell of rest detection with measured noise, sample intervals.
NOISE_DWELL = 5
#: Rests over which the noise estimate is averaged (a running mean over at most this many).
NOISE_MEMORY = 16
#: How far a force-free reading must turn back to show ringing, m: beyond the noise of
#: the encoders in use (0.4 um rms at most in the batteries) and beyond what LuGre
#: bristles give back when the table stops (about f_s/sigma_0: 7.5 um at most over the
#: ranges of realism_mc_lugre.toml).
RING_LEG = 1e-5
#: Dwell after ringing was seen, in periods of the ring (``MODE_PERIODS`` of the model layer).
RING_PERIODS = 2.5
#: Longest dwell learned from ringing, sample intervals.
RING_DWELL_MAX = 1000


class RestDetector:
    """Band, dwell, noise estimate and the averaged reading at rest.

    Parameters
    ----------
    rest_band : float
        Smallest band, m (``rest_band`` setting).
    rest_samples : int
        Smallest dwell, sample intervals (``rest_samples`` setting).
    rest_auto : bool
        Whether band and dwell grow with the measured noise and ``mode_samples``.
    mode_samples : int
        Dwell from the machine's slowest mode, sample intervals (0: rigid).

    Attributes
    ----------
    sigma2 : float
        Encoder noise variance measured at rest, m**2 (0 until measured).
    noise_rests : int
        Rests (or quiet windows) the noise estimate averages, at most ``NOISE_MEMORY``.
    anchor, lo, hi : float
        First, lowest and highest reading of the present run within the band, m.
    sum, sum2 : float
        Sums of the readings' deviations from ``anchor`` and of their squares (m, m**2).
    n : int
        Readings in the present run.
    look : int
        Run length at which the next decision on averaged readings is due.
    ring : list of float
        The last ``NOISE_WINDOW`` force-free readings (a ring), m.
    ring_n : int
        Force-free readings put into the ring since it was last emptied.
    dir : float
        Last force-free change of the reading (its sign is the direction), m.
    turns : int
        How often the force-free reading turned back.
    band, dwell : float, int
        The present test (derived from the settings and ``sigma2``).
    ring_dwell : int
        Dwell learned from ringing seen, sample intervals (0: none seen); kept across
        maneuvers.
    x_turn : float
        Reading at the last turn of the force-free reading (or where it began), m.
    legs : int
        1 once the reading has turned back by more than ``RING_LEG`` and the band since
        the last force (ringing seen), else 0.
    since_force, since_turn : int
        Force-free readings since the last force and since the last turn.
    """

    #: Names of the state (:meth:`state`), in order.
    FIELDS = ("sigma2", "noise_rests", "anchor", "lo", "hi", "sum", "sum2", "n", "look",
              "ring", "ring_n", "dir", "turns", "ring_dwell", "x_turn", "legs", "since_force",
              "since_turn")
    _INTS = frozenset(("noise_rests", "n", "look", "ring_n", "turns", "ring_dwell", "legs",
                       "since_force", "since_turn"))

    def __init__(self, rest_band: float, rest_samples: int, rest_auto: bool,
                 mode_samples: int) -> None:
        self.rest_band = float(rest_band)
        self.rest_samples = int(rest_samples)
        self.auto = bool(rest_auto)
        self.mode_samples = int(mode_samples)
        self.sigma2 = 0.0
        self.noise_rests = 0
        self.ring_dwell = 0
        self.update_test()
        self.reset()

    def reset(self) -> None:
        """A new maneuver: no run, an empty ring (the noise estimate is kept)."""
        self.anchor = math.nan
        self.lo = self.hi = 0.0
        self.sum = self.sum2 = 0.0
        self.n = 0
        self.look = 0
        self.ring = [0.0] * NOISE_WINDOW
        self.ring_n = 0
        self.forget_direction()

    # -- the test ----------------------------------------------------------------------
    def update_test(self) -> None:
        """Band (m) and dwell (sample intervals) from the settings and what was measured."""
        band, dwell = self.rest_band, self.rest_samples
        if self.auto:
            if self.sigma2 > 0.0:
                band = max(band, BAND_SIGMAS * math.sqrt(self.sigma2))
                dwell = max(dwell, NOISE_DWELL)
            dwell = max(dwell, self.mode_samples)
        dwell = max(dwell, self.ring_dwell)
        self.band, self.dwell = band, dwell

    # -- runs of readings --------------------------------------------------------------
    def start_run(self, x: float) -> None:
        """A new run of readings begins with x (m)."""
        self.anchor = x
        self.lo = self.hi = x
        self.sum = self.sum2 = 0.0
        self.n = 1
        self.look = 0

    def read(self, x: float, force_free: bool) -> bool:
        """Take the reading x (m); whether the mass is at rest by band and dwell.

        A run that grows beyond the band ends (its spread updates the noise estimate
        if it was a force-free rest, ``force_free``) and a new one starts at x.
        """
        lo, hi = self.lo, self.hi
        if x == self.anchor and lo == hi:  # the reading unchanged
            self.n += 1
            return self.n > self.dwell
        if x < lo:
            lo = x
        if x > hi:
            hi = x
        if hi - lo > self.band:
            if self.n > NOISE_DWELL and self.sum2 > 0.0:
                self.end_run(force_free)
            self.start_run(x)
            return False
        self.lo, self.hi = lo, hi
        dev = x - self.anchor
        self.sum += dev
        self.sum2 += dev * dev
        self.n += 1
        return self.n > self.dwell

    def x_hat(self) -> float:
        """Mean of the readings of the present run (the position at rest), m."""
        if self.sum == 0.0:
            return self.anchor
        return self.anchor + self.sum / self.n

    def sigma_mean(self) -> float:
        """Standard error of :meth:`x_hat`, m."""
        return math.sqrt(self.sigma2 / self.n)

    def sigma_move(self) -> float:
        """Standard deviation of a displacement measured as the difference of two rests of
        the dwell, m."""
        return math.sqrt(2.0 * self.sigma2 / max(self.dwell + 1, 1))

    def end_run(self, force_free: bool) -> None:
        """A run of readings ends: if it was a force-free rest, its spread updates the noise."""
        n = self.n
        if n > NOISE_DWELL and self.sum2 > 0.0 and self.auto and force_free:
            mean = self.sum / n
            var = max(self.sum2 / n - mean * mean, 0.0) * n / (n - 1)
            self.add_noise(var)

    def add_noise(self, var: float) -> None:
        """Average the variance var (m**2) of one rest into the noise estimate."""
        self.noise_rests = min(self.noise_rests + 1, NOISE_MEMORY)
        self.sigma2 += (var - self.sigma2) / self.noise_rests
        self.update_test()

    # -- force-free readings -----------------------------------------------------------
    def force_free(self, x: float, dx: float, at_rest: bool) -> bool:
        """Take a force-free reading x (m, dx since the last); at rest, with noise in view.

        A mass moves one way only, so readings that turn back twice show noise (or a
        vibration); until the noise is measured, equal readings show a rest only when
        many in a row are.
        """
        self.ring[self.ring_n % NOISE_WINDOW] = x
        self.ring_n += 1
        self.since_force += 1
        self.since_turn += 1
        if self.since_force == 1:  # the first force-free reading: where it began
            self.x_turn = x - dx
        if dx != 0.0:
            if dx * self.dir < 0.0:
                self.turns += 1
                self.x_turn = x - dx
                self.since_turn = 1
            self.dir = dx
            if self.turns and not self.legs and self.mode_samples == 0:
                self._turned_back(x)
        if self.auto:
            if at_rest and self.turns >= 2 and self.sigma2 == 0.0:
                # noise makes equal readings by chance, not many in a row
                at_rest = self.n > NOISE_DWELL and self.lo == self.hi
            if not at_rest and self.ring_n >= NOISE_WINDOW:
                at_rest = self.quiet_window()
        return at_rest

    def _turned_back(self, x: float) -> None:
        """After a turn at x_turn, the reading x (m): ringing if it went back far enough."""
        if abs(x - self.x_turn) <= max(RING_LEG, self.band):
            return
        self.legs = 1
        if self.auto:
            # forward, back and this far: about three quarters of a period after a force,
            # at most four times the samples since the turn (after a long coast)
            period = min(self.since_force, 4 * (self.since_turn + 1))
            dwell = min(int(math.ceil(RING_PERIODS * max(period, 2))), RING_DWELL_MAX)
            if dwell > self.ring_dwell:
                self.ring_dwell = dwell
                self.update_test()

    def ringing(self) -> bool:
        """Whether ringing was ever seen (a mode the settings did not name)."""
        return self.ring_dwell > 0

    def forget_direction(self) -> None:
        """A force is applied: the force-free direction and its turns start anew."""
        self.dir = 0.0
        self.turns = 0
        self.x_turn = 0.0
        self.legs = 0
        self.since_force = 0
        self.since_turn = 0

    def quiet_window(self) -> bool:
        """The last force-free readings drift no more than their scatter: noise, at rest.

        If so, their scatter becomes (part of) the noise estimate and the run of
        readings restarts with the present one, so that the wider band applies.
        """
        ring, k = self.ring, self.ring_n
        first = ring[k % NOISE_WINDOW]
        last = ring[(k - 1) % NOISE_WINDOW]
        s2 = 0.0
        prev = first
        for i in range(1, NOISE_WINDOW):
            x = ring[(k + i) % NOISE_WINDOW]
            s2 += (x - prev) ** 2
            prev = x
        if not s2 > 0.0:
            return False
        var = s2 / (2.0 * (NOISE_WINDOW - 1))
        if abs(last - first) > NOISE_DRIFT * math.sqrt(2.0 * var):
            return False
        self.add_noise(var)
        # the window's readings are the present rest; summed one after another from 0.0, as
        # Python 3.11's sum() does (3.12's compensates the rounding: another result, and not
        # the C controller's, fmu_src/PulseController/controller.c)
        self.anchor = first
        self.lo, self.hi = min(ring), max(ring)
        total = total2 = 0.0
        for x in ring:
            total += x - first
        for x in ring:
            total2 += (x - first) ** 2
        self.sum, self.sum2 = total, total2
        self.n = NOISE_WINDOW
        self.look = 0
        self.ring_n = 0
        return True

    def count_idle(self, k: int, x: float) -> None:
        """Count k more readings equal to x (m) into the run and the ring."""
        self.n += k
        ring, start = self.ring, self.ring_n
        for i in range(min(k, NOISE_WINDOW)):
            ring[(start + i) % NOISE_WINDOW] = x
        self.ring_n = start + k

    # -- state -------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The state by name (:attr:`FIELDS`): floats, whole numbers, and the ring."""
        out: dict[str, Any] = {}
        for name in self.FIELDS:
            value = getattr(self, name)
            out[name] = list(value) if name == "ring" else value
        return out

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state`."""
        for name in self.FIELDS:
            value = values[name]
            if name == "ring":
                ring = [float(q) for q in value]
                if len(ring) != NOISE_WINDOW:
                    raise ValueError(f"rest.ring holds {len(ring)} numbers, not {NOISE_WINDOW}")
                self.ring = ring
            else:
                setattr(self, name, int(value) if name in self._INTS else float(value))
        self.update_test()
