"""The C controller (fmu_src/PulseController/controller.c) against the Python controllers.

The C controller is compiled for this machine (tests/native_lib.py: the system ``cc``,
``-O2 -ffp-contract=off``) and stepped beside the Python controller of the same settings
(:func:`papwc.controllers.make_controller`) for the kinds it implements, pwc, papwc and pid:

- over random settings drawn inside their ranges and random measurement sequences
  (hypothesis, derandomized): a closed loop around the C plant (Table 1 with encoder noise
  or a flexible drive, drawn), with readings held, jumps, invalid readings (NaN, inf, beyond
  1e6 m), changed references and new maneuvers mixed in; after every sample the force and
  every output are compared, and the whole state (sequencer, rest detection, trust region,
  law) every few samples; a state copied in the middle continues in a new C controller
  exactly as the Python controller's restored ``set_state`` does;
- on every run of scenarios/realism.toml (its eight cases, three targets, seed 1) for the
  controllers of the kinds it implements, three iterations each with the estimates carried
  over, around the C plant.

Tolerance: none. Both compute with IEEE doubles in the same operation order and call the
same C library's sqrt, ceil, floor, copysign and pow, so every force, output and state field
is equal bit for bit (``float.hex``).

The settings' checks: ``pc_check`` refuses what the model layer refuses, with its words.
"""

from __future__ import annotations

import ctypes
import functools
import math
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from papwc.controllers import make_controller
from papwc.controllers.settings import ControllerSettings
from papwc.fmubuild.native_tables import NATIVE_KINDS, controller_header
from papwc.master.native_controller import NativeControllerLibrary, PcOutputs
from papwc.model.controller_settings import (
    CONTROLLER_CONSTRAINTS,
    CONTROLLER_SETTINGS,
    SAMPLE_PERIOD,
    settings_problems,
)
from papwc.model.variables import problems

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from native_lib import (  # noqa: E402
    NativeLibrary,
    NativePlant,
    build_controller_library,
    build_plant_library,
    compiler,
    controller_state,
    controller_struct,
)

pytestmark = pytest.mark.skipif(
    compiler() is None,
    reason="no C compiler (cc, gcc, clang or the ziglang package) to build "
           "fmu_src/PulseController/controller.c")

#: Hypothesis settings of every property here: reproducible, bounded.
SETTINGS = settings(derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow])


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> NativeControllerLibrary:
    lib = NativeControllerLibrary(build_controller_library(
        tmp_path_factory.mktemp("native_controller")))
    assert lib.controller_size == ctypes.sizeof(controller_struct())
    return lib


@pytest.fixture(scope="module")
def plant_lib(tmp_path_factory: pytest.TempPathFactory) -> NativeLibrary:
    return NativeLibrary(build_plant_library(tmp_path_factory.mktemp("native_plant")))


# --- one controller in both languages ------------------------------------------------------------

@functools.cache
def c_struct() -> type[ctypes.Structure]:
    """``PcController`` as ctypes lays it out (checked against the library's size)."""
    return controller_struct()


def bits(value: Any) -> str:
    """A value as its exact bits (floats by float.hex, so 0.0 and -0.0 differ)."""
    if isinstance(value, list):
        return "[" + ", ".join(bits(v) for v in value) + "]"
    return float(value).hex() if isinstance(value, float) else repr(int(value))


