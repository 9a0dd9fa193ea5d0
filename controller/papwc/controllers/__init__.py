"""Control laws and estimators of the pulse controllers: standard library only.

This package is bundled, under a name of its own, into the PulseController FMU,
so its modules import each other relatively and import nothing outside the
standard library.

Every controller implements :class:`~.base.Controller`: at each sample it gets
the time, the measured position and the reference, and returns the force to
hold over the next sample.
"""

from .base import Controller, Mode
from .registry import CONTROLLER_KINDS, make_controller

__all__ = ["CONTROLLER_KINDS", "Controller", "Mode", "make_controller"]
