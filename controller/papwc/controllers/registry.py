"""Controller kinds by name: a new controller is one module and one line here.

A kind's module holds its control law and its settings (the class's ``SETTINGS``, declared
with the model layer's :class:`~papwc.model.variables.Variable`). The model layer assembles
its tables from this registry on first use: ``CONTROLLER_SETTINGS`` (the shared settings,
then each kind's in this order) and ``KIND_CODES`` (PulseController.fmu's ``kind_code`` n is
the n-th kind here: register a new kind last, so that the others keep their numbers).
"""

from __future__ import annotations

from .dual_loop import DualLoopController
from .exact import ExactController
from .hybrid import HybridController
from .interface import Controller
from .papwc import PapwcController
from .pid import PidController
from .pwc import PwcController
from .settings import ControllerSettings

#: Controller classes by the ``kind`` of a scenario's ``[[controller]]`` table, in the order
#: of their ``kind_code`` (1, 2, ...).
CONTROLLER_KINDS: dict[str, type[Controller]] = {
    PwcController.kind: PwcController,
    PapwcController.kind: PapwcController,
    ExactController.kind: ExactController,
    PidController.kind: PidController,
    DualLoopController.kind: DualLoopController,
    HybridController.kind: HybridController,
}


def make_controller(settings: ControllerSettings, T: float) -> Controller:
    """A controller of ``settings.kind`` for sample period ``T`` (s)."""
    try:
        cls = CONTROLLER_KINDS[settings.kind]
    except KeyError:
        raise ValueError(
            f"controller kind {settings.kind!r} is unknown; known kinds: "
            + ", ".join(sorted(CONTROLLER_KINDS))
        ) from None
    return cls(settings, T)