class Pair:
    """The Python controller and the C controller of the same settings, stepped alike."""

    def __init__(self, library: NativeControllerLibrary, s: ControllerSettings, T: float,
                 buffer: ctypes.Array | None = None, python=None) -> None:
        self.library = library
        self.T = T
        self.py = python if python is not None else make_controller(s, T)
        self.buffer = buffer if buffer is not None else library.new(s, T)
        self.c = c_struct().from_buffer(self.buffer)
        self.y = PcOutputs()
        self.k = 0
        #: What the samples went through: modes, outcomes, reasons and parts of the state.
        self.seen: set[tuple[str, Any]] = set()

    def update(self, x_meas: float, x_ref: float) -> float:
        """One sample of both; the forces and every output equal, bit for bit."""
        t = self.k * self.T
        c = self.c
        held, h_n, outcome = c.law.holding, c.law.h_n, c.seq.outcome
        u_py = self.py.update(t, x_meas, x_ref)
        u_c = self.library.api.sample(ctypes.addressof(self.buffer), t, x_meas, x_ref,
                                      ctypes.byref(self.y))
        self.k += 1
        assert bits(u_c) == bits(u_py), (self.k, x_meas, x_ref)
        assert self.outputs() == {n: bits(v) for n, v in self.py.outputs().items()}, self.k
        self.seen.update({("mode", c.seq.mode), ("outcome", c.seq.outcome),
                          ("reason", c.seq.outcome_reason), ("noise", c.rest.sigma2 > 0.0),
                          ("idle", c.seq.idle_samples > 0), ("ringing", c.trust.ring),
                          ("creep", c.law.creeps[2] > 0.0), ("released", c.seq.released),
                          # the PID's in-position window: coasting into it, the force held,
                          # the hold left (the PID acts again), the table crept under it
                          # (the average starts anew), a settled outcome taken back
                          ("coasting", c.law.coasting), ("holding", c.law.holding),
                          ("left", bool(held and not c.law.holding and not c.seq.stopped)),
                          ("crept", bool(held and h_n >= 31 and c.law.h_n == 16)),
                          ("unsettled", outcome == 1 and c.seq.outcome == 0)})
        return u_py

    def outputs(self) -> dict[str, str]:
        return {name: bits(getattr(self.y, name)) for name, _ in PcOutputs._fields_}

    def reset(self) -> None:
        self.py.reset()
        self.library.api.reset(ctypes.addressof(self.buffer), ctypes.byref(self.y))

    def same_state(self) -> None:
        """The whole state equal: every field of the Python controller's state()."""
        expected = {k: bits(v) for k, v in self.py.state().items()}
        got = {k: bits(v) for k, v in controller_state(self.c, list(expected)).items()}
        assert got == expected
        assert self.library.state_problem(self.buffer) is None

    def copy(self) -> ctypes.Array:
        """The C controller's bytes (what an FMU state holds)."""
        out = (ctypes.c_uint64 * len(self.buffer))()
        ctypes.memmove(out, self.buffer, ctypes.sizeof(self.buffer))
        return out


# --- random settings, drawn inside their ranges --------------------------------------------------

def some(draw: st.DrawFn, strategy: st.SearchStrategy) -> Any:
    """None (the computed default) or a value of ``strategy``."""
    return draw(st.one_of(st.none(), strategy))


