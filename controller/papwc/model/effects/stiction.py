"""Random stiction: the breakaway force redrawn each time the mass sticks.

Real surfaces do not release at one force: after each stop the breakaway
force is drawn anew, uniformly in ``f_s*(1 - f_s_spread)`` to
``f_s*(1 + f_s_spread)``. Draw ``k`` is number ``k`` of the stiction stream of
:mod:`.draws` under the plant's ``seed``: draw 0 holds from the start, draw
``k`` after the ``k``-th time the mass sticks. The state of the effect is the
current breakaway force and the number of draws made.
"""

from __future__ import annotations

from .draws import uniform

__all__ = ["STREAM", "RandomStiction"]

#: Stream number of the breakaway draws.
STREAM = 1


class RandomStiction:
    """Breakaway forces ``f_s*(1 + f_s_spread*(2U - 1))``, U uniform in (0, 1).

    Parameters
    ----------
    f_s : float
        Nominal breakaway (stiction) force, N.
    spread : float
        Relative half-width, 0 < spread < 1.
    seed : int
        Seed of the draws.
    """

    __slots__ = ("f_s", "seed", "spread")

    def __init__(self, f_s: float, spread: float, seed: int) -> None:
        self.f_s = f_s
        self.spread = spread
        self.seed = seed

    def draw(self, k: int) -> float:
        """Breakaway force number ``k`` (N)."""
        return self.f_s * (1.0 + self.spread * (2.0 * uniform(self.seed, STREAM, k) - 1.0))
