"""Every Real parameter of the FMUs declares min and max, and the FMUs keep to them.

A host that checks a value against the model description's range must never pass
one the FMU then refuses: every Real parameter of FrictionPlant.fmu (native and
pythonfmu) and PulseController.fmu declares ``min`` and ``max`` with its start
between them, an excluded bound written as the next double inside it, and the
FMU accepts a sample of parameters at ``min`` and at ``max`` and refuses the next
double outside.

How a refusal shows: the native FrictionPlant returns fmi2Error from
``fmi2ExitInitializationMode``; a pythonfmu FMU (pythonfmu 0.7.0 returns fmi2OK
from that call whatever the model says) logs the refusal with status fmi2Error and
returns fmi2Discard from every ``fmi2DoStep``. Never fmi2OK from ``fmi2DoStep``.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from harness import FMI2_DISCARD, FMI2_ERROR, FmuInstance

#: Parameters tried at their bounds, per FMU (their bounds meet no rule between parameters
#: at the other start values). ``<name>_given = true`` so that the Real is read.
PLANT_SAMPLE = ("m", "c", "ripple", "ripple_phase", "sigma_1", "tau_u")
CONTROLLER_SAMPLE = ("K_c", "lambda_2", "floor_raise", "k_p", "k_d", "x_ref_offset", "f_mode",
                     "T")
#: Further parameters a value needs to be read (its switch), or to be allowed by a rule
#: between parameters (f_mode <= 0.25/T).
READ_WITH = {"k_p": {"k_p_given": True}, "k_d": {"k_d_given": True}, "f_mode": {"T": 1e-7}}


@pytest.fixture(params=["native", "pythonfmu", "controller"])
def unzipped(request: pytest.FixtureRequest) -> Path:
    """An extracted FMU: FrictionPlant native or pythonfmu, or PulseController."""
    fixture = {"native": "friction_plant_unzipped", "pythonfmu": "pythonfmu_plant_unzipped",
               "controller": "pulse_controller_unzipped"}[request.param]
    return request.getfixturevalue(fixture)


def real_parameters(unzipped: Path) -> dict:
    md = read_model_description(str(unzipped))
    return {v.name: v for v in md.modelVariables
            if v.causality == "parameter" and v.type == "Real"}


def test_every_real_parameter_has_min_and_max_around_its_start(unzipped: Path) -> None:
    params = real_parameters(unzipped)
    assert len(params) >= 10
    lacking = [name for name, v in params.items() if v.min is None or v.max is None]
    assert lacking == [], f"Real parameters without min or max: {lacking}"
    for name, v in params.items():
        low, high, start = float(v.min), float(v.max), float(v.start)
        assert math.isfinite(low) and math.isfinite(high), name
        assert low <= start <= high, (name, low, start, high)


def _sample(unzipped: Path) -> tuple[str, ...]:
    identifier = read_model_description(str(unzipped)).coSimulation.modelIdentifier
    return CONTROLLER_SAMPLE if identifier == "PulseController" else PLANT_SAMPLE


def _try(unzipped: Path, name: str, value: float) -> tuple[bool, list[str]]:
    """Initialize with ``name = value`` and step once: (accepted, messages logged as Error).

    Accepted: ``fmi2ExitInitializationMode`` and ``fmi2DoStep`` return fmi2OK and nothing
    is logged with status Error. A refusal must be fmi2Error or fmi2Discard, never fmi2OK.
    """
    fmu = FmuInstance(unzipped, "ranges")
    try:
        statuses = []
        try:
            fmu.init(**{name: value, **READ_WITH.get(name, {})})
        except FMICallException as exc:
            statuses.append(exc.status)
        else:
            h = fmu.get("T") if "T" in fmu.vars else 0.01
            try:
                fmu.fmu.doStep(0.0, h)
            except FMICallException as exc:
                statuses.append(exc.status)
        errors = fmu.logged(FMI2_ERROR)
        assert all(s in (FMI2_ERROR, FMI2_DISCARD) for s in statuses), statuses
        if errors:  # a pythonfmu FMU logs the refusal; its doStep must then be refused
            assert statuses, f"{name} = {value!r}: refused in the log, but doStep returned OK"
        return not statuses and not errors, errors
    finally:
        try:
            fmu.close()
        except FMICallException:  # fmi2Terminate refused in initialization mode
            fmu.fmu.freeInstance()


def test_a_sample_of_parameters_is_accepted_at_its_bounds_and_refused_beyond(
        unzipped: Path) -> None:
    params = real_parameters(unzipped)
    for name in _sample(unzipped):
        low, high = float(params[name].min), float(params[name].max)
        for value in (low, high):
            accepted, errors = _try(unzipped, name, value)
            assert accepted, (name, value, errors)
        for value in (math.nextafter(low, -math.inf), math.nextafter(high, math.inf)):
            accepted, errors = _try(unzipped, name, value)
            assert not accepted, (name, value)
            assert any(name in e for e in errors), (name, value, errors)
