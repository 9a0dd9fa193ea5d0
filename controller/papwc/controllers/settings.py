"""Settings of a pulse controller: one ``[[controller]]`` table of a scenario file.

Standard library only. :class:`ControllerSettings` is built from the table
:data:`papwc.model.controller_settings.CONTROLLER_SETTINGS`: one attribute per setting
(``lam`` for ``lambda``), its default from there, and :meth:`~ControllerSettings.problems`
checks the values against the ranges written there. The scenario reader and the
controller FMU both use it; adding a setting is one entry in that table.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from ..model.controller_settings import CONTROLLER_SETTINGS, settings_problems
from ..model.variables import by_name

__all__ = ["ControllerSettings", "SETTINGS_BY_NAME", "settings_for_kind"]

#: The settings' metadata by scenario-file name.
SETTINGS_BY_NAME = by_name(CONTROLLER_SETTINGS)


def _field(var) -> tuple[str, type, dataclasses.Field]:
    return (var.attribute, Any, dataclasses.field(default=var.default))


class _SettingsBase:
    """Methods of :class:`ControllerSettings` (the fields come from the table)."""

    #: TOML keys that differ from the attribute names.
    KEY_ALIASES: dict[str, str] = {v.name: v.attr for v in CONTROLLER_SETTINGS if v.attr}

    @classmethod
    def field_names(cls) -> list[str]:
        """Names of the settings as they are written in a scenario file."""
        return [v.name for v in CONTROLLER_SETTINGS]

    def get(self, name: str) -> Any:
        """Value of the setting with scenario-file name ``name``."""
        return getattr(self, SETTINGS_BY_NAME[name].attribute)

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
        """
        out: list[tuple[str, str]] = []
        if kinds is not None and self.kind not in kinds:
            out.append(("kind", f"kind = {self.kind!r}: must be one of "
                        + ", ".join(repr(k) for k in kinds)))
        return out + settings_problems(self.to_mapping(with_none=True))

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> ControllerSettings:
        """Settings from a mapping with scenario-file keys.

        Raises
        ------
        KeyError
            For a key that is not a setting (the scenario reader names it first).
        """
        kwargs = {}
        for key, value in values.items():
            kwargs[SETTINGS_BY_NAME[key].attribute] = value
        return cls(**kwargs)

    def to_mapping(self, with_none: bool = False) -> dict[str, Any]:
        """The settings with scenario-file keys (``None`` values left out unless asked)."""
        out = {}
        for var in CONTROLLER_SETTINGS:
            value = getattr(self, var.attribute)
            if value is not None or with_none:
                out[var.name] = value
        return out


#: Settings of one controller: one attribute per entry of CONTROLLER_SETTINGS, SI units.
ControllerSettings = dataclasses.make_dataclass(
    "ControllerSettings",
    [_field(v) for v in CONTROLLER_SETTINGS],
    bases=(_SettingsBase,),
    namespace={"__module__": __name__},
)
ControllerSettings.__doc__ = (
    "Settings of one controller (SI units; names follow the paper).\n\n"
    + "\n".join(f"- ``{v.name}`` ({v.unit or '-'}, default {v.default!r}): {v.description}"
                for v in CONTROLLER_SETTINGS)
)


def settings_for_kind(kind: str) -> list[str]:
    """Scenario-file names of the settings that controller kind ``kind`` reads."""
    return [v.name for v in CONTROLLER_SETTINGS if not v.kinds or kind in v.kinds]
