"""Motion and rests in a log: which samples moved, the encoder's count and noise, the breakaways.

The position difference ``dx_k = x_{k+1} - x_k`` of each sample interval is compared with
a threshold set by the encoder: :data:`NOISE_FACTOR` times the standard deviation of the
differences at rest and :data:`COUNT_FACTOR` counts of the encoder. That deviation is first
1.4826 times the median absolute deviation of the differences after the most samples
without force of :data:`FORCE_FREE` that leave :data:`MIN_POOL` of them (of all, if none
do), then the standard deviation
of the differences inside the rests so found (outliers beyond 4 deviations trimmed), and the
rests are found again with it. The table is at
rest at sample ``k`` when the :data:`REST_INTERVALS` intervals before it did not move; a
rest followed by a move is a breakaway, a rest followed by none a held force.

The encoder's count ``q`` is the smallest nonzero ``|dx|`` when every position is a whole
number of it (else 0: no quantization seen); the noise is what the scatter at rest has
beyond the quantization, ``sigma^2 = s^2/2 - q^2/12`` (``s`` the scatter of ``dx``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from papwc.identify.log_file import Log, LogError

__all__ = [
    "COUNT_FACTOR",
    "NOISE_FACTOR",
    "REST_INTERVALS",
    "Bracket",
    "Motion",
    "analyse",
    "breakaway_bracket",
]

#: A move exceeds this many standard deviations of the differences at rest ...
NOISE_FACTOR = 6.0
#: ... and this many encoder counts.
COUNT_FACTOR = 1.5
#: A scatter at rest below this fraction of the largest position (or 1 m) is rounding, not
#: noise.
NOISE_FLOOR = 1e-12
#: Intervals without motion before a sample at rest.
REST_INTERVALS = 2
#: Samples without force after which the table is taken to have stopped, tried in turn for
#: the first estimate of the noise, and the fewest intervals that estimate is made of.
FORCE_FREE = (20, 10, 5, 3)
MIN_POOL = 20


@dataclass
class Motion:
    """What moved in a log.

    Attributes
    ----------
    dx : ndarray
        Position difference over each sample interval, m (one fewer than samples).
    moved : ndarray of bool
        The interval's difference exceeds :attr:`threshold`.
    threshold : float
        Smallest difference counted as motion, m.
    resolution : float
        Encoder count, m (0: no quantization seen).
    noise : float
        Standard deviation of the encoder noise, m.
    rest : ndarray of bool
        The table is at rest at the sample (per sample).
    breakaways : ndarray of int
        Samples at rest whose interval moved.
    held : ndarray of int
        Samples at rest whose interval did not move.
    """

    dx: np.ndarray
    moved: np.ndarray
    threshold: float
    resolution: float
    noise: float
    rest: np.ndarray
    breakaways: np.ndarray
    held: np.ndarray


@dataclass(frozen=True)
class Bracket:
    """The breakaway force bracketed by the rests, N: ``low`` held, ``high`` moved.

    ``low_k``/``high_k`` are the samples of those forces (-1: none held).
    """

    low: float
    high: float
    low_k: int
    high_k: int

    @property
    def middle(self) -> float:
        """The estimate: the middle of the bracket, N."""
        return 0.5 * (self.low + self.high)


def _resolution(x: np.ndarray, dx: np.ndarray) -> float:
    steps = np.abs(dx[dx != 0.0])
    if steps.size == 0:
        return 0.0
    q0 = float(steps.min())
    span = float(x.max() - x.min())
    for divisor in (1, 2, 3, 4):
        q = q0 / divisor
        # The count refined from the largest span of positions first: the smallest step,
        # a difference of two positions, is off by their rounding, which x/q multiplies
        # by the number of counts (a tenth of a count at 3e5 counts of 0.1 um).
        n = round(span / q)
        if n > 0:
            q = span / n
        counts = x / q
        if np.max(np.abs(counts - np.round(counts))) < 1e-6 and np.max(np.abs(counts)) < 2**50:
            return q
    return 0.0


def _rest_noise(x: np.ndarray, rest: np.ndarray, q: float, rough: float) -> float:
    """Noise from the scatter of the positions within each rest (runs of >= 5 samples)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rest.astype(int), [0]])))
    sum_sq, dof = 0.0, 0
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if b - a >= 5:
            run = x[a:b]
            sum_sq += float(np.sum((run - run.mean()) ** 2))
            dof += b - a - 1
    if dof < 20:
        return rough
    noise = float(np.sqrt(max(sum_sq / dof - q * q / 12.0, 0.0)))
    # Rounding of the positions' last digits is no noise.
    return noise if noise > NOISE_FLOOR * max(float(np.max(np.abs(x))), 1.0) else 0.0


