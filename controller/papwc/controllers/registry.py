"""Controller kinds by name: a new controller is one module and one line here."""

from __future__ import annotations

from .dual_loop import DualLoopController
from .exact import ExactController
from .interface import Controller
from .papwc import PapwcController
from .pid import PidController
from .pwc import PwcController
from .settings import ControllerSettings

#: Controller classes by the ``kind`` of a scenario's ``[[controller]]`` table.
CONTROLLER_KINDS: dict[str, type[Controller]] = {
    PwcController.kind: PwcController,
    PapwcController.kind: PapwcController,
    ExactController.kind: ExactController,
    PidController.kind: PidController,
    DualLoopController.kind: DualLoopController,
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
