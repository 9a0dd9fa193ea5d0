"""The readings the paper leaves open as controller settings, and the claims they reproduce.

Runs use the in-process plant (the same physics FrictionPlant.fmu bundles; the
FMU runs of ``papwc reproduce`` are checked in tests/integration).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from papwc.analysis import claims as C
from papwc.analysis.paper import TABLE_1, d_min
from papwc.controllers import make_controller
from papwc.controllers.estimators import Rls2, ScalarRls
from papwc.controllers.papwc import PapwcController
from papwc.controllers.pwc import PwcController
from papwc.controllers.settings import ControllerSettings
from papwc.errors import ScenarioError
from papwc.model.pulse import pulse_displacement
from papwc.scenario import load_scenario, parse_scenario

PAPER = Path(__file__).resolve().parents[2] / "scenarios" / "paper.toml"
T = 0.01


@pytest.fixture(scope="module")
def paper():
    return load_scenario(PAPER)


@pytest.fixture(scope="module")
def default_table(paper):
    """The claims of scenarios/paper.toml and its known readings (in-process plant)."""
    return C.evaluate_claims(paper, plant="physics")


def _holds(table: C.ClaimsTable) -> dict[str, C.ClaimRow]:
    return {row.claim.key: row for row in table.rows}


# --- the settings -------------------------------------------------------------------------


@pytest.mark.parametrize("field, value, message", [
    ("regressor", 2, "regressor = 2: must be a whole number 0 <= regressor <= 1 "
                     "(0 applied, 1 planned)"),
    ("regressor", 0.5, "regressor = 0.5: must be a whole number 0 <= regressor <= 1"),
    ("floor_mode", -1, "floor_mode = -1: must be a whole number 0 <= floor_mode <= 2"),
    ("update_covariance", 1, "update_covariance = 1: must be true or false"),
])
def test_invalid_reading_settings_are_refused_naming_the_field(field, value, message):
    problems = ControllerSettings(kind="papwc", **{field: value}).problems(("papwc",))
    assert [name for name, _ in problems] == [field]
    assert problems[0][1].startswith(message)


def test_scenario_error_names_file_table_and_field():
    data = {"controller": [{"kind": "pwc", "regressor": 3}]}
    with pytest.raises(ScenarioError, match=r"x\.toml: \[\[controller\]\] #1.*regressor = 3"):
        parse_scenario(data, "x.toml")
    data = {"controller": [{"kind": "pwc", "floor_mode": 1}]}
    with pytest.raises(ScenarioError, match="floor_mode"):
        parse_scenario(data, "x.toml")  # a PAPWC setting is not a PWC field


def test_defaults_are_the_paper_literal_reading():
    s = ControllerSettings()
    assert (s.regressor, s.update_covariance, s.floor_mode) == (0, True, 0)
    assert (s.F_inv0, s.delta_inv, s.lam) == (1e-5, 1e-5, 1.0)


# --- each new setting's effect --------------------------------------------------------------


def test_without_covariance_update_the_gains_stay_at_their_initial_values():
    fixed, updated = ScalarRls(2.75, update_gain=False), ScalarRls(2.75)
    for est in (fixed, updated):
        est.update(9e-4, 1.5e-3)
        est.update(-1e-4, -1.9e-4)
    assert fixed.F_inv == 1e-5 and updated.F_inv > 1e-5
    # Eq. (9) with F(0) fixed: b += u_p * eps / F_inv0.
    est = ScalarRls(2.75, update_gain=False)
    eps = est.update(1e-4, 2e-4)
    assert est.b_hat == pytest.approx(2.75 + 1e-4 * eps / 1e-5)
    fixed2, updated2 = Rls2((4e-5, 3e-3), update_covariance=False), Rls2((4e-5, 3e-3))
    for est in (fixed2, updated2):
        est.update((81.0, -0.27), 1.2e-3)
    assert fixed2.P == [[1e-5, 0.0], [0.0, 1e-5]]
    assert updated2.P != fixed2.P and fixed2.a != [4e-5, 3e-3]


def _pwc(**kw) -> PwcController:
    return PwcController(ControllerSettings(kind="pwc", K_c=0.6, f_c_est=80.0, **kw), T)


@pytest.mark.parametrize("regressor", [0, 1])
def test_pwc_estimator_is_fed_the_applied_or_the_planned_width(regressor):
    c = _pwc(regressor=regressor, safeguards=False)  # the paper's law, Eq. (5)
    b0 = c.estimator.b_hat
    n, f_p = c.plan_pulse(1e-3)
    t_plan = math.sqrt(0.6 * 1e-3 / b0)
    assert c.t_p_plan == pytest.approx(t_plan) and n == math.ceil(t_plan / T)
    d = 4e-4
    c.learn(n, f_p, d)
    u_p = (n * T) ** 2 if regressor == 0 else t_plan**2
    expected = b0 + u_p * (d - b0 * u_p) / (1e-5 + u_p**2)  # Eq. (7)-(9)
    assert c.estimator.b_hat == pytest.approx(expected, rel=1e-12)


def test_planned_width_is_bounded_by_t_p_max_in_whole_samples():
    c = _pwc(regressor=1, t_p_max=0.035)
    c.plan_pulse(0.01)  # Eq. (6) asks for ~0.06 s
    assert c.t_p_plan == pytest.approx(0.03)


def test_papwc_planned_regressor_is_eq_18_at_f_p_max():
    s = ControllerSettings(kind="papwc", regressor=1, t_p_max=math.inf)
    applied = PapwcController(dataclasses.replace(s, regressor=0), T)
    planned = PapwcController(s, T)
    n, f_p = planned.plan_pulse(2e-4)
    assert applied.plan_pulse(2e-4) == (n, f_p)
    assert abs(f_p) < s.f_p_max and planned.f_p_plan == s.f_p_max
    assert planned.t_p_plan < n * T
    d = 3e-4  # both regressors predict K_c*e = 2e-4 m (Eq. (10)): an error of 1e-4 m
    before = Rls2(planned.estimator.a, delta_inv=s.delta_inv)
    planned.learn(n, f_p, d)
    t2 = planned.t_p_plan**2
    before.update((s.f_p_max**2 * t2, -s.f_p_max * t2), d)
    assert planned.estimator.a == pytest.approx(before.a, rel=1e-12)
    applied.learn(n, f_p, d)
    assert applied.estimator.a != pytest.approx(planned.estimator.a, rel=1e-9)


@pytest.mark.parametrize("mode, floor_rises, learned", [(0, True, False), (1, True, True),
                                                         (2, False, True)])
def test_floor_modes_for_a_pulse_that_did_not_move(mode, floor_rises, learned):
    c = PapwcController(ControllerSettings(kind="papwc", floor_mode=mode), T)
    floor0, a0 = c.f_p_floor, list(c.estimator.a)
    c.learn(1, 110.0, 0.0)  # 110 N < f_s: the mass did not move
    assert (c.f_p_floor == pytest.approx(110.0 * 1.05)) is floor_rises
    if not floor_rises:
        assert c.f_p_floor == floor0
    assert (c.estimator.a != a0) is learned


@pytest.mark.parametrize("kind", ["pwc", "papwc"])
def test_state_carries_the_planned_pulse(kind):
    s = ControllerSettings(kind=kind, regressor=1, update_covariance=False, K_c=0.6)
    c = make_controller(s, T)
    c.update(0.0, 0.0, 3e-3)  # plans a pulse
    state = c.state()
    other = make_controller(s, T)
    other.set_state(state)
    assert other.state() == state and other.t_p_plan == c.t_p_plan > 0.0
    with pytest.raises(ValueError, match="missing"):
        other.set_state(dict(list(state.items())[:-1]))


# --- the claims and the readings that reproduce them --------------------------------------


def test_d_min_and_two_sample_displacement():
    d19 = d_min(300.0, T, 150.0, 100.0, 700.0)
    assert d19 == pytest.approx(1.8567455e-4, rel=1e-6)
    assert pulse_displacement(300.0, 2 * T, 150.0, 100.0, 700.0) == pytest.approx(6.9372e-4,
                                                                                   rel=1e-4)


def test_paper_scenario_reproduces_the_pwc_claims_with_k_c_0_6(default_table):
    rows = _holds(default_table)
    assert {k for k, r in rows.items() if r.default.holds} == {
        "limit_cycle_d_min", "unbounded_2t_cycle", "bounded_b_hat_closer", "papwc_final_error"}


def test_unbounded_pwc_cycles_with_2t_pulses_inside_the_k_c_window(paper):
    runs = C._Runs(paper, "physics")
    d2 = pulse_displacement(300.0, 2 * T, **{k: TABLE_1[k] for k in ("m", "f_c", "c")})
    widths = {}
    for k_c in (0.5, 0.54, 0.56, 0.6, 0.64, 0.66):
        m = runs.metrics(C.Reading(pwc=(("K_c", k_c),)))
        widths[k_c] = (m["pwc_bounded"].window_widths, m["pwc_unbounded"].window_widths)
        if k_c in (0.56, 0.6, 0.64):
            assert m["pwc_unbounded"].limit_cycle
            assert m["pwc_unbounded"].cycle_p2p_m == pytest.approx(d2, rel=1e-9)
            assert m["pwc_bounded"].cycle_p2p_m == pytest.approx(TABLE_1_D_MIN, rel=1e-9)
    assert widths == {0.5: ((1,), (1,)), 0.54: ((1,), (1,)), 0.56: ((1,), (2,)),
                      0.6: ((1,), (2,)), 0.64: ((1,), (2,)), 0.66: ((1,), (1,))}


TABLE_1_D_MIN = d_min(300.0, T, 150.0, 100.0, 700.0)


def test_planned_regressor_moves_the_2t_window(paper):
    runs = C._Runs(paper, "physics")
    at = {k_c: runs.metrics(C.Reading(pwc=(("K_c", k_c), ("regressor", 1))))
          for k_c in (0.6, 0.7)}
    assert at[0.6]["pwc_unbounded"].window_widths == (1,)
    assert at[0.7]["pwc_unbounded"].window_widths == (2,)
    assert at[0.7]["pwc_bounded"].window_widths == (1,)
    b = C.claim_context(paper).b
    assert at[0.7]["pwc_unbounded"].b_hat / b == pytest.approx(0.929, abs=1e-3)


@pytest.mark.parametrize("key", sorted(C.KNOWN_READINGS))
def test_each_known_reading_reproduces_its_claim(default_table, key):
    row = _holds(default_table)[key]
    if row.default.holds:
        assert key == "unbounded_2t_cycle"  # the default K_c = 0.6 already does
        return
    assert row.reading == C.KNOWN_READINGS[key]
    assert row.reading_outcome.holds, row.reading_outcome.value


#: What the unreproduced claims read: (with the known reading, at the defaults); each value
#: starts with its text, the b_hat/b ones are the whole value.
CLAIM_VALUES = {
    "papwc_adapts_faster": ("ratio 3.47 bounded", "ratio 0.86 bounded"),
    "unbounded_two_pulses": ("2 pulses (++)", "4 pulses (+++-)"),
    "unbounded_b_hat_above_b": ("b_hat/b = 1.310", "b_hat/b = 0.703"),
    "covariance_update_fewer_switches": ("0 with update, 1 without", "1 with update, 0 without"),
}


def _check_claim_values(rows, field: str, which: int) -> None:
    for key, texts in CLAIM_VALUES.items():
        value, text = getattr(rows[key], field).value, texts[which]
        if key == "unbounded_b_hat_above_b":
            assert value == text, (key, value)
        else:
            assert value.startswith(text), (key, value)


def test_known_reading_outcomes(default_table, paper):
    rows = _holds(default_table)
    _check_claim_values(rows, "reading_outcome", 0)
    assert default_table.best == C.KNOWN_BEST
    assert set(default_table.best_holds) == {c.key for c in C.CLAIMS} - {
        "unbounded_b_hat_above_b"}
    # P(0) = F(0) = 1e5 (the paper's "delta small without noise") makes the PAPWC adapt
    # faster and its b_hat end at 81 % of b, but the unbounded PAPWC cycles.
    m = C._Runs(paper, "physics").metrics(C.Reading(papwc=(("delta_inv", 1e5),)))
    assert m["papwc_bounded"].adaptation == pytest.approx(0.224, abs=1e-3)
    assert m["papwc_bounded"].b_hat / C.claim_context(paper).b == pytest.approx(0.814, abs=1e-3)
    assert m["papwc_unbounded"].limit_cycle


def test_default_values_of_the_unreproduced_claims(default_table):
    _check_claim_values(_holds(default_table), "default", 1)


def test_claims_rows_have_the_columns(default_table):
    for row in default_table.rows:
        d = row.as_dict()
        assert list(d) == C.CLAIMS_COLUMNS
        assert d["reproduced_by_default"] in ("yes", "no")
        assert d["metric"] and d["paper"] and d["default_value"]
        if d["reproduced_by_default"] == "no":
            assert d["reading"] and d["reading_value"] and d["reproduced_by_reading"] == "yes"
    text = C.claims_markdown(default_table)
    assert text.count("\n| ") == len(C.CLAIMS) + 1


def test_search_finds_the_k_c_window_and_says_when_nothing_reproduces(paper):
    scenario = dataclasses.replace(paper, controllers=[
        dataclasses.replace(s, K_c=0.5) if s.kind == "pwc" else s for s in paper.controllers])
    grid = {"pwc": (("K_c", (0.5, 0.54, 0.6, 0.62)),), "papwc": (("K_c", (0.8, 0.9)),)}
    table = C.search_readings(scenario, plant="physics", grid=grid)
    rows = _holds(table)
    assert rows["unbounded_2t_cycle"].reading == C.Reading(pwc=(("K_c", 0.6),))
    assert rows["unbounded_2t_cycle"].reading_outcome.holds
    assert rows["unbounded_b_hat_above_b"].reading is None
    assert rows["unbounded_b_hat_above_b"].as_dict()["reading"].startswith("none found")
    assert {r["reading"] for r in table.searched} == {
        "pwc: K_c = 0.54", "pwc: K_c = 0.6", "pwc: K_c = 0.62", "papwc: K_c = 0.9"}


def test_missing_roles_are_not_applicable(paper):
    only = dataclasses.replace(paper, controllers=paper.controllers[:1],
                               labels=paper.labels[:1])
    rows = _holds(C.evaluate_claims(only, plant="physics"))
    assert rows["limit_cycle_d_min"].default.holds
    assert rows["unbounded_2t_cycle"].default.holds is None
    assert rows["unbounded_2t_cycle"].as_dict()["reproduced_by_default"] == "n/a"


def test_battery_sweeps_the_reading_settings_and_refuses_to_draw_them():
    from papwc.battery.schema import parse_battery

    data = {"controller": [{"kind": "papwc"}],
            "sweep": {"controller.update_covariance": [True, False],
                      "controller.regressor": [0, 1]}}
    assert [p for p, _ in parse_battery(data, "b.toml").sweep] == [
        "controller.update_covariance", "controller.regressor"]
    drawn = {"controller": [{"kind": "papwc"}],
             "monte_carlo": {"n": 2, "controller.floor_mode": {"dist": "uniform", "low": 0,
                                                               "high": 2}}}
    with pytest.raises(ScenarioError, match="'controller.floor_mode': only floating-point"):
        parse_battery(drawn, "b.toml")


def test_adaptation_ratio_of_an_estimator_that_does_not_move():
    assert C._ratio(0.2, 0.0) == math.inf
    assert math.isnan(C._ratio(0.0, 0.0)) and math.isnan(C._ratio(math.nan, 1.0))
    assert C._ratio(0.2, 0.1) == 2.0
