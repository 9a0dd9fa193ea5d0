"""``papwc reproduce`` writes the claims table; the reading settings as FMU parameters."""

from __future__ import annotations

import csv
import dataclasses
import math
import re
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest

from papwc.analysis.claims import CLAIMS, CLAIMS_COLUMNS, KNOWN_READINGS
from papwc.analysis.paper import formula_numbers
from papwc.cli import main
from papwc.controllers.settings import ControllerSettings
from papwc.master import FmuSlave, Maneuver, PhysicsSlave, run_closed_loop, run_controller
from papwc.model.controller_settings import fmu_parameters
from papwc.scenario import load_scenario

#: The formula rows of paper_numbers.csv (the reading notes' table), value for value.
FORMULA_VALUES = [
    2.0, 0.0915683433829429, 0.07071067811865475, 0.5963198826941584, 0.8141177476650238,
    0.040950608078260675, 0.035641987631557265, 0.0025608471550334043,
    0.00018567455439166738, 1.2684129415152859e-05, 14.63833648447758, 1.375,
]


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory, friction_plant_fmu) -> Path:
    out = tmp_path_factory.mktemp("reproduce")
    assert main(["reproduce", "--out", str(out), "--fmu", str(friction_plant_fmu)]) == 0
    return out


def test_formula_numbers_are_unchanged(reproduced):
    with open(reproduced / "paper_numbers.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    formulas = formula_numbers()
    assert [r["quantity"] for r in rows[:len(formulas)]] == [q for q, _, _ in formulas]
    assert [float(r["computed"]) for r in rows[:len(formulas)]] == FORMULA_VALUES


def test_claims_csv_and_report(reproduced):
    with open(reproduced / "claims.csv", newline="") as f:
        reader = csv.DictReader(f)
        assert reader.fieldnames == CLAIMS_COLUMNS
        rows = list(reader)
    assert [r["claim"] for r in rows] == [c.claim for c in CLAIMS]
    by_key = {c.key: r for c, r in zip(CLAIMS, rows, strict=True)}
    assert [c.key for c, r in zip(CLAIMS, rows, strict=True)
            if r["reproduced_by_default"] == "yes"] == [
        "limit_cycle_d_min", "unbounded_2t_cycle", "bounded_b_hat_closer", "papwc_final_error"]
    for key, row in by_key.items():
        if row["reproduced_by_default"] == "no":
            assert row["reading"].startswith(KNOWN_READINGS[key].text())
            assert row["reproduced_by_reading"] == "yes"
    # The FMU runs give the values of the in-process plant (tests/unit/test_readings.py).
    assert by_key["unbounded_2t_cycle"]["default_value"].startswith(
        "widths {2} samples; peak-to-peak 0.0006937 m")
    assert by_key["unbounded_b_hat_above_b"]["reading_value"] == "b_hat/b = 1.310"
    report = (reproduced / "report.md").read_text()
    assert "## The paper's simulation claims (Section 4)" in report
    assert "| " + " | ".join(CLAIMS_COLUMNS) + " |" in report
    assert not (reproduced / "readings.csv").exists()


def test_reproduce_refuses_zero_workers(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--readings", "--workers", "0"]) == 2
    assert "--workers 0: must be >= 1" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


# --- the reading settings through PulseController.fmu ---------------------------------------


def _fmu_values(settings: ControllerSettings) -> dict:
    """The settings as PulseController.fmu start values (computed ones left at their starts)."""
    return fmu_parameters(settings.to_mapping(with_none=True))


@pytest.mark.parametrize("kind", ["pwc", "papwc"])
def test_controller_fmu_reads_the_reading_settings(pulse_controller_fmu, project_dir, kind):
    scenario = load_scenario(project_dir / "scenarios" / "paper.toml")
    base = next(s for s in scenario.controllers if s.kind == kind)
    settings = dataclasses.replace(base, regressor=1, update_covariance=False, K_c=0.7,
                                   t_p_max=0.03, **({"floor_mode": 1} if kind == "papwc"
                                                    else {}))
    maneuver = Maneuver(**{**scenario.maneuver.__dict__, "iterations": 3})
    plant = PhysicsSlave()
    plant.set_start_values(scenario.plant)
    expected = run_controller(plant, settings, maneuver)
    default = run_controller(plant, base, maneuver)
    controller = FmuSlave(pulse_controller_fmu, name="controller", restart_input="maneuver")
    try:
        controller.set_start_values({**_fmu_values(settings), "T": maneuver.T})
        plant = PhysicsSlave()
        plant.set_start_values(scenario.plant)
        got = run_closed_loop(plant, controller, maneuver, settings)
    finally:
        controller.close()
    assert not got.error
    for a, b in zip(got.traces, expected.traces, strict=True):
        assert a.column("u")[:-1] == b.column("u")[:-1]
        assert a.column("b_hat") == b.column("b_hat")
    assert any(a.column("u") != b.column("u")
               for a, b in zip(default.traces, expected.traces, strict=True))


def test_model_description_declares_the_reading_settings(pulse_controller_fmu):
    with zipfile.ZipFile(pulse_controller_fmu) as z:
        md = ET.fromstring(z.read("modelDescription.xml"))
    declared = {sv.get("name"): sv for sv in md.iter("ScalarVariable")}
    assert declared["regressor"].find("Integer").attrib == {"start": "0", "min": "0",
                                                           "max": "1"}
    assert declared["floor_mode"].find("Integer").attrib == {"start": "0", "min": "0",
                                                            "max": "2"}
    assert declared["update_covariance"].find("Boolean").attrib == {"start": "true"}
    assert "Eq. (14)" in declared["update_covariance"].get("description")


def test_ssp_binds_the_boolean_setting_and_libcosim_applies_it(
        friction_plant_fmu, pulse_controller_fmu, project_dir, tmp_path):
    from papwc.controllers import make_controller
    from papwc.fmubuild.ssp_writer import build_closed_loop_ssp
    from papwc.master import run_iteration

    text = (project_dir / "scenarios" / "paper.toml").read_text()
    text = text.replace("delta_inv = 1e-5", "delta_inv = 1e-5\nupdate_covariance = false", 1)
    path = tmp_path / "fixed.toml"
    path.write_text(text)
    ssp = build_closed_loop_ssp(tmp_path, path, friction_plant_fmu, pulse_controller_fmu)
    with zipfile.ZipFile(ssp) as z:
        ssd = z.read("SystemStructure.ssd").decode()
    assert re.search(r'<ssv:Parameter name="update_covariance">\s*<ssv:Boolean value="false" />',
                     ssd)

    execution_module = pytest.importorskip("libcosimpy.CosimExecution")
    execution = execution_module.CosimExecution.from_ssp_file(str(ssp))
    scenario = load_scenario(path)
    n = scenario.maneuver.n_steps
    for _ in range(n):
        assert execution.step()
    controller = execution.slave_index_from_instance_name("controller")
    refs = {v.name.decode(): v.reference for v in execution.slave_variables(controller)}
    from libcosimpy.CosimObserver import CosimObserver

    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    assert execution.step()
    b_hat = observer.last_real_values(controller, [refs["b_hat"]])[0]

    settings = next(s for s in scenario.controllers if s.kind == "papwc")
    assert settings.update_covariance is False
    maneuver = dataclasses.replace(scenario.maneuver, iterations=1, timing="delayed",
                                   duration=(n + 1) * scenario.maneuver.T)
    expected = {}
    for update in (False, True):
        plant = PhysicsSlave()
        plant.set_start_values(scenario.plant)
        trace = run_iteration(plant, make_controller(
            dataclasses.replace(settings, update_covariance=update), maneuver.T), maneuver)
        expected[update] = trace.column("b_hat")[-1]
    assert expected[False] != pytest.approx(expected[True], rel=1e-6)
    assert b_hat == pytest.approx(expected[False], rel=1e-6)


def test_controller_fmu_state_holds_the_planned_pulse(pulse_controller_fmu):
    from fmpy import extract, instantiate_fmu, read_model_description

    unzip = extract(str(pulse_controller_fmu))
    md = read_model_description(unzip)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = instantiate_fmu(unzip, md)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setString([vr["kind"]], ["pwc"])
        fmu.setInteger([vr["regressor"]], [1])
        fmu.setBoolean([vr["update_covariance"]], [False])
        fmu.setReal([vr["x_ref"]], [3e-3])
        fmu.exitInitializationMode()
        fmu.setReal([vr["x_meas"]], [0.0])
        fmu.doStep(0.0, 0.01)  # plans a pulse
        state = fmu.getFMUstate()
        serialized = fmu.serializeFMUstate(state)
        fmu.freeFMUstate(state)

        def steps() -> list[tuple[float, float]]:
            out = []
            for k in range(1, 30):  # the pulse moves the mass 5e-4 m, then it rests
                fmu.setReal([vr["x_meas"]], [1e-4 * min(k, 5)])
                fmu.doStep(0.01 * k, 0.01)
                out.append(tuple(fmu.getReal([vr["u"], vr["b_hat"]])))
            return out

        first = steps()
        restored = fmu.deSerializeFMUstate(serialized)
        fmu.setFMUstate(restored)
        fmu.freeFMUstate(restored)
        assert steps() == first
        b_hats = [b for _, b in first]
        assert b_hats[-1] != b_hats[0] and all(math.isfinite(b) for b in b_hats)
    finally:
        fmu.terminate()
        fmu.freeInstance()
