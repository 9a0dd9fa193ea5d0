"""Closed loops through the master with FrictionPlant.fmu: the paper's results, the FMU as
a slave (restarts, failures), and the FMU against the in-process plant."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from harness import TABLE_1, ScriptedController

from papwc.analysis import paper
from papwc.controllers.settings import ControllerSettings
from papwc.errors import FmuError
from papwc.master import (
    FmuSlave,
    Maneuver,
    PhysicsSlave,
    run_controller,
    run_iteration,
)
from papwc.results.summary import summarize
from papwc.scenario import load_scenario

T = 0.01


def _run(kind, t_p_max, K_c, tolerance, plant, **kw):
    settings = ControllerSettings(kind=kind, t_p_max=t_p_max, K_c=K_c, tolerance=tolerance, **kw)
    man = Maneuver(x_ref=0.01, T=T, duration=2.0, iterations=10)
    result = run_controller(plant, settings, man)
    assert not result.error
    return [summarize(tr, tolerance) for tr in result.traces]


@pytest.mark.slow
def test_pwc_bounded_ends_in_the_d_min_limit_cycle(friction_plant_fmu):
    with FmuSlave(friction_plant_fmu) as plant:
        plant.set_start_values(TABLE_1)
        # the paper's law: the safeguards' pulse budget would end the cycle it shows
        summaries = _run("pwc", 0.03, 0.5, 0.0, plant, safeguards=False)
    d_min = paper.d_min(300.0, T, 150.0, 100.0, 700.0)  # Eq. (19)
    for s in (summaries[0], summaries[-1]):
        assert s["limit_cycle"]
        # The cycle is one-sample pulses at f_p_max back and forth: its peak-to-peak is
        # Eq. (19) to the rounding of two positions near 0.01 m. Measured: 4.7e-15
        # relative (formerly checked to 10 %).
        assert s["cycle_p2p_m"] == pytest.approx(d_min, rel=1e-14)


@pytest.mark.slow
@pytest.mark.parametrize("t_p_max", [0.03, math.inf])
def test_papwc_tenth_iteration_settles_without_limit_cycle(friction_plant_fmu, t_p_max):
    with FmuSlave(friction_plant_fmu) as plant:
        plant.set_start_values(TABLE_1)
        summaries = _run("papwc", t_p_max, 0.8, 2e-5, plant)
    last = summaries[9]
    assert abs(last["final_error_m"]) <= 2e-5
    assert not last["limit_cycle"]
    assert math.isfinite(last["settle_time_s"])


def test_paper_scenario_file_gives_the_same_results_on_fmu_and_physics(friction_plant_fmu,
                                                                       paper_toml):
    sc = load_scenario(paper_toml)
    man = dataclasses.replace(sc.maneuver, iterations=2)
    for cs in sc.controllers:
        with FmuSlave(friction_plant_fmu) as fmu:
            fmu.set_start_values(sc.plant)
            a = run_controller(fmu, cs, man)
        phys = PhysicsSlave()
        phys.set_start_values(sc.plant)
        b = run_controller(phys, cs, man)
        for ta, tb in zip(a.traces, b.traces, strict=True):
            # the FMU runs the same physics: bit for bit (formerly x to 1e-12 m)
            assert ta.column("x") == tb.column("x")
            assert ta.column("v") == tb.column("v")
            assert ta.column("u")[:-1] == tb.column("u")[:-1]


def test_fmu_discard_stops_the_run_and_keeps_what_was_recorded(friction_plant_fmu):
    with FmuSlave(friction_plant_fmu) as plant:
        plant.set_start_values({"m": 150.0})
        plant.initialize()
        forces = [300.0] * 3 + [0.0] * 2 + [math.nan]
        trace = run_iteration(plant, ScriptedController(forces), Maneuver(duration=0.2))
    assert len(trace) == 6  # samples 0..5 recorded, the 6th step was refused
    assert "fmi2DoStep" in trace.error
    assert "t = 0.05" in trace.error
    assert "nan" in trace.error.lower()  # the FMU's log names the value
    assert "input u = nan N is not finite" in trace.error
    assert trace.column("x")[3] > 0.0  # the motion before the failure is kept


def test_invalid_plant_parameter_is_refused_with_its_name(friction_plant_fmu):
    with FmuSlave(friction_plant_fmu) as plant:
        plant.set_start_values({"f_s": 50.0})
        result = run_controller(plant, ControllerSettings(), Maneuver(iterations=2))
    assert result.error.startswith("iteration 1:")
    assert "f_s = 50.0" in result.error
    assert "parameter f_s = 50.0 N: must be >= f_c = 100.0 N" in result.error
    assert "fmi2ExitInitializationMode" in result.error
    assert result.traces == []


def test_missing_or_broken_fmu_is_a_clear_error(tmp_path, friction_plant_fmu):
    with pytest.raises(FmuError, match="does not exist"):
        FmuSlave(tmp_path / "nothing.fmu")
    (tmp_path / "broken.fmu").write_text("not a zip")
    with pytest.raises(FmuError, match="broken.fmu'?: not a zip archive"):
        FmuSlave(tmp_path / "broken.fmu")
    with pytest.raises(FmuError, match="has no Integer input 'maneuver'"):
        FmuSlave(friction_plant_fmu, restart_input="maneuver")
    with FmuSlave(friction_plant_fmu) as plant:
        with pytest.raises(FmuError, match="has no variable 'mass'"):
            plant.set_start_values({"mass": 1.0})
        with pytest.raises(FmuError, match="variable 'x' is not an input"):
            plant.input_setter(["x"])


@pytest.mark.parametrize("timing", ["immediate", "delayed"])
def test_iterations_restart_the_plant_and_carry_the_estimates(friction_plant_fmu, timing):
    with FmuSlave(friction_plant_fmu) as plant:
        plant.set_start_values(TABLE_1)
        result = run_controller(plant, ControllerSettings(kind="papwc", t_p_max=0.03),
                                Maneuver(duration=1.0, iterations=3, timing=timing))
    assert not result.error
    for tr in result.traces:
        assert tr.column("x")[0] == 0.0 and tr.column("v")[0] == 0.0  # starts at rest at 0
    b_start = [tr.column("b_hat")[0] for tr in result.traces]
    b_end = [tr.column("b_hat")[-1] for tr in result.traces]
    assert b_start[1] == b_end[0] and b_start[2] == b_end[1]
    assert b_start[0] != b_end[0]
    # the restarted FMU (its state after initialization restored) is the in-process plant
    phys = PhysicsSlave()
    phys.set_start_values(TABLE_1)
    again = run_controller(phys, ControllerSettings(kind="papwc", t_p_max=0.03),
                           Maneuver(duration=1.0, iterations=3, timing=timing))
    assert [tr.columns for tr in result.traces] == [tr.columns for tr in again.traces]


def test_the_plant_fmu_and_the_physics_offer_the_same_variables(friction_plant_fmu: Path):
    with FmuSlave(friction_plant_fmu) as fmu:
        assert fmu.variables() == PhysicsSlave().variables()


def test_an_input_holding_its_value_is_not_sent_again_and_is_after_a_restart(
        friction_plant_fmu):
    """FmuSlave does not repeat fmi2SetReal for a value the input holds (FMI keeps an input
    until it is set); after a restart (a restored state) or a setter of the same input, it
    sends it again: the FMU's own ``u`` is the force each step asked for."""
    from papwc.master import FmuSlave

    slave = FmuSlave(friction_plant_fmu)
    try:
        slave.set_start_values(TABLE_1)
        iu, ix = slave.watch(["u", "x"])
        set_a, set_b = slave.input_setter(["u"]), slave.input_setter(["u"])
        slave.initialize()
        forces = [140.0, 140.0, 0.0, 0.0, -0.0, 140.0]
        seen = []
        for k, u in enumerate(forces):
            set_a(u)
            slave.do_step(k * 0.01, 0.01)
            seen.append(slave.values[iu])
        assert seen == forces
        assert math.copysign(1.0, seen[4]) == -1.0  # -0.0 is sent, not taken for 0.0
        x_first = slave.values[ix]
        slave.restart()  # the FMU's u is 0 again
        set_a(140.0)
        slave.do_step(0.0, 0.01)
        assert slave.values[iu] == 140.0 and slave.values[ix] > 0.0
        set_b(0.0)  # another setter of u
        set_a(140.0)
        slave.do_step(0.01, 0.01)
        assert slave.values[iu] == 140.0
        assert x_first > 0.0
    finally:
        slave.close()
