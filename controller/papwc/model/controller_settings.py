"""The pulse controllers' settings and signals: names, units, defaults, ranges.

Standard library only (bundled into PulseController.fmu). Every setting is at once a
field of a scenario's ``[[controller]]`` table, a battery path (``controller.NAME``), an
attribute of :class:`papwc.controllers.settings.ControllerSettings` and a parameter of
PulseController.fmu. The settings every kind reads are declared here
(:data:`SHARED_SETTINGS`); a controller kind declares its own in its module (its class's
``SETTINGS``, with this module's :class:`~papwc.model.variables.Variable`), and
:data:`CONTROLLER_SETTINGS` is assembled from both through the registry
(:func:`assemble_settings`), each setting's ``kinds`` naming the kinds that read it (empty:
every kind); so is :data:`KIND_CODES`, the kinds' numbers in PulseController.fmu.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from .variables import Constraint, Variable, problems, switch_variables

__all__ = [
    "CONTROLLER_CONSTRAINTS",
    "CONTROLLER_INPUTS",
    "CONTROLLER_OUTPUTS",
    "CONTROLLER_SETTINGS",  # noqa: F822 (assembled on first use, see __getattr__)
    "CONTROLLER_SWITCHES",  # noqa: F822 (assembled on first use, see __getattr__)
    "SHARED_SETTINGS",
    "F_MODE_MAX_T",
    "KIND_CODE",  # noqa: F822 (assembled on first use, see __getattr__)
    "KIND_CODES",  # noqa: F822 (assembled on first use, see __getattr__)
    "MODE_PERIODS",
    "OUTCOMES",
    "OUTCOME_REASONS",
    "PULSE_CONTROLLER_VARIABLES",  # noqa: F822 (assembled on first use, see __getattr__)
    "REFERENCE_OFFSET",
    "SAMPLE_PERIOD",
    "STEP_RTOL",
    "assemble_settings",
    "kind_code_variable",
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
#: Settings every controller kind reads (a ``[[controller]]`` table of any kind may set them),
#: in the order of the FMU's value references. Each kind adds its own in its module
#: (``SETTINGS`` of its class, :mod:`papwc.controllers`); :data:`CONTROLLER_SETTINGS` is
#: assembled from these and the registry.
SHARED_SETTINGS: tuple[Variable, ...] = (
    Variable("kind", "Controller kind (pwc: Section 2, papwc: Section 3, exact: Eq. (3) "
             "learned, pid: PID with friction feed-forward, no pulses, dual_loop: exact pulses "
             "from a drive relaxed by a motor-side loop on x_d_meas, hybrid: the PID's approach "
             "with its in-position window, then force ramps cut on the first reliable move, "
             "for T = 1 ms)", "", "papwc", type="String"),
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
    Variable("max_pulses", "Pulses per maneuver after which the controller stops (PWC and "
             "PAPWC: with safeguards)", "", 20, type="Integer", min=1, max=1_000_000),
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

def kind_code_variable(kind_codes: Sequence[str]) -> Variable:
    """The controller kind as an Integer parameter of PulseController.fmu (``kind_code``).

    For hosts and SSP readers that cannot set the String ``kind`` (fmpy, OMSimulator): 0
    leaves the choice to ``kind``, ``n`` selects ``kind_codes[n - 1]``; a host that sets
    both must set them alike.
    """
    return Variable(
        "kind_code", "Controller kind as a number, for hosts that cannot set Strings: 0 = as "
        "the String kind says, " + ", ".join(f"{n} = {k}" for n, k in enumerate(kind_codes, 1))
        + "; if kind is also set, both must name the same kind", "", 0, type="Integer", min=0,
        max=len(kind_codes),
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
    codes = __getattr__("KIND_CODES")
    if kind_code == 0 or not 1 <= kind_code <= len(codes):
        return kind, None
    named = codes[kind_code - 1]
    if kind_set and kind != named:
        return kind, (f"parameter kind = {kind!r} and kind_code = {kind_code} ({named!r}) "
                      "name different controllers: set only one of them, or both alike")
    return named, None


#: Outcome of a maneuver by code (the controller FMU's ``outcome`` output): ``active`` while
#: the controller still works (coarse, pulse, wait), ``settled`` once abs(e) is within the
#: tolerance at rest, ``stopped`` when it gave up (``outcome_reason`` says why).
OUTCOMES: tuple[str, ...] = ("active", "settled", "stopped")

#: Reasons of an outcome by code (the controller FMU's ``outcome_reason`` output).
#: ``time_ended`` is never set by a controller: a maneuver whose time ended while its
#: controller was still active is ``stopped`` for that reason in the results.
OUTCOME_REASONS: tuple[str, ...] = (
    "",  # 0: active
    "within_tolerance",  # 1: settled
    "no_move_helps",  # 2: no pulse it can make would bring the mass nearer to the target
    "pulse_budget",  # 3: max_pulses pulses in this maneuver (exact, dual_loop: settle_timeout)
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


def assemble_settings(shared: Sequence[Variable],
                      by_kind: Mapping[str, Sequence[Variable]]) -> tuple[Variable, ...]:
    """The settings of every controller kind: ``shared``, then each kind's own, in order.

    Parameters
    ----------
    shared : sequence of Variable
        The settings every kind reads (:data:`SHARED_SETTINGS`), without ``kinds``.
    by_kind : mapping of str to sequence of Variable
        Each kind's own settings (its class's ``SETTINGS``), in the registry's order. A
        setting that several kinds read is the same :class:`~papwc.model.variables.Variable`
        in each of their tuples.

    Returns
    -------
    tuple of Variable
        The shared settings, then each kind's in the order of ``by_kind`` (a setting
        listed by several kinds where the first lists it), each with ``kinds`` set to the
        kinds that list it.

    Raises
    ------
    ValueError
        If two different settings have one name.
    """
    kinds: dict[str, list[str]] = {}
    first: dict[str, Variable] = {v.name: v for v in shared}
    for kind, own in by_kind.items():
        for var in own:
            known = first.setdefault(var.name, var)
            if known is not var or var in shared:
                raise ValueError(f"setting {var.name!r} of kind {kind!r} is declared twice")
            kinds.setdefault(var.name, []).append(kind)
    return tuple(first[name] if name not in kinds
                 else dataclasses.replace(first[name], kinds=tuple(kinds[name]))
                 for name in first)


def _assembled() -> dict[str, Any]:
    """The tables that depend on the registered kinds and their settings (once)."""
    from ..controllers.registry import CONTROLLER_KINDS

    kind_codes = tuple(CONTROLLER_KINDS)
    settings = assemble_settings(SHARED_SETTINGS, {kind: CONTROLLER_KINDS[kind].SETTINGS
                                                   for kind in CONTROLLER_KINDS})
    switches = switch_variables(settings)
    kind_code = kind_code_variable(kind_codes)
    return {
        "KIND_CODES": kind_codes,
        "KIND_CODE": kind_code,
        "CONTROLLER_SETTINGS": settings,
        "CONTROLLER_SWITCHES": switches,
        "PULSE_CONTROLLER_VARIABLES": (
            settings + (SAMPLE_PERIOD, kind_code, REFERENCE_OFFSET) + CONTROLLER_INPUTS
            + CONTROLLER_OUTPUTS + switches),
    }


#: The names :func:`__getattr__` assembles from the registry on first use.
_LAZY = ("KIND_CODES", "KIND_CODE", "CONTROLLER_SETTINGS", "CONTROLLER_SWITCHES",
         "PULSE_CONTROLLER_VARIABLES")


def __getattr__(name: str) -> Any:
    """The tables assembled from the registered controller kinds, on first use.

    - ``KIND_CODES``: the kinds by number, in the registry's order:
      ``KIND_CODES[n - 1]`` is the kind that PulseController.fmu's ``kind_code = n``
      selects (a new kind is registered last, so the numbers of the others stay);
    - ``KIND_CODE``: that parameter (:func:`kind_code_variable`);
    - ``CONTROLLER_SETTINGS``: the settings of a ``[[controller]]`` table of any kind,
      in the order of PulseController.fmu's value references (:func:`assemble_settings`
      over :data:`SHARED_SETTINGS` and each registered kind's ``SETTINGS``);
    - ``CONTROLLER_SWITCHES``: the Boolean parameters ``<name>_given`` of
      PulseController.fmu, false by default: the computed default of an optional setting
      (``None`` in a scenario) or no bound on the pulse width (``t_p_max = inf``), the
      Real beside it not read; true, the Real is used;
    - ``PULSE_CONTROLLER_VARIABLES``: every variable of PulseController.fmu in the order
      of its value references (the switches last).

    A kind's settings are declared in its own module (:mod:`papwc.controllers`), so these
    are assembled from the registry the first time one is read, not when this module is
    imported (the controllers import this module).
    """
    if name in _LAZY:
        tables = _assembled()
        globals().update(tables)
        return tables[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def fmu_parameters(values: Mapping[str, Any]) -> dict[str, Any]:
    """PulseController.fmu parameters for settings ``values`` (scenario-file names).

    A setting at the default a Real cannot hold (``None``: computed; ``inf``: no
    bound) is left out (its switch ``<name>_given`` and the Real keep their start
    values, which select that default); any other value of such a setting sets the
    Real and its switch true. Other settings are passed as they are.
    """
    out: dict[str, Any] = {}
    for var in __getattr__("CONTROLLER_SETTINGS"):
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
    return problems(__getattr__("CONTROLLER_SETTINGS"), values, CONTROLLER_CONSTRAINTS)
