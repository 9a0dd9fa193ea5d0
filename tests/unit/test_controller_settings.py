"""A controller kind is one module: its settings declared there, the tables assembled from the
registry, ControllerSettings an explicit dataclass equal to them."""

from __future__ import annotations

import dataclasses
import math

import pytest

from papwc.controllers import CONTROLLER_KINDS
from papwc.controllers.settings import ControllerSettings
from papwc.model import controller_settings as table
from papwc.model.controller_settings import (
    CONTROLLER_SETTINGS,
    KIND_CODES,
    PULSE_CONTROLLER_VARIABLES,
    SHARED_SETTINGS,
    assemble_settings,
)
from papwc.model.variables import Variable


def test_controller_settings_is_the_table_field_for_field() -> None:
    """Names (attributes), order and defaults of the dataclass are those of the table."""
    fields = dataclasses.fields(ControllerSettings)
    assert [f.name for f in fields] == [v.attribute for v in CONTROLLER_SETTINGS]
    for f, var in zip(fields, CONTROLLER_SETTINGS, strict=True):
        same = f.default == var.default or (
            isinstance(var.default, float) and math.isinf(var.default) and math.isinf(f.default))
        assert same, (var.name, f.default, var.default)
        expected = {"Real": "float", "Integer": "int", "Boolean": "bool", "String": "str"}
        assert f.type.split(" ")[0] == expected[var.type], (var.name, f.type)
        assert ("None" in f.type) == bool(var.optional), var.name


def test_the_kind_codes_are_the_registry_in_its_stable_order() -> None:
    """kind_code n of PulseController.fmu selects KIND_CODES[n - 1]: the numbers of the kinds
    users have are kept (a new kind is registered last)."""
    assert KIND_CODES == tuple(CONTROLLER_KINDS)
    assert KIND_CODES[:5] == ("pwc", "papwc", "exact", "pid", "dual_loop")
    kind_code = next(v for v in PULSE_CONTROLLER_VARIABLES if v.name == "kind_code")
    assert kind_code.max == len(KIND_CODES)


def test_each_kind_declares_its_own_settings_and_the_table_names_the_kinds_that_read_them():
    shared = {v.name for v in SHARED_SETTINGS}
    for kind, cls in CONTROLLER_KINDS.items():
        own = {v.name for v in cls.SETTINGS}
        assert not own & shared, kind
        for var in CONTROLLER_SETTINGS:
            reads = var.name in shared or var.name in own
            assert reads == (not var.kinds or kind in var.kinds), (kind, var.name)
    assert [v.name for v in CONTROLLER_SETTINGS[:len(SHARED_SETTINGS)]] == [
        v.name for v in SHARED_SETTINGS]
    by_name = {v.name: v for v in CONTROLLER_SETTINGS}
    assert by_name["m_d_est"].kinds == ("pwc", "papwc", "exact", "dual_loop")
    assert by_name["regressor"].kinds == ("pwc", "papwc")


def test_a_new_kinds_settings_are_assembled_after_the_others() -> None:
    gain = Variable("gain", "Gain of a kind written for this test", "1", 2.0, min=0.0)
    kinds = {kind: cls.SETTINGS for kind, cls in CONTROLLER_KINDS.items()}
    assembled = assemble_settings(SHARED_SETTINGS, {**kinds, "toy": (gain,)})
    assert assembled[:-1] == CONTROLLER_SETTINGS
    assert assembled[-1] == dataclasses.replace(gain, kinds=("toy",))


def test_two_settings_of_one_name_are_refused() -> None:
    twin = Variable("f_p_max", "A second f_p_max", "N", 1.0)
    with pytest.raises(ValueError, match="setting 'f_p_max' of kind 'toy' is declared twice"):
        assemble_settings(SHARED_SETTINGS, {"toy": (twin,)})
    again = Variable("gain", "Gain", "1", 2.0)
    other = Variable("gain", "Another gain", "1", 3.0)
    with pytest.raises(ValueError, match="setting 'gain' of kind 'b' is declared twice"):
        assemble_settings(SHARED_SETTINGS, {"a": (again,), "b": (other,)})


def test_the_assembled_tables_are_made_once() -> None:
    assert table.CONTROLLER_SETTINGS is table.CONTROLLER_SETTINGS
    assert table.CONTROLLER_SETTINGS == CONTROLLER_SETTINGS
    with pytest.raises(AttributeError, match="has no attribute 'NO_SUCH_TABLE'"):
        table.NO_SUCH_TABLE  # noqa: B018
