"""FrictionPlant.fmu with the deviations of a real machine, through fmpy and the master.

The FMU and the master's in-process plant step the same model-layer object, so
their trajectories must agree bit for bit; the FMU state (get/set, serialize)
must carry every state of the deviations, the random generators included;
invalid deviation parameters are refused at initialization with their name,
value and range.
"""

from __future__ import annotations

import math
import random
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest
from fmpy.validation import validate_fmu
from harness import DEVIATIONS, FmuInstance

from papwc.controllers.settings import ControllerSettings
from papwc.errors import FmuError
from papwc.master import FmuSlave, Maneuver, PhysicsSlave, run_controller
from papwc.model.effects.encoder import MOTOR_STREAM, EncoderNoise
from papwc.model.plant import DEVIATION_PARAMETERS
from papwc.model.stickslip import quantize, simulate

T = 0.01

#: The cases of scenarios/realism.toml, and all deviations together.
CASES = {
    **DEVIATIONS,
    "all": {"v_s": 1e-3, "ripple": 0.1, "f_s_spread": 0.1, "seed": 8, "tau_u": 2e-3,
            "m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3, "noise_std": 2e-7,
            "x_resolution": 1e-7},
    # The motor encoder: its own resolution, noise and stream, on a flexible and a rigid
    # drive (x_d = x there), beside a noisy table encoder.
    "motor_encoder": {"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3, "seed": 2,
                      "x_resolution": 1e-7, "x_d_resolution": 1e-7, "x_d_noise_std": 5e-8,
                      "noise_std": 5e-8},
    "motor_encoder_rigid": {"x_d_resolution": 1e-7, "x_d_noise_std": 2e-7, "seed": 3},
    "motor_resolution_rigid": {"x_d_resolution": 1e-6},
}
OUTPUTS = ["x", "v", "x_meas", "x_d", "x_d_meas"]


def forces(seed: int, n: int) -> list[float]:
    rng = random.Random(seed)
    return [rng.choice((0.0, 0.0, 300.0, -300.0, 120.0, 200.0, -90.0)) for _ in range(n)]


def outputs(fmu: FmuInstance) -> list[float]:
    """The plant FMU's OUTPUTS now."""
    return fmu.fmu.getReal([fmu.vars[n].valueReference for n in OUTPUTS])


def step(fmu: FmuInstance, u: float) -> list[float]:
    """One step of T with the force u (N); the outputs after it."""
    fmu.advance(T, u=u)
    return outputs(fmu)


@pytest.fixture
def instances(friction_plant_unzipped: Path):
    made: list[FmuInstance] = []

    def make(params: dict) -> FmuInstance:
        made.append(FmuInstance(friction_plant_unzipped, "plant"))
        made[-1].init(**params)
        return made[-1]

    yield make
    for instance in made:
        instance.close()


@pytest.mark.parametrize("case", sorted(CASES))
def test_fmu_and_in_process_plant_agree_bit_for_bit(case: str, instances) -> None:
    params = CASES[case]
    fmu = instances(params)
    physics = PhysicsSlave()
    physics.set_start_values(params)
    index = physics.watch(OUTPUTS)
    physics.initialize()
    assert outputs(fmu) == [physics.values[i] for i in index]
    for k, u in enumerate(forces(len(case), 120)):
        physics.u = u
        physics.do_step(k * T, T)
        assert step(fmu, u) == [physics.values[i] for i in index], k


def test_defaults_are_still_eq1_exactly(instances) -> None:
    fmu = instances({})
    u_seq = forces(1, 150)
    states = simulate(u_seq, T, 150.0, 100.0, 130.0, 700.0)
    for u, (x, v) in zip(u_seq, states[1:], strict=True):
        assert step(fmu, u)[:2] == [x, v]


@pytest.mark.parametrize("case", ("stiction", "noise", "all", "lugre", "flexible",
                                  "motor_encoder", "motor_encoder_rigid"))
def test_state_get_set_and_serialize_continue_bit_for_bit(case: str, instances) -> None:
    params = CASES[case]
    u_seq = forces(7, 80)
    a = instances(params)
    for u in u_seq[:40]:
        step(a, u)
    state = a.fmu.getFMUstate()
    serialized = a.fmu.serializeFMUstate(state)
    expected = [step(a, u) for u in u_seq[40:]]
    # The same instance, back to the saved state (and its time: step 40).
    a.fmu.setFMUstate(state)
    a.fmu.freeFMUstate(state)
    a.t = 40 * T
    assert [step(a, u) for u in u_seq[40:]] == expected
    # Another instance, from the serialized state.
    b = instances(params)
    restored = b.fmu.deSerializeFMUstate(serialized)
    b.fmu.setFMUstate(restored)
    b.fmu.freeFMUstate(restored)
    b.t = 40 * T
    assert [step(b, u) for u in u_seq[40:]] == expected
    assert not [m for m in a.messages + b.messages if "refused" in m.text]


