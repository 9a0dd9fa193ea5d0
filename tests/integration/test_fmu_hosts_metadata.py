"""What other hosts read off the FMUs: complete model descriptions (``fmpy validate`` clean,
ranges, ``initial="calculated"`` outputs with their InitialUnknowns, no feedthrough), the
outputs' values in initialization mode, the controller kind as an Integer, and refusals that
reach stderr when the host's logging is off."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description
from harness import FmuInstance

from papwc.fmubuild.model_description import read_model_description as read_md_xml
from papwc.fmubuild.native_tables import NATIVE_KINDS
from papwc.model.controller_settings import KIND_CODES, PULSE_CONTROLLER_VARIABLES
from papwc.model.plant import PLANT_OUTPUTS, PLANT_PARAMETERS

FMPY = [sys.executable, "-m", "fmpy.cli"]


def fmpy_cli(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    if env is None:
        env = {k: v for k, v in os.environ.items() if k != "PAPWC_FMU_STDERR"}
    return subprocess.run([*FMPY, *args], capture_output=True, text=True, timeout=300,
                          check=False, env=env)


@pytest.mark.parametrize("name", ["FrictionPlant.fmu", "PulseController.fmu"])
def test_fmpy_validate_is_clean(fmu_dir: Path, name: str) -> None:
    done = fmpy_cli("validate", str(fmu_dir / name))
    assert done.returncode == 0 and "No problems found" in done.stdout, done.stdout + done.stderr


@pytest.mark.parametrize("name, table", [("FrictionPlant.fmu", PLANT_PARAMETERS),
                                         ("PulseController.fmu", PULSE_CONTROLLER_VARIABLES)])
def test_every_bounded_parameter_declares_its_range(fmu_dir: Path, name: str, table) -> None:
    root = read_md_xml(fmu_dir / name)
    declared = {sv.get("name"): next(iter(sv)) for sv in root.iter("ScalarVariable")}
    checked = 0
    for var in table:
        if var.causality != "parameter" or var.type not in ("Real", "Integer"):
            continue
        typed = declared[var.name]
        if var.min is not None:  # an excluded bound: the next double inside it
            low = math.nextafter(var.min, math.inf) if var.min_open else var.min
            assert float(typed.get("min")) == low, var.name
            checked += 1
        if var.max is not None:
            high = math.nextafter(var.max, -math.inf) if var.max_open else var.max
            assert float(typed.get("max")) == high, var.name
        if var.nominal is not None:
            assert float(typed.get("nominal")) == var.nominal, var.name
    assert checked >= 5


def test_plant_outputs_are_calculated_from_the_parameters(friction_plant_fmu: Path) -> None:
    md = read_model_description(str(friction_plant_fmu))
    by_name = {v.name: v for v in md.modelVariables}
    index = {v.name: i + 1 for i, v in enumerate(md.modelVariables)}
    for var in PLANT_OUTPUTS:
        assert by_name[var.name].initial == "calculated" and by_name[var.name].start is None
    assert sorted(index[u.variable.name] for u in md.initialUnknowns) == sorted(
        index[v.name] for v in PLANT_OUTPUTS)
    # no direct feedthrough: x, v, x_meas, stuck do not depend on u at the same instant
    assert all(o.dependencies == [] for o in md.outputs)


def test_outputs_in_initialization_mode_follow_the_parameters(
        friction_plant_unzipped: Path) -> None:
    instance = FmuInstance(friction_plant_unzipped, "plant")
    fmu = instance.fmu
    vr = {name: v.valueReference for name, v in instance.vars.items()}
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([vr["x0"], vr["v0"], vr["x_resolution"]], [0.00123456, -0.02, 1e-4])
        fmu.enterInitializationMode()
        x, v, x_meas = fmu.getReal([vr["x"], vr["v"], vr["x_meas"]])
        (stuck,) = fmu.getBoolean([vr["stuck"]])
        assert (x, v) == (0.00123456, -0.02)
        assert math.isclose(x_meas, 0.0012, abs_tol=1e-15) and not stuck
        fmu.setReal([vr["v0"]], [0.0])
        assert fmu.getBoolean([vr["stuck"]]) == [True]
        fmu.exitInitializationMode()
        assert fmu.getReal([vr["x"], vr["v"]]) == [0.00123456, 0.0]
        fmu.terminate()
    finally:
        fmu.freeInstance()


def controller(unzipped: Path) -> FmuInstance:
    """PulseController.fmu driven by fmpy's FMU2Slave (a Python host), experiment set up."""
    c = FmuInstance(unzipped, "controller")
    c.fmu.setupExperiment(startTime=0.0)
    return c