def _rests(moved: np.ndarray) -> np.ndarray:
    """At rest at each sample: the :data:`REST_INTERVALS` intervals before it did not move."""
    n = moved.size + 1
    rest = np.zeros(n, dtype=bool)
    still = ~moved
    rest[REST_INTERVALS:] = np.all(
        [still[REST_INTERVALS - 1 - j:n - 1 - j] for j in range(REST_INTERVALS)], axis=0)
    return rest


def analyse(log: Log) -> Motion:
    """Tell the motion of ``log`` from its rests.

    Raises
    ------
    LogError
        If the position never moves beyond the noise (no motion at all), or if the
        table never breaks away from a rest (the force never exceeds the breakaway).
    """
    x = log.x
    dx = np.diff(x)
    q = _resolution(x, dx)
    # The scatter of the differences at rest: 1.4826 times their median absolute deviation,
    # over the intervals after the most samples without force (of FORCE_FREE) that leave at
    # least MIN_POOL of them (the table has stopped there, or most of it), else over all.
    zero = (log.u[:-1] == 0.0).astype(int)
    pool = dx
    for samples in FORCE_FREE:
        free = np.convolve(zero, np.ones(samples, dtype=int), "full")[:dx.size] >= samples
        if np.count_nonzero(free) >= MIN_POOL:
            pool = dx[free]
            break
    scatter = 1.4826 * float(np.median(np.abs(pool - np.median(pool))))
    noise = float(np.sqrt(max(scatter**2 / 2.0 - q * q / 12.0, 0.0)))
    threshold = max(NOISE_FACTOR * scatter, COUNT_FACTOR * q)
    moved = np.abs(dx) > threshold
    column_x, column_u = log.columns.position, log.columns.force
    if not moved.any():
        k = int(np.argmax(np.abs(log.u)))
        raise LogError(f"{log.source}, rows 1-{x.size}, column {column_x!r}: no motion at all: "
                       f"the position never changes by more than {threshold:.3g} m from one "
                       f"row to the next (the noise); the largest force, {float(log.u[k])!r} N in "
                       f"row {k + 1} (column {column_u!r}), never moved the table")
    # The differences of the whole log overstate the noise when the table moves in most
    # intervals: estimate it again from the differences inside the rests found so (their
    # outliers, small moves taken for rests, trimmed), and find the rests again with it.
    rest = _rests(moved)
    inside = rest[1:] & rest[:-1]
    pool = dx[inside]
    if pool.size >= 20:
        spread = 1.4826 * float(np.median(np.abs(pool - np.median(pool))))
        kept = pool[np.abs(pool - np.median(pool)) <= 4.0 * max(spread, q)]
        scatter = min(scatter, float(np.std(kept)))
        threshold = max(NOISE_FACTOR * scatter, COUNT_FACTOR * q)
        moved = np.abs(dx) > threshold
        rest = _rests(moved)
    still = ~moved
    noise = _rest_noise(x, rest, q, noise)
    starts = np.flatnonzero(rest[:-1] & moved)
    held = np.flatnonzero(rest[:-1] & still)
    if starts.size == 0:
        at_rest = held[np.argmax(np.abs(log.u[held]))] if held.size else 0
        raise LogError(f"{log.where(int(at_rest), column_u)}: the force never exceeds the "
                       f"breakaway: the table moves, but never from a rest; the largest force "
                       f"applied at rest, {float(log.u[at_rest])!r} N here, held it; the log must "
                       "break the table away (see papwc identify --design)")
    return Motion(dx, moved, threshold, q, noise, rest, starts, held)


def breakaway_bracket(motion: Motion, force: np.ndarray) -> Bracket:
    """The breakaway force bracketed by the rests under ``force`` (N per sample interval).

    ``force`` is the force that acts on the table over each interval at rest (the log's,
    or the lagging actuator's largest over the interval). If a force that held exceeds one
    that moved (noise), the bracket is the two, in order.
    """
    moved_at = motion.breakaways
    f_moved = np.abs(force[moved_at])
    j = int(np.argmin(f_moved))
    high, high_k = float(f_moved[j]), int(moved_at[j])
    if motion.held.size:
        f_held = np.abs(force[motion.held])
        i = int(np.argmax(f_held))
        low, low_k = float(f_held[i]), int(motion.held[i])
    else:
        low, low_k = 0.0, -1
    if low > high:
        low, high, low_k, high_k = high, low, high_k, low_k
    return Bracket(low, high, low_k, high_k)