@st.composite
def controller_settings(draw: st.DrawFn, kind: str, T: float) -> ControllerSettings:
    """Settings of ``kind`` at sample period T, each inside its range and the rules."""
    f_p_max = draw(st.floats(60.0, 1000.0))
    tolerance = draw(st.one_of(st.sampled_from((0.0, 1e-6, 2e-5, 1e-4)), st.floats(0.0, 1e-3)))
    f_mode = draw(st.one_of(st.just(0.0), st.floats(max(5.0, 2.5e-6 / T), 0.25 / T)))
    t_p_max = draw(st.one_of(st.just(math.inf), st.floats(1.0, 10.0).map(lambda x: T * x)))
    values = {
        "kind": kind,
        "f_p_max": f_p_max,
        "t_p_max": t_p_max,
        "K_c": draw(st.floats(0.05, 1.95)),
        "tolerance": tolerance,
        "m_est": draw(st.floats(20.0, 400.0)),
        "f_c_est": f_p_max * draw(st.floats(0.1, 0.9)),
        "f_p_min": some(draw, st.floats(0.0, 1.0).map(lambda x: f_p_max * x)),
        "floor_raise": draw(st.floats(0.01, 1.0)),
        "F_inv0": draw(st.floats(-8.0, -2.0).map(lambda e: 10.0 ** e)),
        "lambda_1": draw(st.floats(0.5, 1.0)),
        "lambda_2": draw(st.floats(0.0, 1.99)),
        "delta_inv": draw(st.floats(-8.0, -1.0).map(lambda e: 10.0 ** e)),
        "lambda": draw(st.floats(0.5, 1.0)),
        "regressor": draw(st.integers(0, 1)),
        "update_covariance": draw(st.booleans()),
        "floor_mode": draw(st.integers(0, 2)),
        "e_band": tolerance + draw(st.floats(1e-5, 0.05)),
        "k_p": some(draw, st.floats(1e3, 1e5)),
        "k_d": some(draw, st.floats(0.0, 1e4)),
        "rest_samples": draw(st.integers(1, 6)),
        "rest_band": draw(st.sampled_from((0.0, 1e-7, 1e-6))),
        "max_pulses": draw(st.one_of(st.integers(1, 4), st.integers(1, 40))),
        "safeguards": draw(st.sampled_from((True, True, False))),
        "rest_auto": draw(st.sampled_from((True, True, False))),
        "f_mode": f_mode,
        "k_i": some(draw, st.floats(0.0, 1e6)),
        "a_max": some(draw, st.floats(0.01, 10.0)),
        "v_max": draw(st.floats(0.005, 0.5)),
        "hunt_max": draw(st.integers(1, 8)),
        "m_d_est": draw(st.floats(1.0, 200.0)),
        "x_resolution": draw(st.sampled_from((0.0, 1e-7, 1e-6))),
        "in_position": some(draw, st.booleans()),
        "in_position_band": some(draw, st.one_of(st.sampled_from((0.0, 1e-7, 1e-6, 2e-5)),
                                                 st.floats(0.0, 1e-3))),
    }
    s = ControllerSettings.from_mapping(values)
    assert settings_problems({**s.to_mapping(with_none=True), "T": T}) == []
    return s


@st.composite
def plant_params(draw: st.DrawFn) -> dict[str, float]:
    """Table 1 with a drawn mass, friction and damping; an ideal, quantized or noisy encoder,
    or a flexible drive (20 Hz class)."""
    f_c = draw(st.floats(40.0, 150.0))
    p = {"m": draw(st.floats(60.0, 300.0)), "f_c": f_c, "f_s": f_c * draw(st.floats(1.0, 1.5)),
         "c": draw(st.floats(0.0, 900.0))}
    encoder = draw(st.sampled_from(("ideal", "quantized", "noisy", "noisy", "flexible")))
    if encoder == "quantized":
        p["x_resolution"] = draw(st.sampled_from((1e-7, 1e-6)))
    elif encoder == "noisy":
        p.update(noise_std=draw(st.floats(1e-8, 1e-6)), x_resolution=1e-7,
                 seed=draw(st.integers(0, 1000)))
    elif encoder == "flexible":
        p.update(m_d=draw(st.floats(20.0, 80.0)), k_t=draw(st.floats(2e5, 2e6)),
                 c_t=draw(st.floats(0.0, 300.0)))
    return p


#: What may happen at a sample besides the closed loop: the reading held, a jump, an invalid
#: reading, another reference, a new maneuver.
EVENTS = ("hold", "jump", "invalid", "target", "maneuver")


@st.composite
def scripts(draw: st.DrawFn) -> list[tuple[str, float]]:
    """Samples of the closed loop (``"loop"``), a drawn share of them another event."""
    n = draw(st.integers(20, 500))
    share = draw(st.sampled_from((0.0, 0.01, 0.05, 0.2)))
    return [(draw(st.sampled_from(EVENTS)) if draw(st.floats(0.0, 1.0)) < share else "loop",
             draw(st.floats(-1.0, 1.0))) for _ in range(n)]


