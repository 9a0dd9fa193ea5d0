"""Identification of a drive's mode from the ringing its motor encoder shows.

While the table sticks and no force acts, the spring deflection delta = x_d - x of a
motor (mass m_d) on a coupling (stiffness k_t, damping c_t) against the stuck table rings
freely; sampled at T it obeys exactly

    delta_(k+1) = a_1*delta_k + a_2*delta_(k-1),

with ``a_1 = 2*r*cos(w_d*T)`` and ``a_2 = -r**2``, ``r = exp(-sigma*T)``: the decay
``sigma = c_t/(2*m_d)`` and the damped frequency ``w_d``, the undamped one
``omega = sqrt(sigma**2 + w_d**2) = sqrt(k_t/m_d)``. :class:`ModeIdentifier` fits
``a_1, a_2`` by least squares to every such triple of readings (no force for ``SETTLE``
samples before and throughout, so that an actuator's lag has let go; the table's reading
within the rest band of where the run began), and accepts the mode once the fit has
``MIN_TRIPLES`` triples, a ringing of at least ``MIN_RINGING`` (root mean square of delta
over the readings' resolution), complex poles inside the unit circle, and ``MATCHES`` fits
in a row that agree within ``AGREE`` in frequency. With its mode the dual-loop controller
builds its motor loop (:class:`~.dual_loop.MotorLoop`, with the motor mass it is told).

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["ModeIdentifier", "mode_of"]

#: Triples of force-free readings of a stuck table the fit needs before it may accept.
MIN_TRIPLES = 8
#: Least ringing: root mean square of the deflection over the readings' resolution.
MIN_RINGING = 20.0
#: Force-free samples before a run of readings begins (an actuator's lag lets go).
SETTLE = 3
#: Fits in a row (one per new triple) whose frequencies agree within AGREE (relative).
MATCHES = 4
AGREE = 0.005


class ModeIdentifier:
    """Least-squares fit of the free ringing of a drive against its stuck table.

    Parameters
    ----------
    T : float
        Sample period, s.
    resolution : float
        Resolution of the readings, m (the ringing must stand out of it; 0: any).

    Attributes
    ----------
    sums : list of float
        ``[S_11, S_12, S_22, S_y1, S_y2, S_yy]``: sums of products of the regressors
        (delta_k, delta_(k-1)) and the target delta_(k+1) over the triples taken, m**2.
    triples : int
        Triples taken.
    recent : list of float
        The last (up to) two deflections of the present force-free stuck run, m.
    quiet : int
        Force-free samples in a row.
    x_run : float
        The table's reading where the present run began, m.
    matches : int
        Fits in a row that agreed with the one before.
    f_last : float
        Frequency of the last fit, Hz (0: none).
    f_mode : float
        The accepted mode's frequency, Hz (0: not yet).
    """

    def __init__(self, T: float, resolution: float = 0.0) -> None:
        self.T = float(T)
        self.resolution = float(resolution)
        self.sums = [0.0] * 6
        self.triples = 0
        self.recent: list[float] = []
        self.quiet = 0
        self.x_run = 0.0
        self.matches = 0
        self.f_last = 0.0
        self.f_mode = 0.0

    def observe(self, delta: float, x: float, force: float, band: float) -> None:
        """The readings of a sample: deflection delta and table x (m), after the force
        ``force`` (N) was held over the last interval; ``band`` (m): how far the table's
        reading may wander (noise) while it sticks."""
        if force != 0.0 or not (math.isfinite(delta) and math.isfinite(x)):
            self.quiet = 0
            self.recent = []
            return
        self.quiet += 1
        if self.quiet <= SETTLE or not self.recent or abs(x - self.x_run) > band:
            # (a run begins: after the lag has let go, or where the table moved to)
            self.recent = []
            self.x_run = x
            if self.quiet <= SETTLE:
                return
        self.take(delta)

    def take(self, delta: float) -> None:
        """Take a deflection delta (m) read force-free with the table stuck since the last."""
        if self.f_mode > 0.0:
            return
        recent = self.recent
        if len(recent) == 2:
            d_1, d_0 = recent[1], recent[0]
            s = self.sums
            s[0] += d_1 * d_1
            s[1] += d_1 * d_0
            s[2] += d_0 * d_0
            s[3] += delta * d_1
            s[4] += delta * d_0
            s[5] += delta * delta
            self.triples += 1
            self._judge()
        self.recent = [*recent[-1:], delta]

    def fit(self) -> float | None:
        """Frequency of the least-squares fit, Hz, or None (too few triples, too little
        ringing, poles not complex or not inside the unit circle)."""
        found = self.ringing()
        return found[0] if found is not None else None

    def ringing(self) -> tuple[float, float] | None:
        """Undamped frequency (Hz) and ``2*sigma`` (1/s) of the least-squares fit, or None
        (see :meth:`fit`)."""
        s11, s12, s22, sy1, sy2, syy = self.sums
        if self.triples < MIN_TRIPLES:
            return None
        if self.resolution > 0.0 and syy < (MIN_RINGING * self.resolution) ** 2 * self.triples:
            return None
        det = s11 * s22 - s12 * s12
        if not det > 0.0:
            return None
        a_1 = (sy1 * s22 - sy2 * s12) / det
        a_2 = (s11 * sy2 - s12 * sy1) / det
        return mode_of(a_1, a_2, self.T)

    def _judge(self) -> None:
        f = self.fit()
        if f is None:
            self.matches, self.f_last = 0, 0.0
            return
        if self.f_last > 0.0 and abs(f - self.f_last) <= AGREE * self.f_last:
            self.matches += 1
        else:
            self.matches = 0
        self.f_last = f
        if self.matches >= MATCHES:
            self.f_mode = f

    def state(self) -> list[float]:
        """Everything that evolves, as numbers: sums, triples, the run (count and up to two
        deflections), matches, the last fit, the mode, the quiet samples and where the run
        began."""
        run = [float(len(self.recent)), *self.recent, *[0.0] * (2 - len(self.recent))]
        return [*self.sums, float(self.triples), *run, float(self.matches), self.f_last,
                self.f_mode, float(self.quiet), self.x_run]

    def set_state(self, values: Sequence[float]) -> None:
        """Restore :meth:`state`."""
        if len(values) != 15:
            raise ValueError(f"law.mode_id holds {len(values)} numbers, not 15")
        v = [float(x) for x in values]
        self.sums = v[:6]
        self.triples = int(v[6])
        n = min(max(int(v[7]), 0), 2)
        self.recent = v[8:8 + n]
        self.matches = int(v[10])
        self.f_last, self.f_mode = v[11], v[12]
        self.quiet, self.x_run = int(v[13]), v[14]


def mode_of(a_1: float, a_2: float, T: float) -> tuple[float, float] | None:
    """Undamped frequency (Hz) and ``2*sigma`` (1/s) of the ringing
    ``delta_(k+1) = a_1*delta_k + a_2*delta_(k-1)`` sampled at T (s); None if its poles
    are not complex or not inside the unit circle."""
    if not (a_2 < 0.0 and a_1 * a_1 + 4.0 * a_2 < 0.0):
        return None
    r = math.sqrt(-a_2)
    if not r < 1.0:
        return None
    theta = math.acos(max(-1.0, min(1.0, a_1 / (2.0 * r))))
    sigma = -math.log(r) / T
    w_d = theta / T
    return math.hypot(sigma, w_d) / (2.0 * math.pi), 2.0 * sigma
