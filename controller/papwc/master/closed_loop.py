"""Closed-loop runs: a plant and a controller, a maneuver repeated over iterations.

:func:`run_closed_loop` assembles an :class:`~papwc.master.execution.Execution`
of two slaves, the controller and the plant (any of FrictionPlant.fmu, the
in-process physics, a Python controller, PulseController.fmu), connected
``plant.x_meas -> controller.x_meas`` and ``controller.u -> plant.u``, with the
maneuver's measurement noise as a manipulator and a trace observer. Timing
(see :mod:`papwc.master.algorithm`):

- ``"immediate"`` (default): at t_k the controller reads the plant and the
  plant gets u_k over [t_k, t_k+1];
- ``"delayed"``: what a master that steps plant and controller side by side
  does (libcosim, an SSP run): the plant gets u_(k-1) over [t_k, t_k+1]
  (u_(-1) = 0).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from papwc.controllers import CONTROLLER_KINDS, Controller, make_controller
from papwc.controllers.settings import ControllerSettings
from papwc.errors import FmuError
from papwc.interrupts import Terminated
from papwc.master.algorithm import FixedStepAlgorithm
from papwc.master.execution import Execution
from papwc.master.manipulators import MeasurementNoise
from papwc.master.observers import Observer, TraceObserver
from papwc.master.slave import ControllerSlave, Slave
from papwc.master.trace import Trace
from papwc.model.maneuver import MANEUVER_DEFAULTS, TIMINGS

__all__ = [
    "TIMINGS",
    "Maneuver",
    "RunResult",
    "run_closed_loop",
    "run_controller",
    "run_iteration",
]


@dataclass
class Maneuver:
    """A rest-to-rest maneuver: from rest at x0 = 0 to ``x_ref`` (m) at period ``T`` (s).

    The fields and their defaults are those of :data:`papwc.model.maneuver.MANEUVER_VARIABLES`
    (a scenario's ``[maneuver]`` table).

    Parameters
    ----------
    x_ref : float
        Reference (target) position, m; the mass starts at rest at 0.
    T : float
        Sample period, s.
    duration : float
        Duration of one iteration, s, a whole number of samples.
    iterations : int
        Repetitions of the maneuver; what the controller learned carries over.
    timing : {"immediate", "delayed"}
        When the force computed at t_k acts: over [t_k, t_k+1], or one sample later (as a
        master stepping plant and controller side by side).
    noise_std : float
        Standard deviation of measurement noise added to ``x_meas``, m.
    noise_seed : int
        Seed of the measurement noise.

    Examples
    --------
    >>> maneuver = Maneuver(x_ref=1e-3, duration=0.5)
    >>> maneuver.T, maneuver.n_steps, maneuver.iterations
    (0.01, 50, 10)
    """

    x_ref: float = MANEUVER_DEFAULTS["x_ref"]
    T: float = MANEUVER_DEFAULTS["T"]
    duration: float = MANEUVER_DEFAULTS["duration"]
    iterations: int = MANEUVER_DEFAULTS["iterations"]
    timing: str = MANEUVER_DEFAULTS["timing"]
    noise_std: float = MANEUVER_DEFAULTS["noise_std"]
    noise_seed: int = MANEUVER_DEFAULTS["noise_seed"]

    @property
    def n_steps(self) -> int:
        """Samples per iteration, ``round(duration / T)``."""
        return int(round(self.duration / self.T))


@dataclass
class RunResult:
    """What :func:`run_closed_loop` returns: the traces of all iterations of one controller.

    Parameters
    ----------
    label : str
        The controller's name in results.
    settings : ControllerSettings
        Its settings.
    traces : list of Trace
        One per iteration run, in order.
    error : str
        Why the run stopped early (``"iteration N: ..."``), or empty.
    """

    label: str
    settings: ControllerSettings
    traces: list[Trace] = field(default_factory=list)
    error: str = ""


class ClosedLoop:
    """A plant and a controller slave in one execution, for a maneuver.

    Parameters
    ----------
    plant : Slave
        The plant, its parameters already given as start values.
    controller : Slave
        The controller: inputs ``x_meas``, ``x_ref``; outputs ``u``, ``mode``,
        ``pulses``, ``b_hat``, ``f_c_hat``.
    maneuver : Maneuver
        Reference, period, duration, timing and measurement noise.
    label : str
        Name of the controller in the traces.
    motor_encoder : bool
        Connect ``plant.x_d_meas -> controller.x_d_meas`` too (a controller that reads the
        motor encoder).
    observers : sequence of Observer
        Further observers, told after the trace observer (e.g. a
        :class:`~papwc.master.observers.StepGuard`, which may stop the run between
        two steps by raising).
    """

    def __init__(self, plant: Slave, controller: Slave, maneuver: Maneuver,
                 label: str = "", motor_encoder: bool = False,
                 observers: Sequence[Observer] = ()) -> None:
        self.maneuver = maneuver
        self.plant = plant
        self.controller = controller
        execution = Execution(FixedStepAlgorithm(maneuver.T, maneuver.timing))
        execution.add_slave(controller)
        execution.add_slave(plant)
        execution.connect(plant, "x_meas", controller, "x_meas")
        execution.connect(controller, "u", plant, "u")
        if motor_encoder:
            execution.connect(plant, "x_d_meas", controller, "x_d_meas")
        controller.set_start_values({"x_ref": maneuver.x_ref})
        self.noise = None
        if maneuver.noise_std > 0.0:
            self.noise = MeasurementNoise(plant, "x_meas", maneuver.noise_std,
                                          maneuver.noise_seed)
            execution.add_manipulator(self.noise)
        self.observer = TraceObserver(plant, controller, label, 1, maneuver.T, maneuver.x_ref)
        execution.add_observer(self.observer)
        for observer in observers:
            execution.add_observer(observer)
        self.execution = execution

    def iteration(self, number: int, first: bool | None = None) -> Trace:
        """Run one iteration: initialize (the first) or restart, then every sample.

        Parameters
        ----------
        number : int
            Iteration number (from 1): names the trace and seeds the noise.
        first : bool, optional
            Initialize the slaves (default: ``number == 1``); otherwise restart them.

        Returns
        -------
        Trace
            A failure of a slave ends it early with ``trace.error`` set and every
            sample before it kept (no sample if the (re)initialization failed).
        """
        self.observer.new_trace(number)
        if self.noise is not None:
            self.noise.iteration = number
        trace = self.observer.trace
        try:
            if number == 1 if first is None else first:
                self.execution.initialize()
            else:
                self.execution.restart()
        except FmuError as exc:
            trace.error = str(exc)
            trace.columns = {name: [] for name in trace.columns}
            return trace
        try:
            self.execution.step(self.maneuver.n_steps)
        except FmuError as exc:
            trace.error = str(exc)
            return trace
        self.execution.finish()
        return trace


def run_closed_loop(plant: Slave, controller: Slave, maneuver: Maneuver,
                    settings: ControllerSettings | None = None, label: str = "",
                    observers: Sequence[Observer] = (),
                    stopped: Callable[[RunResult], None] | None = None) -> RunResult:
    """Run all iterations of the maneuver; what the controller learns carries over.

    The first iteration initializes both slaves, later ones restart them (the plant from
    its initial state, the controller keeping its estimates).

    Parameters
    ----------
    plant : Slave
        The plant (FrictionPlant.fmu as an :class:`~papwc.master.fmu.FmuSlave`, or the
        in-process :class:`~papwc.master.slave.PhysicsSlave`), its parameters already given
        as start values.
    controller : Slave
        The controller: a :class:`~papwc.master.slave.ControllerSlave` of a Python
        controller, or PulseController.fmu as an ``FmuSlave``.
    maneuver : Maneuver
        Reference, period, duration, iterations, timing and measurement noise.
    settings : ControllerSettings, optional
        The controller's settings, kept in the result (default: the default settings).
    label : str
        The controller's name in the traces (default: its kind).
    observers : sequence of Observer
        Further observers of the execution (see :class:`ClosedLoop`); what they raise ends
        the run.
    stopped : callable, optional
        When Ctrl-C or SIGTERM (a KeyboardInterrupt, raised between two steps) stops the
        run, called first with what was computed: the finished iterations' traces and the
        cut one (its ``error`` saying where it was cut), ``result.error`` set; the
        KeyboardInterrupt then goes on.

    Returns
    -------
    RunResult
        A trace per iteration. A failure stops the run and is kept in ``result.error``
        (``"iteration N: ..."``); the traces recorded until then are kept.

    Examples
    --------
    >>> from papwc.controllers import make_controller
    >>> from papwc.controllers.settings import ControllerSettings
    >>> from papwc.master.slave import ControllerSlave, PhysicsSlave
    >>> settings = ControllerSettings(kind="papwc", t_p_max=0.03, K_c=0.8, tolerance=2e-5)
    >>> maneuver = Maneuver(x_ref=0.01, iterations=2)
    >>> controller = ControllerSlave(make_controller(settings, maneuver.T))
    >>> result = run_closed_loop(PhysicsSlave(), controller, maneuver, settings)
    >>> len(result.traces), result.error
    (2, '')
    >>> abs(0.01 - result.traces[-1].column("x")[-1]) <= 2e-5
    True
    """
    settings = settings if settings is not None else ControllerSettings()
    result = RunResult(label or settings.kind, settings)
    kind = CONTROLLER_KINDS.get(settings.kind)
    loop = ClosedLoop(plant, controller, maneuver, result.label,
                      motor_encoder=kind is not None and kind.reads_x_d_meas,
                      observers=observers)
    for number in range(1, maneuver.iterations + 1):
        try:
            trace = loop.iteration(number)
        except KeyboardInterrupt as stop:
            if stopped is not None:
                cut = loop.observer.cut()
                what = ("terminated (SIGTERM)" if isinstance(stop, Terminated)
                        else "interrupted (Ctrl-C)")
                t = cut.columns["t"][-1] if len(cut) else 0.0
                cut.error = f"cut short at t = {t!r} s: {what}"
                if len(cut):
                    result.traces.append(cut)
                result.error = f"iteration {number}: {cut.error}"
                stopped(result)
            raise
        if trace.error and not len(trace):
            result.error = f"iteration {number}: {trace.error}"
            return result
        result.traces.append(trace)
        if trace.error:
            result.error = f"iteration {number}: {trace.error}"
            return result
    return result


def run_controller(plant: Slave, settings: ControllerSettings, maneuver: Maneuver,
                   label: str = "", observers: Sequence[Observer] = (),
                   library=None,
                   stopped: Callable[[RunResult], None] | None = None) -> RunResult:
    """Run the controller of ``settings`` against ``plant``, over every iteration.

    Parameters
    ----------
    plant : Slave
        The plant, its parameters already given as start values.
    settings : ControllerSettings
        The controller's settings (one ``[[controller]]`` table); the controller is made
        from them by the registry.
    maneuver : Maneuver
        The maneuver.
    label : str
        The controller's name in the traces (default: its kind).
    observers : sequence of Observer
        Further observers (see :func:`run_closed_loop`).
    library : NativeControllerLibrary, optional
        The C controller (:class:`papwc.master.native_controller.NativeControllerLibrary`):
        used for a kind it implements, the Python controller otherwise; the same numbers
        either way. Default: the Python controller.
    stopped : callable, optional
        Given what was computed when Ctrl-C or SIGTERM stops the run (see
        :func:`run_closed_loop`).

    Returns
    -------
    RunResult
        As :func:`run_closed_loop`.

    Examples
    --------
    The exact-model controller on Table 1's plant with a 1 µm encoder:

    >>> from papwc.controllers.settings import ControllerSettings
    >>> from papwc.master.slave import PhysicsSlave
    >>> plant = PhysicsSlave()
    >>> plant.set_start_values({"x_resolution": 1e-6})
    >>> settings = ControllerSettings(kind="exact", tolerance=5e-7, x_resolution=1e-6)
    >>> result = run_controller(plant, settings, Maneuver(x_ref=0.01, iterations=2))
    >>> trace = result.traces[-1]
    >>> int(trace.column("pulses")[-1]), abs(0.01 - trace.column("x_meas")[-1]) <= 5e-7
    (5, True)
    """
    if library is None:
        controller = ControllerSlave(make_controller(settings, maneuver.T))
    else:
        from papwc.master.native_controller import controller_slave

        controller = controller_slave(settings, maneuver.T, library)
    return run_closed_loop(plant, controller, maneuver, settings, label, observers, stopped)


def run_iteration(plant: Slave, controller: Controller | Slave, maneuver: Maneuver,
                  label: str = "", iteration: int = 0) -> Trace:
    """One iteration from the plant's initial state (both slaves are initialized here).

    Parameters
    ----------
    plant : Slave
        The plant, its parameters already given as start values.
    controller : Controller or Slave
        A Python controller, or a controller slave.
    maneuver : Maneuver
        The maneuver (its ``iterations`` is not read).
    label : str
        The controller's name in the trace.
    iteration : int
        Names the trace and seeds the noise.

    Returns
    -------
    Trace
        Every sample; ``trace.error`` is set if a step failed.
    """
    slave = controller if hasattr(controller, "watch") else ControllerSlave(controller)
    motor = getattr(getattr(slave, "controller", None), "reads_x_d_meas", False)
    loop = ClosedLoop(plant, slave, maneuver, label, motor_encoder=motor)
    return loop.iteration(iteration, first=True)