def run_script(pair: Pair, plant: NativePlant, x_ref: float,
               script: list[tuple[str, float]], check_every: int = 7
               ) -> list[tuple[float, float, bool]]:
    """Close the loop over ``script``; the inputs given at each sample (x_meas, x_ref, and
    whether a new maneuver started before it)."""
    inputs = []
    last = 0.0
    u = 0.0
    for k, (event, value) in enumerate(script):
        new = False
        if event == "maneuver":
            pair.reset()
            new = True
        elif event == "target":
            x_ref = x_ref + value * 5e-3
        assert plant.step(u, pair.T) is None
        x_meas = plant.outputs().x_meas
        if event == "hold":
            x_meas = last
        elif event == "jump":
            x_meas = x_meas + value * 1e-3
        elif event == "invalid":
            x_meas = (math.nan, math.inf, -math.inf, 2e6)[int(abs(value) * 3.99)]
        inputs.append((x_meas, x_ref, new))
        u = pair.update(x_meas, x_ref)
        if math.isfinite(x_meas):
            last = x_meas
        if k % check_every == 0:
            pair.same_state()
    pair.same_state()
    return inputs


def replay(pair: Pair, inputs: list[tuple[float, float, bool]]) -> list[tuple[str, ...]]:
    """Give ``inputs`` to both controllers; the forces and outputs (all checked equal)."""
    out = []
    for x_meas, x_ref, new in inputs:
        if new:
            pair.reset()
        u = pair.update(x_meas, x_ref)
        out.append((bits(u), *pair.outputs().values()))
    return out


def run_with_a_copy(library: NativeControllerLibrary, s: ControllerSettings, T: float,
                    plant: NativePlant, x_ref: float, script: list[tuple[str, float]],
                    at: int) -> set[tuple[str, Any]]:
    """Close the loop over ``script`` with both controllers of ``s``; the state saved after
    ``at`` samples, restored into new controllers (the Python one by ``set_state``, the C one
    from its bytes), gives the same tail as the run and as new controllers given every input.
    What the run went through (:attr:`Pair.seen`, and whether the copy was made in the PID's
    hold)."""
    pair = Pair(library, s, T)
    pair.same_state()
    head = run_script(pair, plant, x_ref, script[:at])
    saved_py, saved_c = pair.py.state(), pair.copy()
    tail_inputs = run_script(pair, plant, head[-1][1] if head else x_ref, script[at:])
    tail = replay(Pair(library, s, T), head + tail_inputs)[at:]
    python = make_controller(s, T)
    python.set_state(saved_py)
    restored = Pair(library, s, T, buffer=saved_c, python=python)
    assert library.state_problem(saved_c) is None
    restored.same_state()
    assert replay(restored, tail_inputs) == tail
    return pair.seen | {("saved holding", restored.c.law.holding)}


#: What the drawn runs of each kind go through at least (the comparison reaches every mode;
#: the generation of examples is not the same on every machine, so only what dozens of them
#: reach). What the realism runs and the named situations below reach, deterministically:
#: settling, the pulse budget, no move that helps, noise measured, idle samples counted, the
#: force released, PAPWC's creeps, ringing seen, the PID hunting.
COVERAGE = {
    "pwc": {("mode", 0), ("mode", 1), ("mode", 2), ("mode", 3), ("outcome", 2), ("reason", 6)},
    "pid": {("mode", 0), ("mode", 3), ("outcome", 2), ("reason", 6)},
}
COVERAGE["papwc"] = COVERAGE["pwc"]


@pytest.mark.parametrize("kind", NATIVE_KINDS)
def test_random_settings_and_readings_are_the_python_controllers_bit_for_bit(
        library: NativeControllerLibrary, plant_lib: NativeLibrary, kind: str) -> None:
    seen: set[tuple[str, Any]] = set()

    @settings(SETTINGS, max_examples=60)
    @given(data=st.data(), T=st.sampled_from((0.01, 0.001, 0.004)),
           params=plant_params(), script=scripts(),
           x_ref=st.one_of(st.sampled_from((1e-2, 1e-3, -5e-5)), st.floats(-0.05, 0.05)),
           cut=st.floats(0.0, 1.0))
    def check(data: st.DataObject, T: float, params: dict[str, float],
              script: list[tuple[str, float]], x_ref: float, cut: float) -> None:
        s = data.draw(controller_settings(kind, T))
        seen.update(run_with_a_copy(library, s, T, NativePlant(plant_lib, params), x_ref,
                                    script, int(cut * len(script))))

    check()
    assert COVERAGE[kind] <= seen, sorted(COVERAGE[kind] - seen)


