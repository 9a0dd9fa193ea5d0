"""Settings of a controller: one ``[[controller]]`` table of a scenario file.

Standard library only. :class:`ControllerSettings` has one attribute per entry of
:data:`papwc.model.controller_settings.CONTROLLER_SETTINGS` (``lam`` for ``lambda``), in its
order and with its defaults (a test holds the two equal); :meth:`~ControllerSettings.problems`
checks the values against the ranges and rules written there. The scenario reader and the
controller FMU both use it. Adding a setting is one ``Variable`` in the settings of the kind
that reads it (or in the model layer's shared settings) and one attribute here.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from typing import Any

from ..model import controller_settings as _table
from ..model.variables import Variable, by_name

__all__ = [
    "ControllerSettings",
    "SETTINGS_BY_NAME",  # noqa: F822 (on first use, see __getattr__)
    "settings_for_kind",
]


def _settings() -> tuple[Variable, ...]:
    """The model layer's table of every kind's settings (assembled on first use)."""
    return _table.CONTROLLER_SETTINGS


@functools.cache
def _by_name() -> dict[str, Variable]:
    """The settings' metadata by scenario-file name."""
    return by_name(_settings())


def __getattr__(name: str) -> Any:
    """``SETTINGS_BY_NAME``: the settings' metadata by scenario-file name (on first use)."""
    if name == "SETTINGS_BY_NAME":
        return _by_name()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclasses.dataclass
class ControllerSettings:
    """Settings of one controller (SI units; names follow the paper).

    One attribute per setting of
    :data:`papwc.model.controller_settings.CONTROLLER_SETTINGS`, where each is described
    with its unit, default, range and the kinds that read it (the reference's table of
    scenario fields lists them); ``lam`` is the setting ``lambda``. ``None`` selects the
    default a setting computes from others (``f_p_min``, ``k_p``, ``k_d``, ``k_i``,
    ``a_max``, ``in_position``, ``in_position_band``). Values are not checked when the object
    is made: :meth:`problems` checks them.

    Examples
    --------
    >>> s = ControllerSettings(kind="pwc", K_c=0.5, t_p_max=0.03)
    >>> s.f_p_max, s.k_p_value
    (300.0, 15000.0)
    >>> s.problems()
    []
    >>> ControllerSettings(kind="pwc", f_c_est=400.0).problems()[0][0]
    'f_c_est'
    """

    # shared by every kind (SHARED_SETTINGS)
    kind: str = "papwc"
    f_p_max: float = 300.0
    t_p_max: float = math.inf
    K_c: float = 1.0
    tolerance: float = 2e-5
    m_est: float = 150.0
    f_c_est: float = 80.0
    f_p_min: float | None = None
    floor_raise: float = 0.05
    e_band: float = 0.02
    k_p: float | None = None
    k_d: float | None = None
    rest_samples: int = 1
    rest_band: float = 0.0
    max_pulses: int = 20
    safeguards: bool = True
    rest_auto: bool = True
    f_mode: float = 0.0
    # pwc (papwc: regressor, update_covariance; every pulse kind: m_d_est)
    F_inv0: float = 1e-5
    lambda_1: float = 1.0
    lambda_2: float = 1.0
    regressor: int = 0
    update_covariance: bool = True
    m_d_est: float = 50.0
    # papwc
    delta_inv: float = 1e-5
    lam: float = 1.0
    floor_mode: int = 0
    # exact (and dual_loop)
    c_est: float = 0.0
    history: int = 16
    x_resolution: float = 0.0
    f_s_tol: float = 0.02
    trust0: float = 0.5
    f_b_floor: float = 0.0
    f_b_step: float = 0.0
    settle_timeout: float = 10.0
    # pid
    k_i: float | None = None
    a_max: float | None = None
    v_max: float = 0.05
    hunt_max: int = 4
    in_position: bool | None = None
    in_position_band: float | None = None
    # dual_loop
    c_t_est: float = 0.0
    f_relax: float = 2.0
    identify_mode: bool = False
    # hybrid
    ramp_rate: float = 150.0

    @classmethod
    def field_names(cls) -> list[str]:
        """Names of the settings as they are written in a scenario file."""
        return [v.name for v in _settings()]

    def get(self, name: str) -> Any:
        """Value of the setting with scenario-file name ``name``."""
        return getattr(self, _by_name()[name].attribute)

    @property
    def f_p_floor0(self) -> float:
        """Initial amplitude floor, N."""
        return self.f_c_est if self.f_p_min is None else self.f_p_min

    @property
    def k_p_value(self) -> float:
        """Proportional gain of the coarse feedback, N/m."""
        return self.m_est * 100.0 if self.k_p is None else self.k_p

    @property
    def k_d_value(self) -> float:
        """Derivative gain of the coarse feedback, N.s/m."""
        return 2.0 * 0.7 * 10.0 * self.m_est if self.k_d is None else self.k_d

    def problems(self, kinds: tuple[str, ...] | None = None) -> list[tuple[str, str]]:
        """Every invalid setting as ``(name, message)``; empty when valid.

        Parameters
        ----------
        kinds : tuple of str, optional
            The controller kinds that exist; ``kind`` must be one of them.

        Returns
        -------
        list of (str, str)
            The setting's scenario-file name and one line that says what is wrong and
            what is allowed, for each invalid setting.
        """
        out: list[tuple[str, str]] = []
        if kinds is not None and self.kind not in kinds:
            out.append(("kind", f"kind = {self.kind!r}: must be one of "
                        + ", ".join(repr(k) for k in kinds)))
        return out + _table.settings_problems(self.to_mapping(with_none=True))

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> ControllerSettings:
        """Settings from a mapping with scenario-file keys.

        Parameters
        ----------
        values : mapping of str to value
            Settings by scenario-file name (``lambda``, not ``lam``); those not given
            keep their defaults.

        Returns
        -------
        ControllerSettings
            The settings (not checked: see :meth:`problems`).

        Raises
        ------
        KeyError
            For a key that is not a setting (the scenario reader names it first).
        """
        table = _by_name()
        return cls(**{table[key].attribute: value for key, value in values.items()})

    def to_mapping(self, with_none: bool = False) -> dict[str, Any]:
        """The settings with scenario-file keys (``None`` values left out unless asked).

        Parameters
        ----------
        with_none : bool
            Keep the settings whose value is ``None`` (a computed default).

        Returns
        -------
        dict of str to value
            The settings by scenario-file name, in the table's order.
        """
        out = {}
        for var in _settings():
            value = getattr(self, var.attribute)
            if value is not None or with_none:
                out[var.name] = value
        return out


def settings_for_kind(kind: str) -> list[str]:
    """Scenario-file names of the settings that controller kind ``kind`` reads."""
    return [v.name for v in _settings() if not v.kinds or kind in v.kinds]
