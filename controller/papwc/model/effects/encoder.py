"""The encoder: Gaussian noise added to the position before quantization.

At every communication point ``k`` (0 the start, then one per ``doStep``)::

    x_meas = quantize(x + noise_std * N_k, x_resolution)

with ``N_k`` number ``k`` of the noise stream of :mod:`.draws` under the plant's
``seed`` (independent standard normal numbers), and
:func:`papwc.model.stickslip.quantize` the encoder's rounding to its count.
"""

from __future__ import annotations

from .draws import normal

__all__ = ["STREAM", "EncoderNoise"]

#: Stream number of the noise draws.
STREAM = 2


class EncoderNoise:
    """The noise of the encoder reading.

    Parameters
    ----------
    noise_std : float
        Standard deviation, m, > 0.
    seed : int
        Seed of the draws.
    """

    __slots__ = ("noise_std", "seed")

    def __init__(self, noise_std: float, seed: int) -> None:
        self.noise_std = noise_std
        self.seed = seed

    def draw(self, k: int) -> float:
        """Noise at communication point number ``k``, m."""
        return self.noise_std * normal(self.seed, STREAM, k)
