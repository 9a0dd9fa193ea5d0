"""The co-simulation master, built from parts as libcosim's is.

- :mod:`.slave`: the :class:`~.slave.Slave` interface; the in-process plant
  (:class:`~.slave.PhysicsSlave`) and Python controller
  (:class:`~.slave.ControllerSlave`);
- :mod:`.fmu`: any FMI 2.0 Co-Simulation FMU (:class:`~.fmu.FmuSlave`);
- :mod:`.algorithm`: stepping over connections, immediate or delayed;
- :mod:`.observers` and :mod:`.trace`: recording (named columns; the metrics read off a
  trace are :mod:`papwc.results`), and the step guard that stops a run between two steps;
- :mod:`.manipulators`: what changes between slaves (measurement noise);
- :mod:`.execution`: the parts assembled;
- :mod:`.closed_loop`: closed-loop runs of a maneuver over iterations;
- :mod:`.ssd` and :mod:`.ssp_runner`: reading and running an SSP;
- :mod:`.archive`: opening FMU and SSP archives (bounded unpack);
- :mod:`.native_plant`: a native FrictionPlant's C plant, called in process.
"""

from papwc.master.algorithm import TIMINGS, Connection, FixedStepAlgorithm
from papwc.master.closed_loop import (
    ClosedLoop,
    Maneuver,
    RunResult,
    run_closed_loop,
    run_controller,
    run_iteration,
)
from papwc.master.execution import Execution
from papwc.master.fmu import FmuSlave
from papwc.master.manipulators import MeasurementNoise
from papwc.master.observers import StepGuard, TraceObserver
from papwc.master.slave import ControllerSlave, PhysicsSlave, SignalSlave, Slave
from papwc.master.trace import TRACE_COLUMNS, Trace

__all__ = [
    "TIMINGS",
    "TRACE_COLUMNS",
    "ClosedLoop",
    "Connection",
    "ControllerSlave",
    "Execution",
    "FixedStepAlgorithm",
    "FmuSlave",
    "Maneuver",
    "MeasurementNoise",
    "PhysicsSlave",
    "RunResult",
    "SignalSlave",
    "Slave",
    "StepGuard",
    "Trace",
    "TraceObserver",
    "run_closed_loop",
    "run_controller",
    "run_iteration",
]
