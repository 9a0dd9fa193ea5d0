"""The trust region of a pulse controller: how far a planned pulse may go, as a fraction of abs(e).

A control law plans a pulse to move at most ``trust*|e|``. The trust starts at the
controller's ``trust0`` (1 for a kind that does not read that setting), doubles
(up to 1) after a pulse that moved within ``TRUST_GOOD`` of its prediction and
shrinks after one that moved more, so that a model fooled by noise or by a plant
unlike it plans short pulses instead of long ones. On a machine with a mode, named by
``f_mode`` or seen ringing by the rest detection, the trust is at most
``TRUST_FLEXIBLE``; each ringing seen multiplies it by ``TRUST_RING``.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["TRUST_FLEXIBLE", "TRUST_GOOD", "TRUST_GROWTH", "TRUST_MIN", "TRUST_RING",
           "TrustRegion"]

#: Factor by which the trust region grows after a pulse that moved as predicted.
TRUST_GROWTH = 2.0
#: Relative prediction error up to which a pulse counts as predicted well.
TRUST_GOOD = 0.2
#: Smallest trust.
TRUST_MIN = 0.05
#: Factor on the trust at each ringing seen (never below TRUST_MIN): 0, the least trust.
TRUST_RING = 0.0
#: Largest trust on a machine with a known mode (f_mode > 0).
TRUST_FLEXIBLE = 0.5


class TrustRegion:
    """The largest planned displacement as a fraction of abs(e) (<= 1).

    Parameters
    ----------
    initial : float
        Trust of a new controller (``trust0``), in (0, 1].
    guarded : bool
        With ``safeguards``; without, the trust is always 1.
    flexible : bool
        The machine has a known mode (``f_mode > 0``): at most ``TRUST_FLEXIBLE``.

    Attributes
    ----------
    value : float
        The learned trust (before the flexible cap).
    ring : bool
        Ringing was seen (a mode the settings did not name): the flexible cap applies.
    d_one : float
        Largest move of a one-sample pulse since ringing was seen, m (0: none yet).
    """

    #: Names of the state (:meth:`state`).
    FIELDS = ("value", "ring", "d_one")

    def __init__(self, initial: float, guarded: bool, flexible: bool) -> None:
        self.value = float(initial)
        self.guarded = bool(guarded)
        self.flexible = bool(flexible)
        self.ring = False
        self.d_one = 0.0

    def __call__(self) -> float:
        """The trust in force now.

        On a machine with a known mode at most ``TRUST_FLEXIBLE``: a drive still
        ringing from the last pulse adds to the next one what no model predicts.
        """
        if not self.guarded:
            return 1.0
        return min(self.value, TRUST_FLEXIBLE) if self.flexible or self.ring else self.value

    def ringing(self) -> None:
        """The machine was seen ringing: the flexible cap from now on, and less trust."""
        self.ring = True
        self.value = max(TRUST_MIN, self.value * TRUST_RING)

    def judge(self, pred: float, d_along: float, noise: float) -> None:
        """Compare a pulse's displacement with its prediction; adjust the trust.

        Parameters
        ----------
        pred : float
            Predicted displacement along the pulse, m (nothing is judged unless > 0).
        d_along : float
            Measured displacement along the pulse, m.
        noise : float
            Part of the difference the measurement explains, m.

        The trust doubles (up to 1) after a pulse that moved within ``TRUST_GOOD``
        (relative) of the prediction, and otherwise becomes at most ``1.2/(1 + r)``
        of its value for a pulse that moved ``1 + r`` times the prediction (never
        below ``TRUST_MIN``).
        """
        if not (pred > 0.0 and math.isfinite(pred)):
            return
        err = abs(d_along - pred) - noise
        r = max(err, 0.0) / pred
        if r <= TRUST_GOOD:
            self.value = min(1.0, self.value * TRUST_GROWTH)
        elif d_along > pred:
            self.value = max(TRUST_MIN, min(self.value, 1.2 * pred / max(d_along, 1e-300)))

    def state(self) -> dict[str, Any]:
        """The state by name."""
        return {"value": self.value, "ring": int(self.ring), "d_one": self.d_one}

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state`."""
        self.value = float(values["value"])
        self.ring = bool(values["ring"])
        self.d_one = float(values["d_one"])