@st.composite
def sparse_scripts(draw: st.DrawFn) -> list[tuple[str, float]]:
    """Longer runs of the closed loop (800 to 2500 samples) with at most three other events."""
    script: list[tuple[str, float]] = [("loop", 0.0)] * draw(st.integers(800, 2500))
    for at, event, value in draw(st.lists(st.tuples(
            st.integers(0, len(script) - 1), st.sampled_from(EVENTS), st.floats(-1.0, 1.0)),
            max_size=3)):
        script[at] = (event, value)
    return script


#: What the drawn runs of the PID at T <= 1 ms go through at least: its in-position window
#: (on by default there) coasted into and held (also when the state is copied), a settled
#: outcome (the hold left, the table crept, hunting: the named situations below).
WINDOW_COVERAGE = {("coasting", 1), ("holding", 1), ("outcome", 1), ("saved holding", 1)}


def test_random_pids_at_1khz_are_the_python_pids_bit_for_bit(
        library: NativeControllerLibrary, plant_lib: NativeLibrary) -> None:
    """The PID at T = 1 ms and 0.5 ms (its in-position window drawn on, off or at its
    default, on), random settings and plants, runs long enough to reach the window; the
    state copied in the middle continues alike (as the test above)."""
    seen: set[tuple[str, Any]] = set()

    @settings(SETTINGS, max_examples=30)
    @given(data=st.data(), T=st.sampled_from((0.001, 0.0005)), params=plant_params(),
           script=sparse_scripts(), x_ref=st.sampled_from((1e-3, 2e-4, -5e-5)),
           cut=st.floats(0.0, 1.0))
    def check(data: st.DataObject, T: float, params: dict[str, float],
              script: list[tuple[str, float]], x_ref: float, cut: float) -> None:
        s = data.draw(controller_settings("pid", T))
        seen.update(run_with_a_copy(library, s, T, NativePlant(plant_lib, params), x_ref,
                                    script, int(cut * len(script))))

    check()
    assert WINDOW_COVERAGE <= seen, sorted(WINDOW_COVERAGE - seen)


# --- scenarios/realism.toml through the closed loop ----------------------------------------------

def realism_runs() -> list[tuple[str, dict, ControllerSettings, Any]]:
    from papwc.battery.plan import plan_runs
    from papwc.battery.schema import load_battery
    from papwc.resources import scenario_file
    from papwc.scenario import parse_scenario

    out = []
    for run in plan_runs([load_battery(scenario_file("realism.toml"))]):
        scenario = parse_scenario(run.data, run.run_id)
        if scenario.plant.get("seed", 1) != 1:
            continue
        for s in scenario.controllers:
            if s.kind in NATIVE_KINDS:
                out.append((f"{run.run_id}/{s.kind}", scenario.plant, s, scenario.maneuver))
    return out


def test_every_realism_case_is_the_python_controllers_bit_for_bit(
        library: NativeControllerLibrary, plant_lib: NativeLibrary) -> None:
    runs = realism_runs()
    assert len(runs) == 8 * 3 * 3  # cases x targets x (pwc, papwc, pid)
    pulses = 0
    seen: dict[str, set] = {}
    for name, params, s, maneuver in runs:
        pair = Pair(library, s, maneuver.T)
        for _ in range(maneuver.iterations):
            plant = NativePlant(plant_lib, params)
            pair.reset()
            u = 0.0
            for _k in range(maneuver.n_steps):
                u = pair.update(plant.outputs().x_meas, maneuver.x_ref)
                assert plant.step(u, maneuver.T) is None, name
            pair.same_state()
        pulses += pair.c.seq.pulses
        seen.setdefault(s.kind, set()).update(pair.seen)
    assert pulses > 100
    assert {("reason", 2), ("reason", 3), ("noise", True), ("released", 1)} <= seen["pwc"]
    assert {("creep", True), ("reason", 1), ("reason", 2), ("idle", True), ("noise", True),
            ("released", 1)} <= seen["papwc"]


