"""The encoder: Gaussian noise added to the position before quantization.

At every communication point ``k`` (0 the start, then one per ``doStep``)::

    x_meas = quantize(x + noise_std * N_k, x_resolution)

with ``N_k`` number ``k`` of the noise stream of :mod:`.draws` under the plant's
``seed`` (independent standard normal numbers), and
:func:`papwc.model.stickslip.quantize` the encoder's rounding to its count.
"""

from __future__ import annotations

from .draws import normal

__all__ = ["MOTOR_STREAM", "STREAM", "EncoderNoise"]

#: Stream number of the noise draws.
STREAM = 2
#: Stream number of the motor encoder's noise draws (``x_d_meas``, read from ``x_d`` with
#: ``x_d_noise_std`` and ``x_d_resolution`` by the same law).
MOTOR_STREAM = 3


class EncoderNoise:
    """The noise of the encoder reading.

    Parameters
    ----------
    noise_std : float
        Standard deviation, m, > 0.
    seed : int
        Seed of the draws.
    stream : int
        Stream of the draws: :data:`STREAM` (the table's encoder) or :data:`MOTOR_STREAM`.
    """

    __slots__ = ("noise_std", "seed", "stream")

    def __init__(self, noise_std: float, seed: int, stream: int = STREAM) -> None:
        self.noise_std = noise_std
        self.seed = seed
        self.stream = stream

    def draw(self, k: int) -> float:
        """Noise at communication point number ``k``, m."""
        return self.noise_std * normal(self.seed, self.stream, k)
