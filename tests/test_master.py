"""The co-simulation master, scenario files and the run/reproduce commands."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from papwc.cli import main
from papwc.controllers.settings import ControllerSettings
from papwc.errors import FmuError, ScenarioError
from papwc.master import Maneuver, run_controller, run_iteration
from papwc.scenario import load_scenario
from papwc.master import FmuSlave, PhysicsSlave

ROOT = Path(__file__).resolve().parent.parent


class ScriptedController:
    """Plays a fixed force sequence (N); the interface of papwc.core.Controller."""

    def __init__(self, forces):
        self.forces = list(forces)
        self.mode = 1
        self.pulses = 0
        self.revision = 0

    def reset(self):
        pass

    def update(self, t, x_meas, x_ref):
        k = int(round(t / 0.01))
        return self.forces[k] if k < len(self.forces) else 0.0

    def estimates(self):
        return {"b_hat": math.nan, "f_c_hat": math.nan}


def test_fmu_discard_stops_the_run_and_keeps_what_was_recorded(friction_plant_fmu):
    plant = FmuSlave(friction_plant_fmu)
    plant.set_start_values({"m": 150.0})
    try:
        plant.initialize()
        forces = [300.0] * 3 + [0.0] * 2 + [math.nan]
        trace = run_iteration(plant, ScriptedController(forces), Maneuver(duration=0.2))
    finally:
        plant.close()
    assert len(trace) == 6  # samples 0..5 recorded, the 6th step was refused
    assert "fmi2DoStep" in trace.error
    assert "t = 0.05" in trace.error
    assert "nan" in trace.error.lower()  # the FMU's log names the value
    assert trace.column("x")[3] > 0.0  # the motion before the failure is kept


def test_invalid_plant_parameter_is_refused_with_its_name(friction_plant_fmu):
    plant = FmuSlave(friction_plant_fmu)
    plant.set_start_values({"f_s": 50.0})
    try:
        result = run_controller(plant, ControllerSettings(), Maneuver(iterations=2))
    finally:
        plant.close()
    assert result.error.startswith("iteration 1:")
    assert "f_s = 50.0" in result.error
    assert "fmi2ExitInitializationMode" in result.error
    assert result.traces == []


def test_missing_fmu_is_a_clear_error(tmp_path):
    with pytest.raises(FmuError, match="does not exist"):
        FmuSlave(tmp_path / "nothing.fmu")


def test_delayed_timing_applies_the_force_one_step_later():
    forces = [300.0, 300.0, 0.0, 0.0, 0.0]
    traces = {}
    for timing in ("immediate", "delayed"):
        plant = PhysicsSlave()
        plant.initialize()
        traces[timing] = run_iteration(plant, ScriptedController(forces),
                                       Maneuver(duration=0.05, timing=timing))
    u_now = traces["immediate"].column("u")[:-1]
    u_late = traces["delayed"].column("u")[:-1]
    assert u_now == forces
    assert u_late == [0.0] + forces[:-1]
    assert traces["delayed"].column("x")[1] == 0.0 < traces["immediate"].column("x")[1]


def test_iterations_restart_the_plant_and_carry_the_estimates(friction_plant_fmu):
    plant = FmuSlave(friction_plant_fmu)
    plant.set_start_values({"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0})
    try:
        result = run_controller(plant, ControllerSettings(kind="papwc", t_p_max=0.03),
                                Maneuver(duration=1.0, iterations=3))
    finally:
        plant.close()
    assert not result.error
    for tr in result.traces:
        assert tr.column("x")[0] == 0.0 and tr.column("v")[0] == 0.0  # starts at rest at 0
    b_start = [tr.column("b_hat")[0] for tr in result.traces]
    b_end = [tr.column("b_hat")[-1] for tr in result.traces]
    assert b_start[1] == b_end[0] and b_start[2] == b_end[1]
    assert b_start[0] != b_end[0]


def _write(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


GOOD = """
name = "t"
[plant]
m = 150.0
[maneuver]
x_ref = 0.01
T = 0.01
duration = 0.5
iterations = 1
[[controller]]
kind = "papwc"
"""


@pytest.mark.parametrize(
    "change, field",
    [
        (("m = 150.0", "m = -1.0"), "m"),
        (("m = 150.0", "m = 150.0\nf_s = 20.0"), "f_s"),
        (("m = 150.0", "mass = 150.0"), "mass"),
        (("T = 0.01", "T = 0.0"), "'T'"),
        (("iterations = 1", "iterations = 1.5"), "iterations"),
        (('kind = "papwc"', 'kind = "pid"'), "kind"),
        (('kind = "papwc"', 'kind = "papwc"\nK_c = 2.5'), "K_c"),
        (('kind = "papwc"', 'kind = "papwc"\nt_p_max = "long"'), "t_p_max"),
        (('kind = "papwc"', 'kind = "papwc"\nf_c_est = 400.0'), "f_c_est"),
        (('kind = "papwc"', 'kind = "papwc"\ntolerence = 1e-5'), "tolerence"),
    ],
)
def test_scenario_errors_name_the_file_and_the_field(tmp_path, change, field):
    path = _write(tmp_path, GOOD.replace(*change))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert str(path) in str(info.value)
    assert field in str(info.value)


def test_scenario_toml_syntax_error_names_the_file(tmp_path):
    path = _write(tmp_path, GOOD + "\n[[controller]\n")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(path)


def test_shipped_scenarios_load():
    from papwc.battery import load_battery

    paths = sorted((ROOT / "scenarios").glob("*.toml"))
    assert len(paths) >= 6
    for path in paths:
        if "[monte_carlo]" in path.read_text() or "[sweep]" in path.read_text():
            assert load_battery(path)  # a battery file, read by papwc battery
        else:
            assert load_scenario(path).controllers


def test_cli_run_writes_summary_traces_and_plots(tmp_path, friction_plant_fmu, capsys):
    path = _write(tmp_path, GOOD + '\n[[controller]]\nkind = "pwc"\nt_p_max = 0.03\n')
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--fmu", str(friction_plant_fmu)]) == 0
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    for col in ("controller", "t_p_max", "iteration", "final_error_m", "pulses",
                "settle_time_s", "limit_cycle", "b_hat", "f_c_hat"):
        assert col in rows[0]
    assert len(rows) == 2
    assert {r["status"] for r in rows} == {"ok"}
    assert sorted(p.name for p in out.glob("trace_*.csv")) == [
        "trace_papwc_tpmax_inf_it1.csv", "trace_pwc_tpmax_0.03_it1.csv"]
    for png in ("error.png", "force.png", "estimates.png"):
        assert (out / png).stat().st_size > 1000
    assert "final_error_m" in capsys.readouterr().out


def test_cli_reports_a_bad_scenario_without_a_traceback(tmp_path, capsys):
    path = _write(tmp_path, GOOD.replace("m = 150.0", "m = -1.0"))
    assert main(["run", str(path), "--plant", "physics"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "m = -1.0" in err
