"""The SI units the project's variables use, as exponents of the SI base units.

Standard library only. The model descriptions' ``<UnitDefinitions>`` and the
SSP's ``<ssd:Units>`` are written from this table (FMI 2.0 ``BaseUnit``).
"""

from __future__ import annotations

__all__ = ["UNIT_DEFINITIONS"]

#: Unit name -> exponents of the SI base units.
UNIT_DEFINITIONS: dict[str, dict[str, int]] = {
    "1": {},
    "kg": {"kg": 1},
    "m": {"m": 1},
    "s": {"s": 1},
    "s4": {"s": 4},
    "Hz": {"s": -1},
    "rad": {"rad": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "N/(m.s)": {"kg": 1, "s": -3},
    "N/s": {"kg": 1, "m": 1, "s": -3},
}
