"""Reproducible random numbers addressed by (seed, stream, index): no generator state to keep.

Standard library only. Draw ``k`` of stream ``stream`` under ``seed`` is a pure
function of the three integers (SplitMix64 finalizer, Steele, Lea and Flood,
2014, applied twice), so the state of a random effect is just how many numbers
it has drawn: an integer that an FMU state holds, serializes and restores
exactly, whatever the Python version.
"""

from __future__ import annotations

from statistics import NormalDist

__all__ = ["normal", "uniform"]

_M64 = (1 << 64) - 1
_GOLDEN = 0x9E3779B97F4A7C15
_inv_cdf = NormalDist().inv_cdf


def _mix(z: int) -> int:
    """SplitMix64's output function: a bijection of 64-bit integers."""
    z = (z + _GOLDEN) & _M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
    return z ^ (z >> 31)


def uniform(seed: int, stream: int, k: int) -> float:
    """Draw ``k`` (>= 0) of stream ``stream`` under ``seed``: a number in the open interval (0, 1).

    The 53 high bits of the mixed index, centred in their cell, so that 0 and 1
    never occur.
    """
    z = _mix(_mix(((seed & _M64) << 8 | (stream & 0xFF)) & _M64) ^ (k & _M64))
    return ((z >> 11) + 0.5) * (1.0 / (1 << 53))


def normal(seed: int, stream: int, k: int) -> float:
    """Draw ``k`` of stream ``stream`` under ``seed`` from the standard normal distribution."""
    return _inv_cdf(uniform(seed, stream, k))
