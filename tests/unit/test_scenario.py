"""Scenario files and controller settings: validation against the model layer's tables,
with errors that name the file, the table and the field."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from harness import GOOD

from papwc.controllers import CONTROLLER_KINDS
from papwc.controllers.settings import SETTINGS_BY_NAME, ControllerSettings, settings_for_kind
from papwc.errors import ScenarioError
from papwc.master import Maneuver
from papwc.model.controller_settings import CONTROLLER_SETTINGS
from papwc.model.maneuver import MANEUVER_DEFAULTS, MANEUVER_VARIABLES
from papwc.model.plant import PLANT_DEFAULTS
from papwc.model.units import UNIT_DEFINITIONS
from papwc.model.variables import Variable, problems
from papwc.scenario import controller_label, load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[2]


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


PAPWC_FIELDS = ("kind, f_p_max, t_p_max, K_c, tolerance, m_est, f_c_est, f_p_min, floor_raise, "
                "e_band, k_p, k_d, rest_samples, rest_band, max_pulses, safeguards, rest_auto, "
                "f_mode, regressor, update_covariance, m_d_est, delta_inv, lambda, floor_mode, "
                "label")


@pytest.mark.parametrize(
    ("change", "field", "message"),
    [
        (("m = 150.0", "m = -1.0"), "m", "[plant] field 'm': m = -1.0 kg: must satisfy 1e-06 <= "
                                         "m <= 1e+09 kg"),
        (("m = 150.0", "m = 150.0\nf_s = 20.0"), "f_s",
         "[plant] field 'f_s': f_s = 20.0 N: must be >= f_c = 100.0 N"),
        (("m = 150.0", "mass = 150.0"), "mass",
         "[plant] unknown field 'mass'; allowed: m, f_c, f_s, c, x_resolution, v_s, delta_s, "
         "sigma_0, sigma_1, ripple, ripple_period, ripple_phase, f_s_spread, seed, tau_u, m_d, "
         "k_t, c_t, noise_std, x_d_resolution, x_d_noise_std"),
        (("T = 0.01", "T = 0.0"), "'T'", "[maneuver] field 'T': T = 0.0 s: must satisfy 1e-09 "
                                         "<= T <= 1000 s"),
        (("iterations = 1", "iterations = 1.5"), "iterations",
         "[maneuver] field 'iterations': iterations = 1.5: must be a whole number 1 <= "
         "iterations <= 1000000"),
        (('kind = "papwc"', 'kind = "lqr"'), "kind",
         "[[controller]] #1 field 'kind' = 'lqr': must be one of 'dual_loop', 'exact', 'hybrid', "
         "'papwc', 'pid', 'pwc'"),
        (('kind = "papwc"', 'kind = "papwc"\nK_c = 2.5'), "K_c",
         "[[controller]] #1 field 'K_c': K_c = 2.5: must satisfy 0 < K_c < 2 (Eq. (6))"),
        (('kind = "papwc"', 'kind = "papwc"\nt_p_max = "long"'), "t_p_max",
         "[[controller]] #1 field 't_p_max': t_p_max = 'long': must be a number"),
        (('kind = "papwc"', 'kind = "papwc"\nf_c_est = 400.0'), "f_c_est",
         "[[controller]] #1 field 'f_c_est': f_c_est = 400.0 N: must satisfy 0 < f_c_est < "
         "f_p_max = 300.0 N"),
        (('kind = "papwc"', 'kind = "papwc"\ntolerence = 1e-5'), "tolerence",
         "[[controller]] #1 unknown field 'tolerence' for kind 'papwc'; allowed: "
         + PAPWC_FIELDS),
        (('kind = "papwc"', 'kind = "papwc"\nhistory = 3'), "history",
         "[[controller]] #1 unknown field 'history' for kind 'papwc'; allowed: " + PAPWC_FIELDS),
        (('kind = "papwc"', 'kind = "papwc"\nrest_samples = 0'), "rest_samples",
         "[[controller]] #1 field 'rest_samples': rest_samples = 0: must be a whole number 1 <= "
         "rest_samples <= 1000000"),
        (('kind = "papwc"', 'kind = "papwc"\ne_band = 1e-6'), "e_band",
         "[[controller]] #1 field 'e_band': e_band = 1e-06 m: must be > tolerance = 2e-05 m"),
        (('kind = "papwc"', 'kind = "papwc"\nlabel = 3'), "label",
         "[[controller]] #1 field 'label' = 3: must be a string"),
        (("duration = 0.5", "duration = 0.001"), "duration",
         "[maneuver] field 'duration': duration = 0.001 s: must be >= T = 0.01 s"),
        (("iterations = 1", "iterations = 1\ntiming = 'late'"), "timing",
         "[maneuver] field 'timing': timing = 'late': must be one of 'immediate', 'delayed'"),
    ],
)
def test_scenario_errors_name_the_file_and_the_field(tmp_path, change, field, message):
    path = _write(tmp_path, GOOD.replace(*change))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert str(path) in str(info.value)
    assert field in str(info.value)
    assert str(info.value) == f"{path}: {message}"


#: An exact controller's table with each of its own settings wrong.
EXACT_ERRORS = [
    ("history = 0", "history", "history = 0: must be a whole number 1 <= history <= 52"),
    ("history = -1", "history", "history = -1: must be a whole number 1 <= history <= 52"),
    ('c_est = "x"', "c_est", "c_est = 'x': must be a number"),
    ("f_s_tol = 0", "f_s_tol", "f_s_tol = 0: must satisfy 0 < f_s_tol <= 1"),
    ("f_s_tol = 1.5", "f_s_tol", "f_s_tol = 1.5: must satisfy 0 < f_s_tol <= 1"),
    ("history = true", "history", "history = True: must be a number"),
    ("max_pulses = 0", "max_pulses", "max_pulses = 0: must be a whole number 1 <= max_pulses <= "
                                     "1000000"),
    ("max_pulses = 2.5", "max_pulses", "max_pulses = 2.5: must be a whole number 1 <= "
                                       "max_pulses <= 1000000"),
    ("c_est = -1.0", "c_est", "c_est = -1.0 N.s/m: must satisfy 0 <= c_est <= 1e+09 N.s/m"),
    ("c_est = inf", "c_est", "c_est = inf N.s/m: must be a finite number"),
    ("x_resolution = -1e-6", "x_resolution", "x_resolution = -1e-06 m: must satisfy 0 <= "
                                             "x_resolution <= 1 m"),
]


@pytest.mark.parametrize(("line", "field", "message"), EXACT_ERRORS,
                         ids=[line for line, _, _ in EXACT_ERRORS])
def test_bad_exact_setting_is_a_scenario_error_naming_the_file_and_field(
    tmp_path, line, field, message
):
    path = _write(tmp_path, GOOD.replace('kind = "papwc"', f'kind = "exact"\n{line}'))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert str(info.value) == f"{path}: [[controller]] #1 field '{field}': {message}"


def test_exact_settings_are_read_from_the_scenario(tmp_path):
    text = GOOD.replace('kind = "papwc"', 'kind = "exact"\nhistory = 4\nmax_pulses = 3\n'
                        'c_est = 12.5\nx_resolution = 1e-6\nf_s_tol = 0.5')
    (settings,) = load_scenario(_write(tmp_path, text)).controllers
    assert (settings.history, settings.max_pulses, settings.c_est, settings.x_resolution,
            settings.f_s_tol) == (4, 3, 12.5, 1e-6, 0.5)


def test_scenario_toml_syntax_error_names_the_file(tmp_path):
    path = _write(tmp_path, GOOD + "\n[[controller]\n")
    with pytest.raises(ScenarioError, match="not valid TOML") as info:
        load_scenario(path)
    assert str(info.value).startswith(f"{path}: not valid TOML: ")
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(tmp_path / "missing.toml")


def test_defaults_come_from_the_model_tables(tmp_path):
    sc = load_scenario(_write(tmp_path, 'name = "d"\n[[controller]]\nkind = "pwc"\n'))
    assert sc.plant == {k: v for k, v in PLANT_DEFAULTS.items() if k not in ("x0", "v0")}
    assert sc.maneuver == Maneuver(**MANEUVER_DEFAULTS)
    assert sc.controllers == [ControllerSettings(kind="pwc")]
    assert sc.labels == ["pwc_tpmax_inf"]
    assert sc.name == "d" and sc.source == str(tmp_path / "s.toml")


def test_labels_name_the_controllers_and_must_differ(tmp_path):
    assert controller_label(ControllerSettings(kind="pwc", t_p_max=0.03)) == "pwc_tpmax_0.03"
    assert controller_label(ControllerSettings(kind="papwc")) == "papwc_tpmax_inf"
    assert controller_label(ControllerSettings(), "mine") == "mine"
    text = GOOD + '[[controller]]\nkind = "papwc"\n'
    with pytest.raises(ScenarioError, match="two \\[\\[controller\\]\\] tables have the same "
                                            "label"):
        load_scenario(_write(tmp_path, text))
    with pytest.raises(ScenarioError, match="unknown top-level field 'sweep'"):
        parse_scenario({"sweep": {}, "controller": [{"kind": "pwc"}]}, "x.toml")
    assert parse_scenario({"sweep": {"a": 1}, "controller": [{"kind": "pwc"}]}, "x.toml",
                          allow=("sweep",)).extra == {"sweep": {"a": 1}}


def test_shipped_scenarios_load():
    from papwc.battery import load_battery

    paths = sorted((ROOT / "scenarios").glob("*.toml"))
    assert len(paths) >= 6
    for path in paths:
        if "[monte_carlo]" in path.read_text() or "[sweep]" in path.read_text():
            assert load_battery(path)  # a battery file, read by papwc battery
        else:
            assert load_scenario(path).controllers


# -- the settings table --------------------------------------------------------------------------
def test_settings_dataclass_is_built_from_the_table():
    settings = ControllerSettings()
    assert ControllerSettings.field_names() == [v.name for v in CONTROLLER_SETTINGS]
    for var in CONTROLLER_SETTINGS:
        assert settings.get(var.name) == var.default or (
            isinstance(var.default, float) and math.isinf(var.default))
        assert SETTINGS_BY_NAME[var.name] is var
        assert var.unit in UNIT_DEFINITIONS or (var.type != "Real" and var.unit == "")
        assert var.description
    assert {v.name: v.attribute for v in CONTROLLER_SETTINGS if v.attr} == {"lambda": "lam"}
    assert settings.lam == 1.0
    mapping = settings.to_mapping(with_none=True)
    assert ControllerSettings.from_mapping(mapping) == settings
    assert "f_p_min" not in settings.to_mapping() and "f_p_min" in mapping
    assert settings.problems(tuple(CONTROLLER_KINDS)) == []


def test_computed_defaults():
    settings = ControllerSettings(m_est=120.0, f_c_est=70.0)
    assert settings.f_p_floor0 == 70.0
    assert settings.k_p_value == 120.0 * 100.0
    assert settings.k_d_value == 2.0 * 0.7 * 10.0 * 120.0
    given = ControllerSettings(f_p_min=90.0, k_p=5.0, k_d=1.0)
    assert (given.f_p_floor0, given.k_p_value, given.k_d_value) == (90.0, 5.0, 1.0)


@pytest.mark.parametrize("kind", sorted(CONTROLLER_KINDS))
def test_each_kind_reads_the_shared_settings_and_its_own(kind):
    names = settings_for_kind(kind)
    assert names[0] == "kind"
    own = [v.name for v in CONTROLLER_SETTINGS if v.kinds]
    assert all(not SETTINGS_BY_NAME[n].kinds or kind in SETTINGS_BY_NAME[n].kinds
               for n in names)
    assert set(own) - set(names) == {n for n in own if kind not in SETTINGS_BY_NAME[n].kinds}


@pytest.mark.parametrize(
    ("values", "expected"),
    [
        ({"kind": "lqr"}, [("kind", "kind = 'lqr': must be one of 'pwc', 'papwc', 'exact', "
                                    "'pid', 'dual_loop', 'hybrid'")]),
        ({"k_p": -5.0}, [("k_p", "k_p = -5.0 N/m: must satisfy 0 < k_p <= 1e+15 N/m")]),
        ({"k_d": None, "k_p": None, "f_p_min": None}, []),
        ({"f_p_min": 301.0}, [("f_p_min", "f_p_min = 301.0 N: must satisfy 0 <= f_p_min <= "
                                          "f_p_max = 300.0 N")]),
        ({"t_p_max": math.inf}, []),
        ({"t_p_max": -math.inf}, [("t_p_max", "t_p_max = -inf s: must be a finite number or "
                                              "inf")]),
        ({"lambda_2": 2.0}, [("lambda_2", "lambda_2 = 2.0: must satisfy 0 <= lambda_2 < 2 "
                                          "(Eq. (8))")]),
        ({"rest_samples": 1.5}, [("rest_samples", "rest_samples = 1.5: must be a whole number "
                                                  "1 <= rest_samples <= 1000000")]),
    ],
)
def test_settings_problems(values, expected):
    settings = ControllerSettings(**{("lam" if k == "lambda" else k): v
                                     for k, v in values.items()})
    assert settings.problems(tuple(CONTROLLER_KINDS)) == expected


def test_variable_messages_have_one_form():
    var = Variable("k_p", "gain", "N/m", None, min=0.0, min_open=True, optional=True)
    assert var.check(None) is None
    assert var.message(-5.0, var.check(-5.0)) == "k_p = -5.0 N/m: must be > 0 N/m"
    ratio = Variable("K_c", "gain", "1", 1.0, min=0.0, max=2.0, min_open=True, max_open=True,
                     note="(Eq. (6))")
    assert ratio.message(2.5, ratio.check(2.5)) == "K_c = 2.5: must satisfy 0 < K_c < 2 (Eq. (6))"
    count = Variable("n", "count", "", 1, type="Integer", min=1)
    assert problems([count], {"n": 0}) == [("n", "n = 0: must be a whole number >= 1")]
    assert problems([count], {"m": 0}) == []  # only names given are checked
    with pytest.raises(ValueError, match="type 'Float'"):
        Variable("x", "bad", type="Float")
    for var in MANEUVER_VARIABLES:
        assert var.check(var.default) is None, var.name
