"""The controller interface and the pulse sequencing all pulse controllers share.

A controller sees what a real one sees: the time and the measured position
(an encoder), never the velocity nor the plant's stuck flag. At every sample it
returns the force to hold over the next sample (zero-order hold).

The sequence within one maneuver:

1. *coarse*: PD feedback with Coulomb feed-forward while the error is outside
   ``e_band`` (or the mass moves);
2. once the mass is at rest inside ``e_band``, *pulse* mode: a pulse is planned
   (subclass), applied for whole samples, and followed by *wait* until the
   measured position stops changing; the displacement from the pulse's start to
   that rest is given to the estimator (subclass);
3. *settled* once the mass is at rest with ``|e| <= tolerance``: the output is 0.

Rest is detected from the measured position alone: unchanged (changed by at
most ``rest_band``, 0 by default, more with a noisy sensor) over
``rest_samples`` sample intervals. A pulse is judged not to have moved the mass
only after ``rest_samples + 1`` unchanged intervals following its last sample,
one more than a moving mass needs, so that a loop which delivers the force one
sample late (a co-simulation master stepping plant and controller side by side)
is not mistaken for a pulse that did not move. The mass is assumed at rest when
a maneuver starts.
"""

from __future__ import annotations

import math

from .settings import ControllerSettings


class Mode:
    """Mode codes (the controller FMU's ``mode`` output)."""

    COARSE = 0
    PULSE = 1
    WAIT = 2
    SETTLED = 3
    NAMES = {0: "coarse", 1: "pulse", 2: "wait", 3: "settled"}


class Controller:
    """Base of the pulse controllers: coarse feedback, hand-over and pulse sequencing.

    Subclasses implement :meth:`plan_pulse` and :meth:`learn`, and may add
    observables in :meth:`estimates`.

    Parameters
    ----------
    settings : ControllerSettings
        The controller's settings (validated by the caller).
    T : float
        Sample period, s.
    """

    kind = "base"

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        self.settings = settings
        self.T = float(T)
        # Largest pulse width in whole samples (t_p_max rounded down, at least one).
        if math.isinf(settings.t_p_max):
            self.n_max = 1 << 30
        else:
            self.n_max = max(1, int(math.floor(settings.t_p_max / self.T + 1e-9)))
        self.f_p_floor = settings.f_p_floor0
        self.k_p = settings.k_p_value
        self.k_d = settings.k_d_value
        #: Incremented whenever the estimates may have changed (an observer re-reads
        #: :meth:`estimates` only then).
        self.revision = 0
        self.reset()

    # -- the interface -----------------------------------------------------------------
    def reset(self) -> None:
        """Start a new maneuver from rest; learned estimates are kept."""
        self.mode = Mode.SETTLED  # at rest; decided anew at the first sample
        self.pulses = 0
        self._first = True
        self._x_prev = math.nan
        self._v_hat = 0.0
        self._still = 0
        self._pulse_left = 0
        self._f_pulse = 0.0
        self._n_pulse = 0
        self._x_start = 0.0
        self._waited = 0
        self.last_pulse: tuple[int, float] = (0, 0.0)
        self.last_d = 0.0

    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """Force to hold over the next sample.

        Parameters
        ----------
        t : float
            Time of the sample, s.
        x_meas : float
            Measured position, m.
        x_ref : float
            Reference position, m.

        Returns
        -------
        float
            Force u, N, held until the next sample.
        """
        if self._first:
            at_rest = True
            self._first = False
            self._v_hat = 0.0
        else:
            self._v_hat = (x_meas - self._x_prev) / self.T
            if abs(x_meas - self._x_prev) <= self.settings.rest_band:
                self._still += 1
            else:
                self._still = 0
            at_rest = self._still >= self.settings.rest_samples
        self._x_prev = x_meas
        e = x_ref - x_meas

        if self._pulse_left > 0:
            self._pulse_left -= 1
            return self._f_pulse
        if self.mode == Mode.PULSE:
            self.mode = Mode.WAIT
            self._waited = 0
        if self.mode == Mode.WAIT:
            self._waited += 1
            # A pulse response moves the mass one way only, so "moved" is read off
            # the present position.
            moved = abs(x_meas - self._x_start) > self.settings.rest_band
            if not at_rest or (not moved and self._waited <= self.settings.rest_samples):
                return 0.0
            d = x_meas - self._x_start
            self.last_d = d
            self.learn(self._n_pulse, self._f_pulse, d)
            self.revision += 1
        elif self.mode == Mode.COARSE and not at_rest:
            return self._coarse(e)

        # At rest: settle, pulse, or coarse feedback.
        if abs(e) <= self.settings.tolerance:
            self.mode = Mode.SETTLED
            return 0.0
        if abs(e) > self.settings.e_band:
            self.mode = Mode.COARSE
            return self._coarse(e)
        n, f_p = self.plan_pulse(e)
        self.mode = Mode.PULSE
        self.pulses += 1
        self._n_pulse = n
        self._f_pulse = f_p
        self._pulse_left = n - 1
        self._x_start = x_meas
        self._still = 0
        self.last_pulse = (n, f_p)
        return f_p

    def estimates(self) -> dict[str, float]:
        """Current estimates for recording: at least ``b_hat`` (m/s**2) and ``f_c_hat`` (N)."""
        return {"b_hat": math.nan, "f_c_hat": math.nan}

    # -- to implement ------------------------------------------------------------------
    def plan_pulse(self, e: float) -> tuple[int, float]:
        """Pulse for error ``e`` (m): width in samples (>= 1) and signed height (N)."""
        raise NotImplementedError

    def learn(self, n: int, f_p: float, d: float) -> None:
        """Take the displacement ``d`` (m) of the pulse (``n`` samples, ``f_p`` N)."""
        raise NotImplementedError

    def state(self) -> list[float]:
        """Everything that evolves, as a flat list of floats (FMU state, serialization)."""
        return [
            float(self.mode), float(self.pulses), float(self._first), self._x_prev,
            float(self._still), float(self._pulse_left), self._f_pulse, float(self._n_pulse),
            self._x_start, float(self.last_pulse[0]), self.last_pulse[1], self.last_d,
            self.f_p_floor, self._v_hat, float(self._waited),
        ]  # fmt: skip

    def set_state(self, values: list[float]) -> None:
        """Restore a state returned by :meth:`state`."""
        v = [float(q) for q in values]
        self.mode, self.pulses, self._first = int(v[0]), int(v[1]), bool(v[2])
        self._x_prev, self._still, self._pulse_left = v[3], int(v[4]), int(v[5])
        self._f_pulse, self._n_pulse, self._x_start = v[6], int(v[7]), v[8]
        self.last_pulse = (int(v[9]), v[10])
        self.last_d, self.f_p_floor, self._v_hat = v[11], v[12], v[13]
        self._waited = int(v[14])

    # -- shared pieces -----------------------------------------------------------------
    def _coarse(self, e: float) -> float:
        """PD feedback with Coulomb feed-forward, saturated at f_p_max (N)."""
        u = self.k_p * e - self.k_d * self._v_hat + math.copysign(self.settings.f_c_est, e)
        f_max = self.settings.f_p_max
        return min(max(u, -f_max), f_max)

    def width_samples(self, t_p: float) -> int:
        """Pulse width t_p (s) rounded up to whole samples, within [1, n_max]."""
        n = int(math.ceil(t_p / self.T - 1e-9)) if math.isfinite(t_p) else self.n_max
        return min(max(n, 1), self.n_max)
