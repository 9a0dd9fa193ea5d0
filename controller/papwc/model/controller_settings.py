"""The pulse controllers' settings and signals: names, units, defaults, ranges.

Standard library only (bundled into PulseController.fmu). Every setting here is
at once a field of a scenario's ``[[controller]]`` table, a battery path
(``controller.NAME``), an attribute of
:class:`papwc.controllers.settings.ControllerSettings` and a parameter of
PulseController.fmu. A setting that only one controller kind reads names it in
``kinds``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .variables import Constraint, Variable, problems, switch_variables

__all__ = [
    "CONTROLLER_CONSTRAINTS",
    "CONTROLLER_INPUTS",
    "CONTROLLER_OUTPUTS",
    "CONTROLLER_SETTINGS",
    "CONTROLLER_SWITCHES",
    "F_MODE_MAX_T",
    "KIND_CODE",
    "KIND_CODES",
    "MODE_PERIODS",
    "OUTCOMES",
    "OUTCOME_REASONS",
    "PULSE_CONTROLLER_VARIABLES",
    "REFERENCE_OFFSET",
    "SAMPLE_PERIOD",
    "STEP_RTOL",
    "fmu_parameters",
    "kind_from_code",
    "settings_problems",
]

#: Dwell of rest detection on a machine with a known mode (``f_mode > 0``), in periods of
#: it: not a whole number, so that pulses do not follow each other in step with the ringing
#: they leave.
MODE_PERIODS = 2.5
#: Longest dwell of rest detection, sample intervals (``rest_samples`` and that of ``f_mode``).
DWELL_MAX = 1_000_000
#: Highest mode a controller sampling at T takes, in units of 1/T: above it (omega*T > pi/2)
#: the mode is too close to the Nyquist frequency 0.5/T for one-sample pulses to be timed
#: against its ringing or for a loop at T to damp it.
F_MODE_MAX_T = 0.25

#: Settings of a ``[[controller]]`` table, in the order of the FMU's value references.
CONTROLLER_SETTINGS: tuple[Variable, ...] = (
    Variable("kind", "Controller kind (pwc: Section 2, papwc: Section 3, exact: Eq. (3) "
             "learned, pid: PID with friction feed-forward, no pulses, dual_loop: exact pulses "
             "from a drive relaxed by a motor-side loop on x_d_meas)", "", "papwc",
             type="String"),
    Variable("f_p_max", "Largest pulse amplitude (PWC always pulses at f_p_max), and the force "
             "limit of the coarse feedback and of the PID", "N", 300.0,
             min=0.0, min_open=True, max=1e9, nominal=100.0),
    Variable("t_p_max", "Largest pulse width; inf for no bound", "s", float("inf"), min=0.0,
             min_open=True, max=1e6, inf_ok=True, note="(inf for no bound)", fmi_default=1e6),
    Variable("K_c", "Gain of Eq. (6)", "1", 1.0, min=0.0, max=2.0, min_open=True,
             max_open=True, note="(Eq. (6))"),
    Variable("tolerance", "Error band inside which the mass at rest counts as settled", "m",
             2e-5, min=0.0, max=1.0, nominal=1e-5),
    Variable("m_est", "Initial estimate of the mass", "kg", 150.0, min=1e-6, max=1e9,
             nominal=100.0),
    Variable("f_c_est", "Initial estimate of the Coulomb friction, < f_p_max", "N", 80.0,
             min=1e-6, max=1e9, nominal=100.0),
    Variable("f_p_min", "Initial floor of the pulse amplitude, <= f_p_max; default f_c_est",
             "N", None, min=0.0, max=1e9, optional=True, nominal=100.0, fmi_default=80.0),
    Variable("floor_raise", "Relative step by which the amplitude floor rises above an "
             "amplitude that did not move the mass", "1", 0.05, min=0.0, max=1.0,
             min_open=True),
    Variable("F_inv0", "Initial inverse gain F^-1(0) of the PWC estimator, Eq. (8) (the "
             "paper: 1e-5, so F(0) = 1e5)", "s4",
             1e-5, min=1e-12, max=1e12, kinds=("pwc",)),
    Variable("lambda_1", "Forgetting parameter lambda_1 of Eq. (8)", "1", 1.0, min=0.0,
             max=1.0, min_open=True, note="(Eq. (8))", kinds=("pwc",)),
    Variable("lambda_2", "Forgetting parameter lambda_2 of Eq. (8)", "1", 1.0, min=0.0,
             max=2.0, max_open=True, note="(Eq. (8))", kinds=("pwc",)),
    Variable("delta_inv", "P(0) = delta_inv*I of the PAPWC estimator, Eq. (13)-(17) (the "
             "paper: delta^-1 = 1e-5; its advice 'delta small without noise' reads as 1e5, "
             "P(0) = F(0))", "1",
             1e-5, min=1e-12, max=1e12, kinds=("papwc",)),
    Variable("lambda", "Forgetting factor lambda of Eq. (14)-(15)", "1", 1.0, min=0.0,
             max=1.0, min_open=True, attr="lam", kinds=("papwc",)),
    Variable("regressor", "Pulse the estimator is fed, a reading the paper leaves open: 0 "
             "the applied pulse (u_p = (n*T)**2, Eq. (7)-(9); PAPWC u of Eq. (18) with the "
             "applied height f_p* and width T_x = n*T), 1 the planned pulse (t_p of Eq. (6), "
             "at most t_p_max in whole samples; PAPWC Eq. (18) as printed, at f_p_max)", "", 0,
             type="Integer", min=0, max=1, note="(0 applied, 1 planned)",
             kinds=("pwc", "papwc")),
    Variable("update_covariance", "Update F^-1 by Eq. (8) (PWC) and P by Eq. (14) (PAPWC) "
             "after each pulse; false keeps F^-1(0) and P(0) (the paper's runs 'without "
             "updating the inverse covariance matrix')", "", True, type="Boolean",
             kinds=("pwc", "papwc")),
    Variable("floor_mode", "PAPWC pulse that did not move the mass (height at or below "
             "f_s, Eq. (20)): 0 the amplitude floor rises floor_raise above it and the "
             "estimator skips it; 1 the floor rises and Eq. (13)-(17) take d = 0; 2 the floor "
             "stays f_p_min and Eq. (13)-(17) take d = 0", "", 0, type="Integer", min=0, max=2,
             note="(0 raise, 1 raise and learn d = 0, 2 learn d = 0)", kinds=("papwc",)),
    Variable("e_band", "Error band inside which the mass at rest is handed over from the "
             "coarse feedback to pulse mode, > tolerance", "m", 0.02, min=0.0, min_open=True,
             max=1e3),
    Variable("k_p", "Proportional gain of the coarse feedback (pid: of the PID); default "
             "m_est*(10 rad/s)**2 (pid: m_est*w**2, w = 0.1/T rad/s, at most 0.05*2*pi*f_mode)",
             "N/m", None, min=0.0, min_open=True, max=1e15, optional=True, fmi_default=15000.0),
    Variable("k_d", "Derivative gain of the coarse feedback (pid: of the PID); default "
             "2*0.7*(10 rad/s)*m_est (pid: 2*0.7*w*m_est)",
             "N.s/m", None, min=0.0, max=1e15, optional=True, fmi_default=2100.0),
    Variable("rest_samples", "Sample intervals over which the measured position must stay "
             "within the rest band to count as at rest (the dwell; with rest_auto, at least "
             "this)", "", 1, type="Integer", min=1, max=DWELL_MAX),
    Variable("rest_band", "Largest spread of the measured position over the dwell that still "
             "counts as at rest (with rest_auto, at least this)", "m", 0.0, min=0.0, max=1.0,
             nominal=1e-6),
    Variable("c_est", "Initial estimate of the viscous damping", "N.s/m", 0.0, min=0.0,
             max=1e9, kinds=("exact", "dual_loop"), nominal=100.0),
    Variable("history", "Number of pulses kept for the fit", "", 16, type="Integer", min=1,
             max=1000, kinds=("exact", "dual_loop")),
    Variable("max_pulses", "Pulses per maneuver after which the controller stops (PWC and "
             "PAPWC: with safeguards)", "", 20, type="Integer", min=1, max=1_000_000),
    Variable("x_resolution", "Resolution of the position measurement; weights the fit", "m",
             0.0, min=0.0, max=1.0, kinds=("exact", "dual_loop"), nominal=1e-6),
    Variable("f_s_tol", "Relative width of the f_s bracket below which no more probing is "
             "done", "1", 0.02, min=0.0, max=1.0, min_open=True, kinds=("exact", "dual_loop")),
    Variable("safeguards", "Safeguards around the control law: no planned pulse beyond the "
             "trust region (a multiple of |e| that shrinks when pulses move more than "
             "predicted), none that would end the maneuver farther from the target than it "
             "started, at most max_pulses per maneuver, PAPWC's floor raised by a pulse that "
             "moved far less than predicted; false runs the law as published (the exact "
             "controller keeps its own)", "", True, type="Boolean"),
    Variable("rest_auto", "Rest detection grows its band beyond rest_band and its dwell beyond "
             "rest_samples from the measured encoder noise (estimated from samples at rest) "
             "and the period of f_mode; with an ideal, noiseless encoder and f_mode = 0 they "
             "stay rest_band and rest_samples", "", True, type="Boolean"),
    Variable("f_mode", "Frequency of the machine's slowest mode (0 = rigid or unknown): rest "
             f"lasts at least {MODE_PERIODS:g} periods of it (the ringing a pulse leaves is "
             "waited out before the pulse is judged) and the trust region stays at most 0.5 "
             "(dual_loop: the mode of the motor on the coupling against the stuck table, that "
             "its motor loop damps; 0: no motor loop); at most "
             f"{F_MODE_MAX_T:g}/T (a mode closer to the Nyquist frequency is refused)",
             "Hz",
             0.0, min=0.0, max=1e6, nominal=10.0),
    Variable("trust0", "Trust region of a new controller: the largest planned displacement as "
             "a fraction of |e|; it grows to 1 while the model predicts well and shrinks when "
             "it does not", "1", 0.5, min=0.0, max=1.0, min_open=True,
             kinds=("exact", "dual_loop")),
    Variable("k_i", "Integral gain of the PID; default 0.25*m_est*w**3 with w = 0.1/T rad/s, "
             "at most 0.05*2*pi*f_mode (k_p and k_d default to m_est*w**2 and 2*0.7*w*m_est "
             "for it: the coarse loop's gains, which are these at T = 0.01 s)", "N/(m.s)", None,
             min=0.0, max=1e18, optional=True, kinds=("pid",), fmi_default=37500.0),
    Variable("a_max", "Largest acceleration of the PID's reference trajectory; default "
             "(f_p_max - f_c_est)/(2*m_est), half what the force limit leaves over the "
             "friction", "m/s2", None, min=0.0, min_open=True, max=1e6, optional=True,
             kinds=("pid",), fmi_default=(300.0 - 80.0) / (2.0 * 150.0)),
    Variable("v_max", "Largest speed of the PID's reference trajectory", "m/s", 0.05,
             min=0.0, min_open=True, max=1e3, kinds=("pid",)),
    Variable("hunt_max", "Reversals after which the PID, at rest nearer the target than the "
             "maneuver started, stops (outcome stopped, reason hunting): a reversal is a rest "
             "on the other side of the target than the last one", "", 4, type="Integer",
             min=1, max=1_000_000, kinds=("pid",)),
    Variable("m_d_est", "Motor mass of the flexible drive (the mode f_mode is that of the "
             "motor on the coupling against the stuck table: k_t = m_d_est*(2*pi*f_mode)**2); "
             "told f_mode, a pulse controller fires no pulse whose work on a motor of this "
             "mass, given back by the spring, could sling the table farther than the maneuver "
             "started", "kg", 50.0, min=1e-6, max=1e9, nominal=10.0,
             kinds=("pwc", "papwc", "exact", "dual_loop")),
    Variable("c_t_est", "Damping of the motor-table coupling the motor loop is designed with",
             "N.s/m", 0.0, min=0.0, max=1e9, nominal=100.0, kinds=("dual_loop",)),
    Variable("f_relax", "Largest force amplitude of the drive's ringing, k_t*sqrt(delta**2 + "
             "(delta'/(2*pi*f_mode))**2) with delta = x_d_meas - x_meas, at which the drive "
             "counts as relaxed (a pulse starts, a move is read, the maneuver settles only "
             "from a relaxed drive)", "N", 2.0, min=0.0, min_open=True, max=1e9,
             nominal=1.0, kinds=("dual_loop",)),
    Variable("identify_mode", "With f_mode = 0: identify the drive's mode from the motor "
             "encoder's free ringing (x_d_meas - x_meas while the table sticks) after a probe "
             "(one sample of 0.4*f_c_est on the motor at the first sample, which friction "
             "holds the table against) and build the motor loop on it, with m_d_est and "
             "c_t_est; the table's encoder alone until then, and for good if no ringing "
             "within 0.5 s or a mode above 0.25/T. False: f_mode = 0 means no motor loop",
             "", False,
             type="Boolean", kinds=("dual_loop",)),
)

def _below_f_p_max(name: str, strict: bool):
    def check(values: Mapping[str, Any]) -> tuple[str, str] | None:
        """(name, message) if the setting exceeds f_p_max."""
        value, f_p_max = values[name], values["f_p_max"]
        if value is None or (value < f_p_max if strict else value <= f_p_max):
            return None
        lo = "0 <" if strict else "0 <="
        op = "<" if strict else "<="
        return name, (f"{name} = {value!r} N: must satisfy {lo} {name} {op} f_p_max = "
                      f"{f_p_max!r} N")

    return Constraint((name, "f_p_max"), check)


def _e_band_above_tolerance(values: Mapping[str, Any]) -> tuple[str, str] | None:
    if values["e_band"] > values["tolerance"]:
        return None
    return "e_band", (f"e_band = {values['e_band']!r} m: must be > tolerance = "
                      f"{values['tolerance']!r} m")


def _t_p_max_at_least_T(values: Mapping[str, Any]) -> tuple[str, str] | None:
    if values["t_p_max"] >= values["T"]:
        return None
    return "t_p_max", (f"t_p_max = {values['t_p_max']!r} s: must be >= T = {values['T']!r} s "
                       "(a pulse lasts a whole number of samples, at least one)")


def _mode_dwell_bounded(values: Mapping[str, Any]) -> tuple[str, str] | None:
    f_mode, T = values["f_mode"], values["T"]
    if f_mode == 0.0 or MODE_PERIODS <= DWELL_MAX * f_mode * T:
        return None
    return "f_mode", (f"f_mode = {f_mode!r} Hz: a rest lasts {MODE_PERIODS:g} periods of it, "
                      f"more than {DWELL_MAX} samples of T = {T!r} s; must be 0 (no mode) or "
                      f">= {MODE_PERIODS / (DWELL_MAX * T):g} Hz")


def _mode_below_quarter_rate(values: Mapping[str, Any]) -> tuple[str, str] | None:
    f_mode, T = values["f_mode"], values["T"]
    if f_mode * T <= F_MODE_MAX_T * (1.0 + 1e-12):
        return None
    return "f_mode", (f"f_mode = {f_mode!r} Hz: above {F_MODE_MAX_T:g}/T = "
                      f"{F_MODE_MAX_T / T:g} Hz (T = {T!r} s), too close to the sampling's "
                      f"Nyquist frequency {0.5 / T:g} Hz for a controller sampling at T (a "
                      "motor loop cannot damp it, pulses cannot wait it out); must be 0 (rigid "
                      f"or unknown) or f_mode <= {F_MODE_MAX_T:g}/T = {F_MODE_MAX_T / T:g} Hz "
                      "(or sample faster)")


#: Rules between settings (and the sample period ``T``, where it is given: the
#: controller FMU's parameter, a scenario's ``[maneuver]`` field).
CONTROLLER_CONSTRAINTS: tuple[Constraint, ...] = (
    _below_f_p_max("f_c_est", strict=True),
    _below_f_p_max("f_p_min", strict=False),
    Constraint(("e_band", "tolerance"), _e_band_above_tolerance),
    Constraint(("t_p_max", "T"), _t_p_max_at_least_T),
    Constraint(("f_mode", "T"), _mode_dwell_bounded),
    Constraint(("f_mode", "T"), _mode_below_quarter_rate),
)

#: The sample period as a parameter of PulseController.fmu.
SAMPLE_PERIOD = Variable("T", "Sample period: every communication step must be T", "s", 0.01,
                         min=1e-9, max=1e3)
#: Relative tolerance of PulseController.fmu's check that a communication step is T (libcosim
#: steps on a grid of whole nanoseconds).
STEP_RTOL = 1e-9

#: A fixed reference as a parameter of PulseController.fmu: the controller's reference is
#: ``x_ref_offset + x_ref``. An SSP binds it (SSP 1.0 bindings set FMI 2.0 variables with
#: ``initial = "exact"`` or ``"approx"``: parameters, not inputs) and leaves ``x_ref`` at 0.
REFERENCE_OFFSET = Variable(
    "x_ref_offset", "Constant added to the input x_ref: the reference is x_ref_offset + x_ref "
    "(a fixed target for hosts that leave x_ref unconnected)", "m", 0.0, min=-1e6, max=1e6,
    nominal=0.01,
)

#: Controller kinds by number: ``KIND_CODES[n - 1]`` is the kind that ``kind_code = n``
#: selects (the registry of :mod:`papwc.controllers` has exactly these kinds).
KIND_CODES: tuple[str, ...] = ("pwc", "papwc", "exact", "pid", "dual_loop")

#: The controller kind as an Integer parameter of PulseController.fmu, for hosts and SSP
#: readers that cannot set the String ``kind`` (fmpy, OMSimulator). 0 leaves the choice
#: to ``kind``; a host that sets both must set them alike.
KIND_CODE = Variable(
    "kind_code", "Controller kind as a number, for hosts that cannot set Strings: 0 = as the "
    "String kind says, " + ", ".join(f"{n} = {k}" for n, k in enumerate(KIND_CODES, 1))
    + "; if kind is also set, both must name the same kind", "", 0, type="Integer", min=0,
    max=len(KIND_CODES),
)


def kind_from_code(kind: str, kind_code: int, kind_set: bool) -> tuple[str, str | None]:
    """The controller kind that ``kind`` and ``kind_code`` select, and a conflict if any.

    Parameters
    ----------
    kind : str
        The String parameter ``kind``.
    kind_code : int
        The Integer parameter ``kind_code`` (0: ``kind`` decides).
    kind_set : bool
        Whether ``kind`` was set (not left at its start value).

    Returns
    -------
    (str, str or None)
        The kind, and ``None`` or the message that refuses the pair.
    """
    if kind_code == 0 or not 1 <= kind_code <= len(KIND_CODES):
        return kind, None
    named = KIND_CODES[kind_code - 1]
    if kind_set and kind != named:
        return kind, (f"parameter kind = {kind!r} and kind_code = {kind_code} ({named!r}) "
                      "name different controllers: set only one of them, or both alike")
    return named, None


#: Outcome of a maneuver by code (the controller FMU's ``outcome`` output): ``active`` while
#: the controller still works (coarse, pulse, wait), ``settled`` once |e| is within the
#: tolerance at rest, ``stopped`` when it gave up (``outcome_reason`` says why).
OUTCOMES: tuple[str, ...] = ("active", "settled", "stopped")

#: Reasons of an outcome by code (the controller FMU's ``outcome_reason`` output).
#: ``time_ended`` is never set by a controller: a maneuver whose time ended while its
#: controller was still active is ``stopped`` for that reason in the results.
OUTCOME_REASONS: tuple[str, ...] = (
    "",  # 0: active
    "within_tolerance",  # 1: settled
    "no_move_helps",  # 2: no pulse it can make would bring the mass nearer to the target
    "pulse_budget",  # 3: max_pulses pulses in this maneuver
    "model_rejected",  # 4: its model predicts so badly that no pulse can be trusted
    "time_ended",  # 5: the maneuver ended while the controller was still active
    "invalid_measurement",  # 6: a reading or reference not finite, or beyond 1e6 m
    "cannot_move",  # 7: the largest pulse did not move the mass
    "hunting",  # 8: a PID at rest, nearer than it started, after hunt_max reversals
)

#: Inputs of PulseController.fmu, read at the start of each step.
CONTROLLER_INPUTS: tuple[Variable, ...] = (
    Variable("x_meas", "Measured position, read at the start of each step", "m", 0.0,
             causality="input"),
    Variable("x_ref", "Reference position, read at the start of each step", "m", 0.0,
             causality="input"),
    Variable("maneuver", "Maneuver number: when it changes, the controller starts a new "
             "maneuver from rest, keeping what it has learned (u is 0 until the next step)",
             "", 0, causality="input", type="Integer"),
    Variable("x_d_meas", "Motor-side position (the plant's motor encoder x_d_meas), read at the "
             "start of each step; unconnected by default (the table's encoder alone); only "
             "the dual_loop kind reads it", "m", 0.0, causality="input"),
)

#: Outputs of PulseController.fmu after each step (no direct feedthrough at a
#: communication point: they change only in doStep).
CONTROLLER_OUTPUTS: tuple[Variable, ...] = (
    Variable("u", "Force to hold over the next sample, computed at the last step (0 before "
             "the first step)", "N", 0.0, causality="output", initial="exact",
             variability="discrete"),
    Variable("b_hat", "Estimated pulse-model coefficient b at f_p_max (PWC: Eq. (7)-(9); "
             "PAPWC: A1*f_p_max**2 - A2*f_p_max, Eq. (12))", "m/s2", 0.0,
             causality="output", initial="calculated", variability="discrete"),
    Variable("f_c_hat", "Estimated Coulomb friction (PAPWC: A2/A1; PWC: implied by b_hat)",
             "N", 0.0, causality="output", initial="calculated", variability="discrete"),
    Variable("pulses", "Number of pulses started since the start of the simulation", "", 0,
             causality="output", type="Integer", initial="exact"),
    Variable("mode", "Controller mode after the last step: 0 coarse, 1 pulse, 2 wait, "
             "3 settled (also before the first step: the mass is taken to be at rest and no "
             "force is applied)", "", 3, causality="output", type="Integer", initial="exact"),
    Variable("f_low", "Lowest pulse height the controller plans with now (PWC: f_p_max; "
             "PAPWC: its amplitude floor; exact: f_floor): one sample at it is the smallest "
             "pulse it can make", "N", 0.0, causality="output", initial="calculated",
             variability="discrete"),
    Variable("outcome", "Outcome of the maneuver so far: " + ", ".join(
             f"{n} {name}" for n, name in enumerate(OUTCOMES)) + " (settled only with |e| "
             "within the tolerance at rest; stopped: it gave up, see outcome_reason)", "", 0,
             causality="output", type="Integer", initial="exact"),
    Variable("outcome_reason", "Why: " + ", ".join(
             f"{n} {name or 'none (active)'}" for n, name in enumerate(OUTCOME_REASONS)), "",
             0, causality="output", type="Integer", initial="exact"),
)


#: Boolean parameters ``<name>_given`` of PulseController.fmu, false by default: the computed
#: default of an optional setting (``None`` in a scenario) or no bound on the pulse width
#: (``t_p_max = inf``), the Real beside it not read; true, the Real is used. (A value the
#: Real cannot hold, as -1 for "computed", would be one a host's range check cannot tell from
#: a wrong value.)
CONTROLLER_SWITCHES: tuple[Variable, ...] = switch_variables(CONTROLLER_SETTINGS)

#: Every variable of PulseController.fmu, in the order of its value references (the
#: switches last, so that the other variables keep their value references).
PULSE_CONTROLLER_VARIABLES: tuple[Variable, ...] = (
    CONTROLLER_SETTINGS + (SAMPLE_PERIOD, KIND_CODE, REFERENCE_OFFSET) + CONTROLLER_INPUTS
    + CONTROLLER_OUTPUTS + CONTROLLER_SWITCHES
)


def fmu_parameters(values: Mapping[str, Any]) -> dict[str, Any]:
    """PulseController.fmu parameters for settings ``values`` (scenario-file names).

    A setting at the default a Real cannot hold (``None``: computed; ``inf``: no
    bound) is left out (its switch ``<name>_given`` and the Real keep their start
    values, which select that default); any other value of such a setting sets the
    Real and its switch true. Other settings are passed as they are.
    """
    out: dict[str, Any] = {}
    for var in CONTROLLER_SETTINGS:
        if var.name not in values:
            continue
        value = values[var.name]
        if not var.switch:
            out[var.name] = value
        elif value is not None and value != var.switched_value:
            out[var.name] = value
            out[var.switch] = True
    return out


def settings_problems(values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """Every invalid setting in ``values`` (scenario-file names) as ``(name, message)``.

    Only the values given are checked (the kind is checked against the
    registered controllers by :mod:`papwc.controllers`).
    """
    return problems(CONTROLLER_SETTINGS, values, CONTROLLER_CONSTRAINTS)
