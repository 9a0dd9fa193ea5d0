"""The plant's deviations from Eq. (1): papwc.model.dynamics and papwc.model.effects.

Each deviation is checked against references that share no code with it:

* scipy's ``solve_ivp`` with events and rtol 1e-12 (tests/unit/plant_reference.py)
  on random force sequences: positions agree to :data:`X_TOL`, velocities to
  :data:`V_TOL`;
* closed forms written out here: LuGre's steady state is the Stribeck curve,
  the flexible mode's free vibration, the lag's first-order step response;
* the defaults give :func:`papwc.model.stickslip.step` bit for bit.

Random stiction and encoder noise are checked for reproducibility from their
seed, their range and distribution, and the state round trip.
"""

from __future__ import annotations

import json
import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest
from harness import (
    BOUND_MARGIN,
    REALISM_VARIANTS,
    highest_coupling_damping,
    highest_damping,
    highest_mode_stiffness,
    inside_max,
    inside_min,
    lowest_integrated_mass,
    random_forces,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import stats

from papwc.master import PhysicsSlave
from papwc.model import stickslip
from papwc.model.dynamics import STATE_FIELDS, Plant
from papwc.model.effects.draws import normal, uniform
from papwc.model.effects.encoder import EncoderNoise
from papwc.model.effects.stiction import RandomStiction
from papwc.model.plant import (
    DAMPING_RATE_MAX,
    DEVIATION_PARAMETERS,
    INTEGRATED,
    MODE_FREQUENCY_MAX,
    OFF_OR_AT_LEAST,
    PLANT_DEFAULTS,
    plant_problems,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plant_reference import ReferencePlant  # noqa: E402

T = 0.01
#: Largest position difference to the solve_ivp reference over a force sequence, m.
X_TOL = 1e-9
#: Largest velocity difference to the solve_ivp reference, m/s.
V_TOL = 1e-8
#: Largest difference of the lagging applied force (its tolerance is 1e-7*f_s), N.
F_TOL = 2e-5

#: The deviations at the values of scenarios/realism.toml, and all together.
CASES = REALISM_VARIANTS


# --- the defaults are Eq. (1) -------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(4))
def test_defaults_step_exactly_as_eq1(seed: int) -> None:
    rng = random.Random(seed)
    params = {"m": rng.uniform(50, 300), "f_c": rng.uniform(0, 150), "c": rng.uniform(0, 900),
              "x0": rng.uniform(-1, 1), "v0": rng.choice((0.0, rng.uniform(-0.1, 0.1)))}
    params["f_s"] = params["f_c"] * rng.uniform(1.0, 1.6)
    plant = Plant(params)
    assert plant.is_eq1
    x, v = params["x0"], params["v0"]
    for u in random_forces(seed, 200):
        h = rng.choice((T, rng.uniform(1e-4, 0.05)))
        assert plant.step(u, h) is None
        x, v = stickslip.step(x, v, u, h, params["m"], params["f_c"], params["f_s"], params["c"])
        assert (plant.x, plant.v) == (x, v)


def test_physics_slave_with_defaults_is_stickslip_simulate() -> None:
    forces = random_forces(11, 150)
    slave = PhysicsSlave()
    index = slave.watch(["x", "v"])
    slave.initialize()
    for k, u in enumerate(forces):
        slave.u = u
        slave.do_step(k * T, T)
        x, v = stickslip.simulate(forces[: k + 1], T, 150.0, 100.0, 130.0, 700.0)[-1]
        assert [slave.values[i] for i in index] == [x, v]


def test_deviation_parameters_default_to_absent() -> None:
    plant = Plant({name: PLANT_DEFAULTS[name] for name in (v.name for v in DEVIATION_PARAMETERS)})
    assert plant.is_eq1


# --- against solve_ivp --------------------------------------------------------------------------


@pytest.mark.parametrize("seed", (1, 2))
@pytest.mark.parametrize("case", sorted(CASES))
def test_deviation_matches_solve_ivp_with_events(case: str, seed: int) -> None:
    params = CASES[case]
    plant = Plant(params)
    reference = ReferencePlant(params)
    n = 25 if case.startswith("lugre") else 40
    for u in random_forces(100 * seed + len(case), n):
        assert plant.step(u, T) is None
        reference.step(u, T)
        assert abs(plant.x - reference.x) <= X_TOL, (plant.x, reference.x)
        assert abs(plant.v - reference.v) <= V_TOL, (plant.v, reference.v)
        if params.get("sigma_0", 0.0) == 0.0:
            assert (plant.v == 0.0) == (reference.v == 0.0)
        if "m_d" in params:
            assert abs(plant.x_d - reference.x_d) <= X_TOL
        if "tau_u" in params:
            assert abs(plant.f_a - reference.f_a) <= F_TOL
    if "f_s_spread" in params:
        assert plant.stick_draws == reference.draws


def test_variable_step_sizes_match_solve_ivp() -> None:
    params = CASES["all"]
    plant, reference = Plant(params), ReferencePlant(params)
    rng = random.Random(4)
    for u in random_forces(4, 30):
        h = rng.uniform(1e-3, 0.03)
        assert plant.step(u, h) is None
        reference.step(u, h)
        assert abs(plant.x - reference.x) <= X_TOL
        assert abs(plant.v - reference.v) <= V_TOL


# --- closed forms -------------------------------------------------------------------------------


@pytest.mark.parametrize("v_star", (0.004, 0.02, 0.05, 0.1, -0.03))
def test_lugre_at_constant_velocity_gives_the_stribeck_curve(v_star: float) -> None:
    """Under the force of the Stribeck curve at v*, LuGre slides on at v* (z at g/sigma_0).

    The viscous c = 2000 N.s/m outweighs the curve's falling slope (at most 515 N.s/m
    here), so the velocity settles within a few tenths of a second.
    """
    f_c, f_s, c, v_s, delta_s = 100.0, 130.0, 2000.0, 0.05, 2.0
    g = f_c + (f_s - f_c) * math.exp(-(abs(v_star) / v_s) ** delta_s)
    u = math.copysign(g, v_star) + c * v_star
    plant = Plant({"sigma_0": 6.5e7, "sigma_1": 2e5, "v_s": v_s, "delta_s": delta_s, "c": c,
                   "v0": v_star})
    for _ in range(500):
        assert plant.step(u, T) is None
    assert plant.v == pytest.approx(v_star, rel=1e-8, abs=1e-12)
    assert plant.z == pytest.approx(math.copysign(g, v_star) / 6.5e7, rel=1e-8)


def test_flexible_mode_rings_with_the_designed_frequency_and_damping() -> None:
    """Table held by stiction, a force step on the motor: a damped oscillator of the design."""
    m_d, f_n, zeta, u = 50.0, 20.0, 0.02, 50.0
    w_n = 2 * math.pi * f_n
    k_t = m_d * w_n**2
    c_t = 2 * zeta * math.sqrt(k_t * m_d)
    plant = Plant({"m_d": m_d, "k_t": k_t, "c_t": c_t})
    h = 1e-3
    t = np.arange(1, 601) * h
    x_d = []
    for _ in t:
        assert plant.step(u, h) is None
        x_d.append(plant.x_d)
    assert plant.x == 0.0 and plant.v == 0.0
    w_d = w_n * math.sqrt(1 - zeta**2)
    exact = u / k_t * (1 - np.exp(-zeta * w_n * t) * (np.cos(w_d * t) + zeta * w_n / w_d
                                                       * np.sin(w_d * t)))
    assert np.max(np.abs(np.array(x_d) - exact)) <= 1e-10
    # The same from the samples alone: zero crossings give the frequency, peaks the decay.
    d = np.array(x_d) - u / k_t
    cross = [t[i] - d[i] * h / (d[i + 1] - d[i]) for i in range(len(d) - 1)
             if d[i] < 0 <= d[i + 1]]
    f_measured = (len(cross) - 1) / (cross[-1] - cross[0])
    assert f_measured == pytest.approx(w_d / (2 * math.pi), rel=1e-4)
    peaks = [i for i in range(1, len(d) - 1) if d[i] > d[i - 1] and d[i] >= d[i + 1]]
    decrement = math.log(d[peaks[0]] / d[peaks[-1]]) / (len(peaks) - 1)
    zeta_measured = decrement / math.sqrt(4 * math.pi**2 + decrement**2)
    assert zeta_measured == pytest.approx(zeta, rel=2e-3)


def test_flexible_mode_with_the_table_free_has_the_two_mass_frequency() -> None:
    m, m_d, k_t = 100.0, 50.0, 7.896e5
    plant = Plant({"m": m, "f_c": 0.0, "f_s": 0.0, "c": 0.0, "m_d": m_d, "k_t": k_t})
    h = 1e-3
    assert plant.step(100.0, 0.01) is None
    w = math.sqrt(k_t * (1 / m + 1 / m_d))
    deflection, amplitude = [], []
    for _ in range(500):
        assert plant.step(0.0, h) is None
        d = plant.x_d - plant.x
        deflection.append(d)
        amplitude.append(math.hypot(d, (plant.v_d - plant.v) / w))
    d = np.array(deflection)
    cross = [i - d[i] / (d[i + 1] - d[i]) for i in range(len(d) - 1) if d[i] < 0 <= d[i + 1]]
    f_measured = (len(cross) - 1) / ((cross[-1] - cross[0]) * h)
    assert f_measured == pytest.approx(w / (2 * math.pi), rel=1e-4)
    # No damping and no friction: the amplitude stays.
    assert max(amplitude) - min(amplitude) <= 1e-8 * max(amplitude)


@pytest.mark.parametrize("tau_u", (2e-3, 0.02))
def test_lag_step_response_is_first_order(tau_u: float) -> None:
    # Table held: the applied force alone.
    held = Plant({"tau_u": tau_u, "f_s": 1e4})
    # Table free of friction: m*x'' = f_a, integrated.
    free = Plant({"tau_u": tau_u, "f_c": 0.0, "f_s": 0.0, "c": 0.0})
    u, m, h = 100.0, 150.0, 1e-3
    for k in range(1, 101):
        t = k * h
        assert held.step(u, h) is None
        assert free.step(u, h) is None
        f_a = u * -math.expm1(-t / tau_u)
        assert held.f_a == pytest.approx(f_a, rel=1e-12, abs=1e-12)
        assert free.f_a == pytest.approx(f_a, rel=1e-6, abs=1e-9)
        v = u / m * (t + tau_u * math.expm1(-t / tau_u))
        x = u / m * (t * t / 2 - tau_u * t - tau_u**2 * math.expm1(-t / tau_u))
        assert free.v == pytest.approx(v, rel=1e-8, abs=1e-12)
        assert free.x == pytest.approx(x, rel=1e-8, abs=1e-13)


# --- random stiction and noise ------------------------------------------------------------------


def _run(params: dict, forces: list[float]) -> list[tuple]:
    plant = Plant(params)
    out = []
    for u in forces:
        assert plant.step(u, T) is None
        out.append((plant.x, plant.v, plant.f_s_now, plant.x_meas()))
    return out


@pytest.mark.parametrize("extra", ({}, {"v_s": 1e-3}))
def test_random_stiction_is_reproducible_from_its_seed(extra: dict) -> None:
    forces = random_forces(5, 150)
    a = _run({"f_s_spread": 0.1, "seed": 7, **extra}, forces)
    b = _run({"f_s_spread": 0.1, "seed": 7, **extra}, forces)
    c = _run({"f_s_spread": 0.1, "seed": 8, **extra}, forces)
    assert a == b
    assert [r[2] for r in a] != [r[2] for r in c]
    assert all(130.0 * 0.9 <= r[2] <= 130.0 * 1.1 for r in a + c)


def test_random_stiction_draws_once_each_time_the_mass_sticks() -> None:
    plant = Plant({"f_s_spread": 0.1, "seed": 2})
    sticks = 0
    for u in random_forces(9, 300):
        v = plant.v
        draws = plant.stick_draws
        assert plant.step(u, T) is None
        if v != 0.0 and plant.v == 0.0:
            sticks += 1
            assert plant.stick_draws == draws + 1
        elif v == 0.0:
            assert plant.stick_draws == draws
    assert sticks > 10
    assert plant.stick_draws == sticks + 1


def test_breakaway_forces_are_uniform_in_the_spread() -> None:
    stiction = RandomStiction(130.0, 0.1, 12)
    draws = np.array([stiction.draw(k) for k in range(4000)])
    assert draws.min() >= 117.0 and draws.max() <= 143.0
    assert stats.kstest((draws - 117.0) / 26.0, "uniform").pvalue > 1e-3


def test_noise_is_reproducible_gaussian_and_added_before_quantization() -> None:
    noise = EncoderNoise(2e-7, 5)
    draws = np.array([noise.draw(k) for k in range(4000)])
    assert draws.tolist() == [EncoderNoise(2e-7, 5).draw(k) for k in range(4000)]
    assert draws.tolist() != [EncoderNoise(2e-7, 6).draw(k) for k in range(4000)]
    assert stats.kstest(draws / 2e-7, "norm").pvalue > 1e-3
    plant = Plant({"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 5})
    assert plant.x_meas() == stickslip.quantize(0.0 + draws[0], 1e-7)
    for k, u in enumerate(random_forces(3, 50), start=1):
        assert plant.step(u, T) is None
        assert plant.noise == draws[k]
        assert plant.x_meas() == stickslip.quantize(plant.x + draws[k], 1e-7)


def test_noise_leaves_the_motion_unchanged() -> None:
    forces = random_forces(6, 120)
    a = _run({}, forces)
    b = _run({"noise_std": 5e-7, "seed": 1}, forces)
    assert [r[:2] for r in a] == [r[:2] for r in b]
    assert [r[3] for r in a] != [r[3] for r in b]


def test_draws_are_in_the_open_unit_interval_and_differ_by_stream() -> None:
    us = [uniform(s, stream, k) for s in (0, 1, 2**31 - 1) for stream in (1, 2)
          for k in range(500)]
    assert all(0.0 < u < 1.0 for u in us)
    assert uniform(3, 1, 10) != uniform(3, 2, 10)
    assert math.isfinite(normal(0, 2, 0))


# --- state --------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", sorted(CASES) + ["noise"])
def test_state_round_trip_continues_bit_for_bit(case: str) -> None:
    params = CASES.get(case, {"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 4})
    forces = random_forces(21, 40)
    a = Plant(params)
    for u in forces[:20]:
        assert a.step(u, T) is None
    state = json.loads(json.dumps(a.state()))
    b = Plant(params)
    b.set_state(state)
    for u in forces[20:]:
        assert a.step(u, T) is None
        assert b.step(u, T) is None
        assert a.state() == b.state()


@pytest.mark.parametrize(("change", "field"), [
    ({"x": math.nan}, "x"), ({"v": "0"}, "v"), ({"stick_draws": -1}, "stick_draws"),
    ({"noise_draws": 1.5}, "noise_draws"), ({"z": True}, "z"),
])
def test_bad_plant_state_is_refused_and_changes_nothing(change: dict, field: str) -> None:
    plant = Plant(CASES["all"])
    assert plant.step(200.0, T) is None
    before = plant.state()
    with pytest.raises(ValueError, match=field):
        plant.set_state({**before, **change})
    assert plant.state() == before
    with pytest.raises(ValueError, match="fields"):
        plant.set_state({k: v for k, v in before.items() if k != "h_next"})
    assert set(before) == set(STATE_FIELDS)


def test_a_refused_step_leaves_the_state_as_it_was() -> None:
    plant = Plant(CASES["all"])
    assert plant.step(250.0, T) is None
    before = plant.state()
    assert plant.step(1e300, T) is not None
    assert plant.state() == before


# --- bad input ----------------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "value", "allowed"), [
    ("v_s", -1e-3, "0 <= v_s <= 10 m/s"),
    ("delta_s", 0.5, "1 <= delta_s <= 10"),
    ("sigma_0", -1.0, "0 <= sigma_0 <= 1e+12 N/m"),
    ("sigma_1", math.inf, "finite"),
    ("ripple", 1.0, "0 <= ripple < 1"),
    ("ripple_period", 1e-5, "0.0001 <= ripple_period <= 1000 m"),
    ("ripple_phase", 7.0, "ripple_phase"),
    ("f_s_spread", -0.1, "0 <= f_s_spread < 1"),
    ("seed", -1, "a whole number 0 <= seed <= 2147483647"),
    ("seed", 2.5, "a whole number"),
    ("tau_u", -1e-3, "0 <= tau_u <= 10 s"),
    ("m_d", -1.0, "0 <= m_d <= 1e+06 kg"),
    ("k_t", math.nan, "finite"),
    ("c_t", -1.0, "0 <= c_t <= 1e+09 N.s/m"),
    ("noise_std", -1e-7, "0 <= noise_std <= 1 m"),
])
def test_out_of_range_parameter_is_refused_naming_it(name: str, value, allowed: str) -> None:
    found = plant_problems({**PLANT_DEFAULTS, name: value})
    assert found, name
    where, message = found[0]
    assert where == name
    assert message.startswith(f"{name} = {value!r}")
    assert allowed in message


@pytest.mark.parametrize(("values", "name", "text"), [
    ({"f_s_spread": 0.3}, "f_s_spread", "f_s*(1 - f_s_spread) = 91.0 N must be >= f_c"),
    ({"sigma_0": 1e7, "f_c": 0.0, "f_s": 0.0}, "sigma_0", "needs f_c > 0"),
    ({"sigma_0": 1e7, "f_s_spread": 0.1}, "f_s_spread", "never sticks"),
    ({"m_d": 10.0}, "k_t", "needs a coupling stiffness k_t > 0"),
    ({"sigma_0": 1e12}, "sigma_0", f"<= {MODE_FREQUENCY_MAX:g} Hz"),
    ({"m_d": 1.0, "k_t": 1e10}, "k_t", f"<= {MODE_FREQUENCY_MAX:g} Hz"),
])
def test_rules_between_parameters_are_enforced(values: dict, name: str, text: str) -> None:
    found = plant_problems({**PLANT_DEFAULTS, **values})
    assert [n for n, _ in found] == [name]
    assert text in found[0][1]


# --- never NaN ----------------------------------------------------------------------------------


def _log_uniform(lo: float, hi: float):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


DEVIATION_NAMES = {v.name for v in DEVIATION_PARAMETERS}


@st.composite
def plants(draw) -> dict:
    """Valid parameter sets over the allowed ranges, each deviation on or off."""
    p: dict = {"m": draw(_log_uniform(1e-2, 1e4)), "f_c": draw(_log_uniform(1e-2, 1e4)),
               "c": draw(st.one_of(st.just(0.0), _log_uniform(1e-2, 1e5)))}
    p["f_s"] = p["f_c"] * draw(st.floats(1.0, 3.0))
    if draw(st.booleans()):
        p["v_s"] = draw(_log_uniform(1e-6, 10.0))
        p["delta_s"] = draw(st.floats(1.0, 10.0))
    if draw(st.booleans()):
        p["ripple"] = draw(st.floats(0.0, 0.99))
        p["ripple_period"] = draw(_log_uniform(1e-4, 1e3))
        p["ripple_phase"] = draw(st.floats(-2 * math.pi, 2 * math.pi))
    if draw(st.booleans()):
        p["tau_u"] = draw(_log_uniform(1e-6, 10.0))
    if draw(st.booleans()):
        p["m_d"] = draw(_log_uniform(1e-2, 1e4))
        k_max = min(1e12, highest_mode_stiffness(p["m"], p["m_d"]))
        p["k_t"] = draw(_log_uniform(min(1.0, k_max), k_max))
        p["c_t"] = draw(st.one_of(st.just(0.0), _log_uniform(1e-2, 1e6)))
    if draw(st.booleans()):
        s0_max = min(1e12, highest_mode_stiffness(p["m"]))
        p["sigma_0"] = draw(_log_uniform(min(1.0, s0_max), s0_max))
        p["sigma_1"] = draw(st.one_of(st.just(0.0), _log_uniform(1e-2, 1e7)))
    elif draw(st.booleans()):
        p["f_s_spread"] = draw(st.floats(0.0, 0.9)) * (1 - p["f_c"] / p["f_s"])
        p["seed"] = draw(st.integers(0, 2**31 - 1))
    if draw(st.booleans()):
        p["noise_std"] = draw(_log_uniform(1e-9, 1e-3))
    for name, low in OFF_OR_AT_LEAST.items():  # a smaller one than these is refused: none
        if name in p and 0.0 < p[name] < low and name in DEVIATION_NAMES:
            p[name] = 0.0
    if any(p.get(name, 0.0) > 0.0 for name in INTEGRATED):  # the integrated plant's bounds
        if draw(st.booleans()):  # the damping rate at its bound (raising m would too)
            p["m"] = max(p["m"], lowest_integrated_mass(p["f_s"], 0.0))
            p["c"] = highest_damping(p["m"])
        else:
            p["m"] = max(p["m"], lowest_integrated_mass(p["f_s"], p["c"]))
    if p.get("m_d", 0.0) > 0.0:
        p["c_t"] = min(p["c_t"], highest_coupling_damping(p["m"], p["m_d"]))
    return p


@settings(max_examples=500, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(params=plants())
def test_the_plants_strategy_draws_inside_the_bounds(params: dict) -> None:
    """Issue 44: the strategy of the test below drew c/m = 10000.000000000002 (its derived
    bound without a margin), which the plant refuses; every draw is a valid plant."""
    assert plant_problems({**PLANT_DEFAULTS, **params}) == []


def _bound_cases() -> list[dict]:
    """20,000 plants at one of the derived bounds of :func:`plants` each (seeded)."""
    rng = random.Random(44)
    cases = []
    for k in range(20_000):
        m, m_d = 10.0 ** rng.uniform(-2.0, 4.0), 10.0 ** rng.uniform(-2.0, 4.0)
        f_c = 10.0 ** rng.uniform(-2.0, 4.0)
        f_s, c = f_c * rng.uniform(1.0, 3.0), 10.0 ** rng.uniform(-2.0, 5.0)
        p = {"m": m, "f_c": f_c, "f_s": f_s, "c": 0.0, "tau_u": 1e-3}
        rule = k % 5
        if rule == 0:
            p.update(c=c, m=lowest_integrated_mass(f_s, c))
        elif rule == 1:
            p.update(m=max(m, lowest_integrated_mass(f_s, 0.0)))
            p["c"] = highest_damping(p["m"])
        elif rule == 2:
            p.update(m_d=m_d, k_t=highest_mode_stiffness(m, m_d))
        elif rule == 3:
            p.update(sigma_0=highest_mode_stiffness(m))
        else:
            p.update(m_d=m_d, k_t=1.0, c_t=highest_coupling_damping(m, m_d))
        if rule != 1:
            p["m"] = max(p["m"], lowest_integrated_mass(f_s, p["c"]))
        cases.append(p)
    return cases


def test_the_strategies_derived_bounds_keep_their_margin() -> None:
    """Issue 44: every bound the strategies derive (tests/harness.py) gives valid plants at
    the bound itself, where the bare quotient lands outside for some (so this can fail)."""
    cases = _bound_cases()
    assert [p for p in cases if plant_problems({**PLANT_DEFAULTS, **p})] == []
    bare = sum(x / (x / DAMPING_RATE_MAX) > DAMPING_RATE_MAX
               for x in (p["c"] for p in cases) if x > 0.0)
    assert bare > 20
    assert inside_max(1.0) == 1.0 - BOUND_MARGIN and inside_min(1.0) == 1.0 + BOUND_MARGIN


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(params=plants(), forces=st.lists(st.floats(-1e4, 1e4), min_size=1, max_size=4),
       h=st.sampled_from((1e-3, 0.01)))
def test_the_plant_never_returns_nan(params: dict, forces: list[float], h: float) -> None:
    assert plant_problems({**PLANT_DEFAULTS, **params}) == []
    plant = Plant(params)
    for u in forces:
        before = plant.state()
        reason = plant.step(u * params["f_s"] / 1e3, h)
        if reason is not None:
            assert isinstance(reason, str) and reason
            assert plant.state() == before
        state = plant.state()
        assert all(math.isfinite(state[name]) for name in STATE_FIELDS)
        assert math.isfinite(plant.x_meas())
        if params.get("sigma_0", 0.0) == 0.0 and plant.v == 0.0:
            assert plant.state()["v"] == 0.0


# --- the integrator's Jacobian ------------------------------------------------------------------


@pytest.mark.parametrize("case", ("stribeck", "lugre", "ripple", "lag", "flexible", "all"))
def test_jacobian_matches_finite_differences(case: str) -> None:
    plant = Plant(CASES[case])
    rng = random.Random(3)
    for _ in range(20):
        y = [rng.uniform(-1e-3, 1e-3), rng.uniform(-0.05, 0.05)]
        for name in plant._names[2:]:
            y.append({"z": rng.uniform(-2e-6, 2e-6), "x_d": rng.uniform(-1e-3, 1e-3),
                      "v_d": rng.uniform(-0.05, 0.05), "f_a": rng.uniform(-300, 300)}[name])
        u = rng.uniform(-300, 300)
        s = 1.0 if y[1] > 0 else -1.0
        jac = plant._jacobian(y, u, s)
        for j in range(len(y)):
            step = 1e-7 * max(abs(y[j]), 1e-6)
            up, down = list(y), list(y)
            up[j] += step
            down[j] -= step
            fd = [(a - b) / (2 * step) for a, b in zip(plant._rates(up, u, s),
                                                        plant._rates(down, u, s), strict=True)]
            for i in range(len(y)):
                assert jac[i][j] == pytest.approx(fd[i], rel=1e-5, abs=1e-6 * (
                    1 + max(abs(r[j]) for r in jac)))