#: realism.toml's flexible drive (20 Hz while the table sticks), its mode not told (f_mode 0):
#: the rest detection sees it ring.
FLEXIBLE_UNTOLD = {"m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3}


@pytest.mark.parametrize(("values", "params", "x_ref", "T", "reached"), [
    ({"kind": "papwc", "max_pulses": 1, "tolerance": 0.0, "t_p_max": 0.03}, {}, 0.01, 0.01,
     {("reason", 3)}),
    ({"kind": "pid", "tolerance": 1e-7, "hunt_max": 1}, {"x_resolution": 1e-6}, 1e-3, 0.01,
     {("reason", 8)}),
    ({"kind": "pid", "tolerance": 2e-5}, {"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 3},
     1e-3, 0.001, {("reason", 1), ("noise", True)}),
    ({"kind": "papwc", "t_p_max": 0.03, "K_c": 0.8}, FLEXIBLE_UNTOLD, 1e-2, 0.01,
     {("ringing", 1)}),
    ({"kind": "pwc", "t_p_max": 0.03, "K_c": 0.8}, FLEXIBLE_UNTOLD, 1e-3, 0.01,
     {("ringing", 1)}),
    # no t_p_max and an estimate by which the mass barely moves: Eq. (6) plans about 1e5
    # samples, which base.cut_width halves down before it cuts one sample at a time
    ({"kind": "pwc", "m_est": 1e9, "e_band": 0.5}, {}, 0.4, 0.01, set()),
    ({"kind": "papwc", "m_est": 1e9, "e_band": 0.5}, {}, 0.4, 0.01, set()),
], ids=["papwc_budget", "pid_hunting", "pid_noise", "papwc_ringing", "pwc_ringing",
        "pwc_wide_plan", "papwc_wide_plan"])
def test_named_situations_are_the_python_controllers_bit_for_bit(
        library: NativeControllerLibrary, plant_lib: NativeLibrary, values: dict[str, Any],
        params: dict[str, float], x_ref: float, T: float, reached: set) -> None:
    """The PAPWC's pulse budget, the PID hunting, the PID on a noisy encoder at 1 kHz, PAPWC
    and PWC on a drive that rings, its mode untold, and their plans of 1e5 samples cut."""
    s = with_values(values)
    pair = Pair(library, s, T)
    plant = NativePlant(plant_lib, {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0,
                                    **params})
    run_script(pair, plant, x_ref, [("loop", 0.0)] * 800, check_every=1)
    assert reached <= pair.seen


#: The plant of the named situations: Table 1.
TABLE_1 = {"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0}
#: A noisy encoder of 0.1 um counts (noise 0.2 um or 1 um rms).
NOISY = {"noise_std": 2e-7, "x_resolution": 1e-7, "seed": 3}
VERY_NOISY = {"noise_std": 1e-6, "x_resolution": 1e-7, "seed": 3}


@pytest.mark.parametrize(("values", "params", "x_ref", "T", "reached"), [
    ({"tolerance": 1e-6}, NOISY, 1e-3, 0.001,
     {("coasting", 1), ("holding", 1), ("crept", True), ("reason", 1), ("noise", True)}),
    ({"tolerance": 1e-7, "hunt_max": 1}, VERY_NOISY, 5e-5, 0.001,
     {("holding", 1), ("left", True), ("reason", 8)}),
    ({"tolerance": 2e-5, "in_position_band": 1e-7}, VERY_NOISY, 5e-5, 0.001,
     {("holding", 1), ("left", True), ("unsettled", True), ("reason", 1)}),
    ({"tolerance": 2e-5, "in_position": True}, NOISY, 1e-3, 0.01,
     {("coasting", 1), ("holding", 1), ("reason", 1)}),
    ({"tolerance": 1e-6, "in_position": False}, NOISY, 1e-3, 0.001,
     {("released", 1), ("reason", 1)}),
], ids=["1khz_settles", "1khz_hunts", "1khz_leaves_the_hold", "100hz_window_on",
        "1khz_window_off"])
def test_the_pids_window_is_the_python_pids_bit_for_bit(
        library: NativeControllerLibrary, plant_lib: NativeLibrary, values: dict[str, Any],
        params: dict[str, float], x_ref: float, T: float, reached: set) -> None:
    """The PID's in-position window (on by default at 1 kHz), 2000 samples: on a noisy
    encoder it coasts into the window, holds, sees the table creep and settles; with a
    tolerance of 0.1 um on a noisier one it leaves the hold and stops hunting; with a band
    of 0.1 um it leaves the hold, takes a settled outcome back and settles again; the window
    set on at 100 Hz and off at 1 kHz. The state saved in the middle of the first hold (or
    of the run) goes on in new controllers as the run did."""
    s = with_values({"kind": "pid", **values})
    pair = Pair(library, s, T)
    plant = NativePlant(plant_lib, {**TABLE_1, **params})
    u, inputs, saved = 0.0, [], None
    for k in range(2000):
        assert plant.step(u, T) is None
        x_meas = plant.outputs().x_meas
        inputs.append((x_meas, x_ref, False))
        u = pair.update(x_meas, x_ref)
        if saved is None and (pair.c.law.holding and pair.c.law.h_n > 0 or k == 1000):
            saved = (k + 1, pair.py.state(), pair.copy())
        pair.same_state()
    assert reached <= pair.seen, sorted(reached - pair.seen)
    at, saved_py, saved_c = saved
    tail = replay(Pair(library, s, T), inputs)[at:]
    python = make_controller(s, T)
    python.set_state(saved_py)
    restored = Pair(library, s, T, buffer=saved_c, python=python)
    assert library.state_problem(saved_c) is None
    restored.same_state()
    assert replay(restored, inputs[at:]) == tail


@pytest.mark.parametrize(("T", "values"), [
    (1e-3, {}), (1e-3 * (1.0 + 5e-10), {}), (1e-3 * (1.0 + 2e-9), {}), (0.01, {}),
    (1e-3, {"in_position": False}), (0.01, {"in_position": True}),
    (1e-3, {"tolerance": 1e-7, "x_resolution": 1e-6}), (1e-3, {"in_position_band": 0.0}),
])
def test_the_pids_window_is_set_as_the_python_pids(
        library: NativeControllerLibrary, T: float, values: dict[str, Any]) -> None:
    """On by default up to T = 1 ms (a relative 1e-9 beyond), its half-width the tolerance,
    at least one count, each as pid.in_position_window gives them."""
    from papwc.controllers.pid import in_position_window

    s = with_values({"kind": "pid", **values})
    c = c_struct().from_buffer(library.new(s, T))
    on, band = in_position_window(s, T)
    assert (bool(c.cfg.window), bits(c.cfg.w_band), bits(c.cfg.q)) == (
        on, bits(band), bits(s.x_resolution))
    assert on == (T < 1.0000000015e-3 if "in_position" not in values else values["in_position"])


# --- settings: the model layer's checks ----------------------------------------------------------

def c_problems(library: NativeControllerLibrary, values: dict[str, Any], T: float) -> list[str]:
    return library.problems(with_values(values), T)


def with_values(values: dict[str, Any]) -> ControllerSettings:
    """The default settings with ``values`` (scenario-file names)."""
    return ControllerSettings.from_mapping({**ControllerSettings().to_mapping(with_none=True),
                                            **values})


@pytest.mark.parametrize(("values", "T"), [
    ({"K_c": 2.5}, 0.01),
    ({"K_c": math.nan}, 0.01),
    ({"f_p_max": -1.0}, 0.01),
    ({"f_c_est": 300.0}, 0.01),
    ({"f_p_min": 400.0}, 0.01),
    ({"e_band": 1e-5, "tolerance": 2e-5}, 0.01),
    ({"t_p_max": 0.005}, 0.01),
    ({"t_p_max": -math.inf}, 0.01),
    ({"rest_samples": 0}, 0.01),
    ({"max_pulses": 0}, 0.01),
    ({"f_mode": 40.0}, 0.01),
    ({"f_mode": 1e-6}, 0.01),
    ({"lambda": 0.0}, 0.01),
    ({"k_p": -5.0}, 0.01),
    ({"a_max": 0.0, "kind": "pid"}, 0.01),
    ({"K_c": 3.0, "f_c_est": 400.0, "f_mode": 30.0}, 0.01),
    ({}, 0.0),
    ({}, math.inf),
])
def test_pc_check_refuses_what_the_model_layer_refuses_in_its_words(
        library: NativeControllerLibrary, values: dict[str, Any], T: float) -> None:
    """pc_check's messages are the model layer's (each setting's range and the rules, T's
    range as the FMU checks it), in its order; a message on a setting with a switch ends
    with what the switch selects, as PulseController.fmu's do."""
    python = [f"parameter {m}" for _, m in problems(
        CONTROLLER_SETTINGS + (SAMPLE_PERIOD,),
        {**with_values(values).to_mapping(with_none=True), "T": T}, CONTROLLER_CONSTRAINTS)]
    assert python, values
    got = c_problems(library, values, T)
    words = {}
    for var in CONTROLLER_SETTINGS:
        if var.switch:
            words[var.name] = (f"; {var.switch} = false selects "
                               + ("the default" if var.optional else "no bound"))
    expected = [m + words.get(m.split()[1], "") for m in python]
    assert got == expected


def test_pc_check_accepts_the_defaults_and_refuses_the_kinds_it_lacks(
        library: NativeControllerLibrary) -> None:
    for kind in NATIVE_KINDS:
        assert c_problems(library, {"kind": kind}, 0.01) == []
    for code, kind in ((3, "exact"), (5, "dual_loop"), (6, "hybrid")):
        assert c_problems(library, {"kind": kind}, 0.01) == [
            f"parameter kind = {code} ({kind}): the C controller implements pwc (1), papwc (2) "
            "and pid (4)"]


def test_a_state_out_of_its_ranges_is_refused(library: NativeControllerLibrary) -> None:
    pair = Pair(library, with_values({"kind": "papwc"}), 0.01)
    for k in range(30):
        pair.update(0.0 if k < 2 else 1e-4, 0.01)
    for field, value, words in (("mode", 7, "a mode, code or count of the sequencer"),
                                ("outcome_reason", 99, "a mode, code or count"),
                                ("pulse_left", -1, "a mode, code or count")):
        broken = pair.copy()
        setattr(c_struct().from_buffer(broken).seq, field, value)
        assert words in library.state_problem(broken)
    broken = pair.copy()
    c_struct().from_buffer(broken).rest.ring_n = -3
    assert "rest detection" in library.state_problem(broken)
    pid = Pair(library, with_values({"kind": "pid", "in_position": True}), 0.001)
    for k in range(30):
        pid.update(0.0 if k < 2 else 1e-4, 0.01)
    for field, value in (("holding", 2), ("coasting", -1), ("ring_n", -1), ("h_look", -2)):
        broken = pid.copy()
        setattr(c_struct().from_buffer(broken).law, field, value)
        assert library.state_problem(broken) == "a count of the PID is out of its range", field
    broken = pid.copy()
    law = c_struct().from_buffer(broken).law
    law.holding, law.h_look = 1, 0  # the decisions' count would never grow: refused
    assert library.state_problem(broken) == "a count of the PID is out of its range"
    broken = pair.copy()
    c_struct().from_buffer(broken).cfg.n_max = 5
    assert library.state_problem(broken) == "its derived values are not those of its settings"
    broken = pair.copy()
    c_struct().from_buffer(broken).magic = 0
    assert "not a controller state of this library" in library.state_problem(broken)


def test_the_header_is_generated_from_the_model_layer() -> None:
    text = controller_header()
    for var in CONTROLLER_SETTINGS[1:]:
        assert f"X({var.name}, " in text, var.name
    assert "#define PC_KIND_PAPWC 2" in text and "#define PC_REASON_HUNTING 8" in text
    assert "#define PC_KIND_DEFAULT PC_KIND_PAPWC" in text
