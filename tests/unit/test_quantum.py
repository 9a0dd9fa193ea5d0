"""The table's quantum (papwc.results.quantum): the bound no controller can set.

On Eq. (1) it is Eq. (20) with the stiction at the top of its band; a ripple raises the band
top, a lag the commanded height that breaks the table away, a flexible drive's spring lowers
or raises it; a Stribeck curve makes it vanish. Computed once per table.
"""

from __future__ import annotations

import math

import pytest
from harness import TABLE_1

import papwc.results.quantum as quantum_module
from papwc.analysis.paper import d_min
from papwc.model.dynamics import Plant
from papwc.model.pulse import pulse_displacement
from papwc.results.quantum import band_top, table_quantum

T = 0.01
M, F_C, F_S, C = (TABLE_1[k] for k in ("m", "f_c", "f_s", "c"))
#: realism.toml's 20 Hz drive (2 % damping while the table sticks).
DRIVE_20HZ = {**TABLE_1, "m": 100.0, "m_d": 50.0, "k_t": 7.896e5, "c_t": 251.3}


def _moves(params: dict, u: float, samples: int = 40) -> bool:
    """Whether one sample at ``u`` (N) from rest, then zero force, moves the table."""
    plant = Plant(params)
    for k in range(samples):
        assert plant.step(u if k == 0 else 0.0, T) is None
        if plant.x != 0.0:
            return True
    return False


@pytest.mark.parametrize("spread", [0.0, 0.1, 0.15])
def test_on_eq1_the_quantum_is_eq20_at_the_band_top(spread):
    """Coulomb and viscous friction, no lag: one sample at f_s*(1 + spread) moves Eq. (3) at
    t_p = T, i.e. Eq. (20) with the stiction at the top of its band (12.68 um at 130 N)."""
    q = table_quantum({**TABLE_1, "f_s_spread": spread, "seed": 7}, T)
    top = F_S * (1.0 + spread)
    assert q.band_top == top
    assert q.u_break == math.nextafter(top, math.inf)  # the table holds up to f_s itself
    assert q.move == pytest.approx(pulse_displacement(top, T, M, F_C, C), rel=1e-12, abs=0)
    assert q.move == pytest.approx(d_min(top, T, M, F_C, C), rel=1e-12, abs=0)


def test_the_ripple_raises_the_band_top_at_any_phase():
    """The breakaway force is r(x)*f_s: at the ripple's peak (1 + a)*f_s*(1 + spread)."""
    plain = table_quantum(TABLE_1, T)
    params = {**TABLE_1, "ripple": 0.1, "ripple_period": 1e-3, "f_s_spread": 0.1}
    rippled = table_quantum(params, T)
    assert rippled.band_top == pytest.approx(130.0 * 1.1 * 1.1, rel=1e-15)
    assert band_top(params) == rippled.band_top > plain.band_top
    # more force: a longer move, though the sliding friction is up to 10 % higher there
    assert rippled.move > plain.move
    assert table_quantum({**params, "ripple_phase": 1.0}, T) is rippled  # phase-free


@pytest.mark.parametrize("tau_u", [2e-3, 5e-3])
def test_a_lag_raises_the_height_that_breaks_the_table_away(tau_u):
    """With a lag the applied force at the sample's end is u*(1 - exp(-T/tau_u)) and falls
    after it: the height that breaks the table away is band_top/(1 - exp(-T/tau_u)), higher
    than the band top (130.88 N at 2 ms, 150.35 N at 5 ms); the table breaks away as the
    force starts falling, so it moves far less than Eq. (20)'s 12.7 um (37 nm, 0.23 um)."""
    params = {**TABLE_1, "tau_u": tau_u}
    q = table_quantum(params, T)
    closed = F_S / -math.expm1(-T / tau_u)
    assert q.band_top == F_S and q.u_break > F_S
    assert q.u_break == pytest.approx(closed, rel=1e-14)
    assert _moves(params, q.u_break) and not _moves(params, q.u_break * (1.0 - 1e-9))
    assert 0.0 < q.move < table_quantum(TABLE_1, T).move