def run(c: FmuInstance, steps: int = 3) -> list[float]:
    """Initialize with the values set so far, then ``steps`` steps of 0.01 s; the forces."""
    c.fmu.enterInitializationMode()
    c.fmu.exitInitializationMode()
    forces = []
    for k in range(steps):
        c.fmu.doStep(currentCommunicationPoint=k * 0.01, communicationStepSize=0.01)
        forces.append(c.get("u"))
    return forces


@pytest.mark.parametrize("code", range(len(KIND_CODES) + 1))
def test_kind_code_selects_the_kind(pulse_controller_unzipped: Path,
                                    pulse_controller_python_unzipped: Path, code) -> None:
    """Each kind in the build that has it (the native one: pwc, papwc, pid)."""
    native = code == 0 or KIND_CODES[code - 1] in NATIVE_KINDS
    c = controller(pulse_controller_unzipped if native else pulse_controller_python_unzipped)
    try:
        c.set("kind_code", code)
        c.set("x_ref_offset", 0.01)
        forces = run(c)
        want = "papwc" if code == 0 else KIND_CODES[code - 1]  # 0: the String kind's start
        assert c.get("kind") == want
        assert forces[0] > 0.0  # the reference is x_ref_offset + x_ref = 0.01 m
    finally:
        c.close()


def test_kind_and_kind_code_that_disagree_are_refused(
        pulse_controller_python_unzipped: Path) -> None:
    """The pythonfmu build (the native one refuses with fmi2Error at initialization:
    test_native_controller_fmu.py)."""
    pulse_controller_unzipped = pulse_controller_python_unzipped
    c = controller(pulse_controller_unzipped)
    try:
        c.set("kind", "pwc")
        c.set("kind_code", KIND_CODES.index("papwc") + 1)
        with pytest.raises(Exception, match="status 2"):  # Discard: initialization refused
            run(c, 1)
    finally:
        c.close()
    same = controller(pulse_controller_unzipped)
    try:
        same.set("kind", "pwc")
        same.set("kind_code", KIND_CODES.index("pwc") + 1)
        same.set("x_ref_offset", 0.01)
        assert run(same, 1)[0] > 0.0
    finally:
        same.close()


def test_fmpy_simulate_shows_the_refusal_without_debug_logging(friction_plant_fmu: Path,
                                                               tmp_path: Path) -> None:
    out = tmp_path / "out.csv"
    done = fmpy_cli("simulate", str(friction_plant_fmu), "--start-values", "m", "-1",
                    "--output-interval", "0.01", "--stop-time", "0.05", "--output-file",
                    str(out))
    lines = [line for line in done.stderr.splitlines() if line.startswith("FrictionPlant")]
    assert lines == ["FrictionPlant FrictionPlant: parameter m = -1.0 kg: must satisfy 1e-06 <= "
                     "m <= 1e+09 kg; initialization refused (fmi2Error)"], done.stderr
    assert done.returncode != 0  # fmi2ExitInitializationMode returned fmi2Error
    quiet = fmpy_cli("simulate", str(friction_plant_fmu), "--start-values", "m", "-1",
                     "--output-interval", "0.01", "--stop-time", "0.05", "--output-file",
                     str(out), env={**os.environ, "PAPWC_FMU_STDERR": "0"})
    assert "must satisfy 1e-06 <= m" not in quiet.stderr


def test_a_refused_step_is_told_once(friction_plant_fmu: Path, tmp_path: Path) -> None:
    inputs = tmp_path / "in.csv"
    inputs.write_text('"time","u"\n0.0,nan\n1.0,nan\n')
    done = fmpy_cli("simulate", str(friction_plant_fmu), "--input-file", str(inputs),
                    "--output-interval", "0.01", "--stop-time", "0.05", "--output-file",
                    str(tmp_path / "out.csv"))
    lines = [line for line in done.stderr.splitlines() if line.startswith("FrictionPlant")]
    assert len(lines) == 1 and "input u = nan N is not finite" in lines[0], done.stderr
