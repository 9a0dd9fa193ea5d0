"""The controller interface: what the controller slave, PulseController.fmu and the trace read.

A controller sees what a real one sees: the time and the measured position (an
encoder), never the velocity nor the plant's stuck flag. At every sample
:meth:`Controller.update` returns the force to hold over the next sample
(zero-order hold). Its other outputs are :meth:`Controller.outputs`, keyed by the
names of :data:`papwc.model.controller_settings.CONTROLLER_OUTPUTS` (all but ``u``, which
``update`` returns): they are declared there once, and the controller slave,
PulseController.fmu and the trace read them by those names. Its state is a named
mapping (:meth:`Controller.state`) that PulseController.fmu's get/set state
serializes.

A new controller kind is a module with a subclass of :class:`Controller` (or of
:class:`papwc.controllers.base.PulseControllerBase` for a pulse controller) and
one line in :mod:`papwc.controllers.registry`.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..model.controller_settings import CONTROLLER_OUTPUTS, OUTCOME_REASONS, OUTCOMES
from ..model.variables import Variable
from .settings import ControllerSettings, settings_for_kind

__all__ = ["OUTPUT_NAMES", "Controller", "Mode", "Outcome", "Reason", "default_outputs"]

#: Names of the outputs :meth:`Controller.outputs` returns: the model layer's controller
#: outputs but ``u`` (the force, which :meth:`Controller.update` returns).
OUTPUT_NAMES: tuple[str, ...] = tuple(v.name for v in CONTROLLER_OUTPUTS if v.name != "u")


class Mode:
    """Mode codes (the controller FMU's ``mode`` output)."""

    COARSE = 0
    PULSE = 1
    WAIT = 2
    SETTLED = 3
    NAMES = {0: "coarse", 1: "pulse", 2: "wait", 3: "settled"}


class Outcome:
    """Outcome codes (the controller FMU's ``outcome`` output), :data:`OUTCOMES`."""

    ACTIVE = OUTCOMES.index("active")
    SETTLED = OUTCOMES.index("settled")
    STOPPED = OUTCOMES.index("stopped")


class Reason:
    """Reason codes (the controller FMU's ``outcome_reason`` output), :data:`OUTCOME_REASONS`."""

    NONE = 0
    WITHIN_TOLERANCE = OUTCOME_REASONS.index("within_tolerance")
    NO_MOVE_HELPS = OUTCOME_REASONS.index("no_move_helps")
    PULSE_BUDGET = OUTCOME_REASONS.index("pulse_budget")
    MODEL_REJECTED = OUTCOME_REASONS.index("model_rejected")
    TIME_ENDED = OUTCOME_REASONS.index("time_ended")
    INVALID_MEASUREMENT = OUTCOME_REASONS.index("invalid_measurement")
    CANNOT_MOVE = OUTCOME_REASONS.index("cannot_move")


def default_outputs() -> dict[str, Any]:
    """Outputs of a controller that cannot be made (invalid settings).

    Returns
    -------
    dict of str to float or int
        By :data:`OUTPUT_NAMES`: integer outputs at their start values, real ones NaN.

    Examples
    --------
    >>> default_outputs()["pulses"], default_outputs()["b_hat"]
    (0, nan)
    """
    return {v.name: (v.default if v.type == "Integer" else math.nan)
            for v in CONTROLLER_OUTPUTS if v.name != "u"}


class Controller:
    """The interface every controller kind implements.

    A subclass implements :meth:`update`, :meth:`reset`, :meth:`estimates`,
    :meth:`state` and :meth:`set_state`, and keeps the attributes ``mode``,
    ``pulses``, ``outcome`` and ``outcome_reason`` (codes of :class:`Mode`,
    :class:`Outcome`, :class:`Reason`) and ``f_low``; :meth:`outputs` is built from
    them. ``revision`` grows whenever :meth:`estimates` or ``f_low`` may have
    changed (the outputs made from them are cached until then); ``idle_samples``
    grows when a sample changed nothing but a count (the outputs are then those of
    the sample before; 0 for a controller that never skips work).

    Parameters
    ----------
    settings : ControllerSettings
        One ``[[controller]]`` table of a scenario, already checked against the ranges
        and rules of :data:`papwc.model.controller_settings.CONTROLLER_SETTINGS`.
    T : float
        Sample period, s: :meth:`update` is called once every T.

    Examples
    --------
    A controller is made from its settings by the registry; the host calls :meth:`update`
    once a sample with the measured position and reads :meth:`outputs`:

    >>> from papwc.controllers import make_controller
    >>> from papwc.controllers.settings import ControllerSettings
    >>> controller = make_controller(ControllerSettings(kind="papwc"), T=0.01)
    >>> u = controller.update(0.0, 0.0, 0.01)  # t (s), x_meas (m), x_ref (m)
    >>> 0.0 < u <= controller.settings.f_p_max  # the coarse move pushes toward the target
    True
    >>> sorted(controller.outputs()) == sorted(OUTPUT_NAMES)
    True
    """

    kind = "base"
    #: The settings the kind reads besides the model layer's shared ones
    #: (:data:`papwc.model.controller_settings.SHARED_SETTINGS`), declared in the kind's
    #: module; the registry assembles every kind's into ``CONTROLLER_SETTINGS``.
    SETTINGS: tuple[Variable, ...] = ()
    #: Whether the kind reads the motor encoder: the host then sets ``x_d_meas`` (m) before
    #: each :meth:`update` and a closed loop connects the plant's ``x_d_meas`` to it.
    reads_x_d_meas = False
    #: Incremented whenever the estimates may have changed.
    revision = 0
    #: Samples only counted since the state was last brought up to date.
    idle_samples = 0
    # the outputs made from the estimates, and the revision they were made at
    _cached_revision = -1
    _cached: dict[str, float] = {}  # (replaced, never changed in place)

    def __init__(self, settings: ControllerSettings, T: float) -> None:
        self.settings = settings
        self.T = float(T)
        self.revision = 0

    # -- to implement ------------------------------------------------------------------
    def update(self, t: float, x_meas: float, x_ref: float) -> float:
        """The force to hold over the next sample.

        Parameters
        ----------
        t : float
            Time of the sample, s.
        x_meas : float
            Measured position, m (the encoder's reading, never the true position).
        x_ref : float
            Reference (target) position, m.

        Returns
        -------
        float
            Force u, N, held over [t, t + T].
        """
        raise NotImplementedError

    def reset(self) -> None:
        """Start a new maneuver from rest; learned estimates are kept."""
        raise NotImplementedError

    def estimates(self) -> dict[str, float]:
        """Current estimates, for recording.

        Returns
        -------
        dict of str to float
            At least ``b_hat`` (m/s**2) and ``f_c_hat`` (N); NaN where the kind has none.
        """
        return {"b_hat": math.nan, "f_c_hat": math.nan}

    #: Lowest pulse height it plans with now, N (NaN: it does not pulse).
    f_low: float = math.nan

    def state(self) -> dict[str, Any]:
        """Everything that evolves, by name: numbers, or lists of numbers."""
        raise NotImplementedError

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state returned by :meth:`state`.

        Parameters
        ----------
        values : mapping of str to number or list of numbers
            A state of this kind, as :meth:`state` returned it.

        Raises
        ------
        ValueError, KeyError
            If the state does not fit (other names, values of another shape).
        """
        raise NotImplementedError

    # -- read by the slave, the FMU and the trace --------------------------------------
    def outputs(self) -> dict[str, float]:
        """The outputs after the last sample.

        An output named among :meth:`estimates` (or ``f_low``) is read from them
        (again only once ``revision`` changed), any other is the attribute of its name.

        Returns
        -------
        dict of str to float
            Keyed by :data:`OUTPUT_NAMES`, in their order.
        """
        if self._cached_revision != self.revision:
            cached = self.estimates()
            cached["f_low"] = self.f_low
            self._cached, self._cached_revision = cached, self.revision
        cached = self._cached
        return {name: cached[name] if name in cached else getattr(self, name)
                for name in OUTPUT_NAMES}

    # declared by subclasses
    mode: int
    pulses: int
    outcome: int
    outcome_reason: int

    @classmethod
    def trust0(cls, settings: ControllerSettings) -> float:
        """Trust region of a new controller of this kind.

        Parameters
        ----------
        settings : ControllerSettings
            The controller's settings.

        Returns
        -------
        float
            ``settings.trust0`` if the kind reads that setting, else 1.
        """
        return float(settings.trust0) if "trust0" in settings_for_kind(cls.kind) else 1.0