def test_random_stiction_and_noise_follow_the_seed(instances) -> None:
    u_seq = forces(3, 150)
    runs = {}
    for seed in (1, 1, 2):
        fmu = instances({"f_s_spread": 0.1, "noise_std": 2e-7, "x_resolution": 1e-7,
                         "seed": seed})
        runs.setdefault(seed, []).append([step(fmu, u) for u in u_seq])
    assert runs[1][0] == runs[1][1]
    assert runs[1][0] != runs[2][0]


@pytest.mark.parametrize(("params", "text"), [
    ({"ripple": 1.5}, "parameter ripple = 1.5: must satisfy 0 <= ripple < 1"),
    ({"tau_u": -1.0}, "parameter tau_u = -1.0 s: must satisfy 0 <= tau_u <= 10 s"),
    ({"seed": -3}, "parameter seed = -3: must be a whole number 0 <= seed <= 2147483647"),
    ({"m_d": 20.0}, "k_t = 0.0 N/m: a flexible drive (m_d = 20.0 kg > 0) needs a coupling"),
    ({"f_s_spread": 0.5}, "the lowest breakaway force f_s*(1 - f_s_spread) = 65.0 N"),
])
def test_invalid_deviation_parameter_is_refused_at_initialization(
        friction_plant_fmu: Path, params: dict, text: str) -> None:
    plant = FmuSlave(friction_plant_fmu)
    try:
        plant.set_start_values(params)
        with pytest.raises(FmuError, match="refused the parameters") as info:
            plant.initialize()
        assert text in str(info.value)
    finally:
        plant.close()


def test_model_description_declares_the_deviations(friction_plant_fmu: Path) -> None:
    assert validate_fmu(str(friction_plant_fmu)) == []
    with zipfile.ZipFile(friction_plant_fmu) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    declared = {sv.get("name"): (sv.get("causality"), next(iter(sv)))
                for sv in root.iter("ScalarVariable")}
    for var in DEVIATION_PARAMETERS:
        causality, typed = declared[var.name]
        assert causality == "parameter"
        assert typed.tag == var.type
        assert float(typed.get("start")) == var.default
        # an excluded bound (ripple < 1) is declared as the next double inside it
        assert float(typed.get("min")) == var.fmi_min
        assert float(typed.get("max")) == var.fmi_max
        assert var.fmi_max == (math.nextafter(var.max, 0.0) if var.max_open else var.max)
        if var.type == "Real":
            assert typed.get("unit") == var.unit


def test_closed_loop_through_the_fmu_equals_the_in_process_plant(friction_plant_fmu) -> None:
    params = CASES["all"]
    maneuver = Maneuver(x_ref=1e-3, T=T, duration=0.6, iterations=2)
    settings = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8)
    results = []
    for plant in (FmuSlave(friction_plant_fmu), PhysicsSlave()):
        try:
            plant.set_start_values(params)
            results.append(run_controller(plant, settings, maneuver))
        finally:
            plant.close()
    fmu, physics = results
    assert not fmu.error and not physics.error
    for a, b in zip(fmu.traces, physics.traces, strict=True):
        for name in ("x", "v", "x_meas", "u"):
            assert a.column(name) == b.column(name)


def test_motor_encoder_reads_the_drive_with_its_own_stream(instances) -> None:
    """On a rigid drive x_d = x and x_d_meas follows x_meas's law with the motor encoder's
    parameters (so the same parameters give the same reading); on a flexible drive the
    motor side rings while the table is stuck, and its noise stream is not the table's."""
    u_seq = forces(5, 120)
    table = instances({"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 4})
    motor = instances({"x_d_noise_std": 2e-7, "x_d_resolution": 1e-7, "seed": 4})
    noise_d = EncoderNoise(2e-7, 4, MOTOR_STREAM)
    for k, u in enumerate(u_seq, start=1):
        x, _, x_meas, _, _ = step(table, u)
        x2, _, x_meas2, x_d, x_d_meas = step(motor, u)
        assert (x2, x_d, x_meas2) == (x, x, x)  # an ideal table encoder
        # x_meas's law with the motor encoder's parameters and stream, point k
        assert x_d_meas == quantize(x + noise_d.draw(k), 1e-7)
    both = instances({"noise_std": 2e-7, "x_d_noise_std": 2e-7, "seed": 4})
    rows = [step(both, u) for u in u_seq]
    assert all(x_d == x for x, _, _, x_d, _ in rows)
    assert sum(x_meas != x_d_meas for _, _, x_meas, _, x_d_meas in rows) > 100
    flexible = instances(CASES["flexible"])
    rows = [step(flexible, u) for u in [300.0] * 3 + [0.0] * 30]
    assert any(x_d != x for x, _, _, x_d, _ in rows)