def test_on_a_stribeck_curve_the_move_grows_from_zero():
    """The sliding friction at rest equals the breakaway force: one sample just above it
    moves a fraction of a nanometre, so the bound is 1.5*abs(e) + q alone."""
    q = table_quantum({**TABLE_1, "v_s": 1e-3}, T)
    assert q.band_top == F_S and 0.0 <= q.move < 1e-9


@pytest.mark.parametrize(("v_s", "level"), [(1e-3, F_S), (0.0, F_C)])
def test_lugre_breaks_away_at_its_friction_at_rest(v_s, level):
    """The bristles hold at most g(0): f_s on a Stribeck curve, f_c without; ripple on top."""
    params = {**TABLE_1, "sigma_0": 6.5e7, "sigma_1": 2e5, "v_s": v_s, "ripple": 0.05}
    q = table_quantum(params, T)
    assert q.band_top == pytest.approx(level * 1.05, rel=1e-15)
    assert q.move > 0.0  # the bristles' pre-sliding and what slides beyond


@pytest.mark.parametrize(("k_t", "c_t"), [(7.896e5, 251.3), (1.974e5, 125.7)])
def test_a_flexible_drive_breaks_the_table_away_through_its_spring(k_t, c_t):
    """The drive at rest, one sample: the spring's force keeps ringing after it, so the
    lowest height that breaks the held table away is found by bisection (20 Hz: 114 N, the
    spring overshoots; 10 Hz: 216 N, the sample is short against the period)."""
    params = {**DRIVE_20HZ, "k_t": k_t, "c_t": c_t}
    q = table_quantum(params, T)
    assert q.band_top == F_S
    assert _moves(params, q.u_break) and not _moves(params, q.u_break * (1.0 - 1e-9))
    assert (q.u_break < F_S) == (k_t > 5e5)
    assert 0.0 < q.move < 1e-4


def test_the_quantum_is_computed_once_per_table(monkeypatch):
    calls = []
    real = quantum_module._compute

    def counted(*args):
        calls.append(args)
        return real(*args)

    monkeypatch.setattr(quantum_module, "_CACHE", {})
    monkeypatch.setattr(quantum_module, "_compute", counted)
    params = {**TABLE_1, "tau_u": 3e-3, "f_s_spread": 0.05}
    first = table_quantum({**params, "seed": 1, "noise_std": 1e-7}, T)
    # the seeds, encoders and ripple phase do not enter: the same table
    assert table_quantum({**params, "seed": 2, "x_resolution": 1e-7}, T) is first
    assert len(calls) == 1
    table_quantum(params, 2 * T)
    table_quantum({**params, "tau_u": 4e-3}, T)
    assert len(calls) == 3


def test_a_height_that_leaves_the_table_chattering_is_passed_over():
    """A lag longer than T and a Stribeck velocity of 2.7 um/s: one ulp above the closed
    form's threshold the table breaks away at the very end of the sample and chatters
    between stick and slip in the next (the plant refuses that step: more than 10000
    events). Such a height does not count as breaking the table away; the next that does
    cleanly is u_break (found by a random draw over the plant's ranges)."""
    params = {"m": 34.049302323820406, "f_c": 58.07252129518841, "c": 1487.229004830658,
              "f_s": 88.59222150461473, "v_s": 2.7438554939469336e-06,
              "delta_s": 1.2886893750665105, "ripple": 0.35993203859033995,
              "ripple_period": 0.0076533883644812045, "tau_u": 0.023564546769457666}
    q = table_quantum(params, T)
    closed = q.band_top / -math.expm1(-T / params["tau_u"])
    assert q.u_break == pytest.approx(closed, rel=1e-14) and q.u_break > closed
    assert _moves({**params, "f_s": q.band_top / (1.0 + params["ripple"]),
                   "ripple_phase": 0.5 * math.pi}, q.u_break)
