"""Control laws and estimators of the pulse controllers: standard library only.

This package is bundled, under a name of its own, into the PulseController FMU,
so its modules import each other relatively and import nothing outside the
standard library.

Every controller implements :class:`~.interface.Controller`: at each sample it
gets the time, the measured position and the reference, and returns the force to
hold over the next sample; its other outputs are keyed by the model layer's
``CONTROLLER_OUTPUTS``. The pulse controllers are built on
:class:`~.base.PulseControllerBase`.
"""

from .base import PulseControllerBase
from .interface import OUTPUT_NAMES, Controller, Mode, Outcome, Reason, default_outputs
from .registry import CONTROLLER_KINDS, make_controller

__all__ = ["CONTROLLER_KINDS", "OUTPUT_NAMES", "Controller", "Mode", "Outcome",
           "PulseControllerBase", "Reason", "default_outputs", "make_controller"]
