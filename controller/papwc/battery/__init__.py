"""Scenario batteries: named cases, parameter sweeps and Monte Carlo draws, run in parallel.

A battery file is a scenario file (see :mod:`papwc.scenario`) with up to four
more top-level tables. Every run of the battery is the scenario with some fields
replaced; a field is named by a dotted path:

- ``plant.F`` -- a ``[plant]`` field (``m``, ``f_c``, ``f_s``, ``c``, ``x_resolution``,
  the deviations ``v_s``, ``sigma_0``, ``ripple``, ``tau_u``, ``m_d``, ...);
- ``maneuver.F`` -- a ``[maneuver]`` field;
- ``controller.F`` -- field ``F`` of every ``[[controller]]`` table;
- ``controller.N.F`` -- field ``F`` of the N-th ``[[controller]]`` table (N from 1).

``[cases]``: named variants of the scenario. Each key is a case name (letters,
digits and ``_``), each value a table of path = value (a number or a string)
that the case sets; ``{}`` is the file's scenario itself::

    [cases]
    exact = {}
    stribeck = { "plant.v_s" = 1e-3 }
    lugre = { "plant.sigma_0" = 6.5e7, "plant.sigma_1" = 2e5, "plant.v_s" = 1e-3 }

Every case gets the whole grid and every draw. A field set by a case cannot
also be in ``[sweep]`` or ``[monte_carlo]`` (a draw may be a ratio ``of`` it).

``[sweep]``: a grid. Each key is a path, each value the list of values it takes;
the runs cover every combination (the first key varies slowest)::

    [sweep]
    "plant.f_c" = [80.0, 100.0, 120.0]
    "controller.t_p_max" = [0.03, inf]

``[monte_carlo]``: ``n`` draws (required, >= 1) from ``seed`` (integer >= 0,
default 0); every other key is a path with its distribution, an inline table::

    [monte_carlo]
    n = 200
    seed = 1
    "plant.m"   = { dist = "uniform", rel = 0.3 }            # nominal * U(0.7, 1.3)
    "plant.c"   = { dist = "uniform", abs = 50.0 }           # nominal + U(-50, 50)
    "plant.f_c" = { dist = "uniform", low = 70.0, high = 130.0 }
    "maneuver.x_ref" = { dist = "normal", std = 1e-3 }       # nominal + N(0, std^2)
    "controller.K_c" = { dist = "normal", rel_std = 0.05 }   # nominal * (1 + N(0, 0.05^2))
    "controller.1.tolerance" = { dist = "normal", mean = 2e-5, std = 5e-6 }
    # ratio to another field of the same run (after its own sweep and draw):
    "plant.f_s" = { dist = "uniform", low = 1.0, high = 1.6, of = "plant.f_c" }
    "controller.m_est" = { dist = "uniform", low = 0.8, high = 1.2, of = "plant.m" }

Distributions: ``uniform`` takes exactly one of ``rel`` (relative half-width),
``abs`` (absolute half-width) or ``low`` and ``high``; ``normal`` takes ``std``
(around the nominal value, or around ``mean`` if given) or ``rel_std``. The
nominal value is the field's value in the file at that case and grid point (its
default if the file leaves it out). With ``of = "plant.F"`` or ``"maneuver.F"`` the
drawn number is a factor applied to that field's value in the run, and only the
``low``/``high`` and ``mean``/``std`` forms are allowed. Such a ratio is the
way to keep a pair ordered, e.g. ``f_s >= f_c``: sampling ``f_s`` on its own
can give ``f_s < f_c``, which is an invalid plant. Ratios are resolved after
every other field. Only floating-point fields can be drawn (not ``plant.seed``,
``maneuver.iterations``, ``noise_seed``, ``timing`` or ``controller.rest_samples``).

Randomness: each field of draw ``d`` gets its own stream, seeded by ``seed``,
``d`` and the path (stdlib :class:`random.Random`, stable across Python
versions); a ``controller.F`` path uses one number for every table, and cases
and grid points reuse the same numbers (common random numbers). All runs are drawn up
front, so the results do not depend on the number of workers, the engine or the
order in which runs finish.

``[battery]``: options. ``success_tolerance`` (m, 0 to 1): the error band used
to call a run a success (default: each controller's own ``tolerance``).
``run_timeout`` (s, default 600, at most a week): the time limit of one run; a
run past it stops (between two communication steps) and is recorded with
status ``error`` and the message ``timed out: ...``; a local worker still busy
10 s later is killed and replaced (on Dask the limit is kept inside the run:
Dask cannot stop a task that does not return). ``--resume`` computes a timed
out run again. ``identify_first`` (true or false, default false): each run's table is
identified first -- the excitation of ``papwc identify --design`` applied to it through its
encoder, another seed for its random draws -- and its controllers are given the identified
plant in place of their told values (``m_est``, ``f_c_est``, ``c_est`` and the stiction
band, where their kind reads them; :mod:`.identify_first`); a table is identified once per
worker process, and ``identified.csv`` holds what was identified of each run's table beside
its own values, with the processor time it took.

Bounds, checked before any run: the runs of the batteries together and the
grid points of a sweep (``--max-runs``, default 100000), the communication
steps of each run (``--max-steps``, default 1e6); every ``[sweep]`` value is
checked against its field's range, and a battery all of whose runs are invalid
is refused.

Cases, a grid and draws combine: every case gets every grid point, every grid
point all ``n`` draws; the fields are set in that order (case, grid point,
draw, then the ratios). Each run has an id (``s<grid point>``, ``d<draw>``,
``s<grid point>-d<draw>``, or ``nominal``, preceded by ``<case>-`` with cases,
or the case name alone), a hash of its fully resolved parameters, and is
validated by
:func:`papwc.scenario.parse_scenario`; a run whose parameters are invalid (e.g. a
sweep value ``f_s < f_c``) is recorded with status ``error`` and the message.

Seed offset (``papwc battery --seed-offset N``, :attr:`Battery.seed_offset`): N is added to
the draws' ``seed`` and to each run's ``plant.seed`` and ``maneuver.noise_seed``, so the same
files are measured on tables and draws they were not tuned on; the offset is part of each
run's hash and of the journal's header (a resume with another offset is refused), and
spec.csv and summary.md show it. ``papwc spec TUNED OTHER`` sets the two batteries' spec.csv
side by side.

Outputs of :func:`run_battery` in the output folder:

- ``journal.jsonl`` -- one JSON line per finished run, flushed and fsync'ed as it
  finishes (a header line first); ``--resume`` reads it back and runs only what is
  missing. It is keyed by what determines the results (the plant FMU's GUID, a
  digest of its sources, and papwc's version and code), so a rebuilt FMU keeps
  the finished runs. A line that cannot be used (torn, not JSON, a record of
  the wrong shape or of other parameters) is skipped with a warning and its run
  computed again (see :mod:`papwc.battery.journal`). On Ctrl-C the runs that
  finished are in it and the message says how to resume.
  ``.papwc.lock`` (:func:`papwc.output_files.lock_folder`) keeps two commands from writing into
  one folder.
- ``results.csv`` -- one row per run, controller and iteration, in the order of
  the runs (battery, case, grid point, draw), controller and iteration: the
  case (a ``case`` column when a battery has cases), the varied fields (one
  column per path; a ``controller.F`` column holds the row's controller's value), the
  metrics of :func:`papwc.results.summary.summarize`, ``success``, ``status`` and
  ``message``; ``last_iteration`` marks each controller's final row.
- ``runs.csv`` -- one row per run with its status and every resolved parameter.
- ``pulses.csv`` -- every pulse of every run, controller and iteration: the run's
  battery, id, hash (and case), then the columns of ``papwc run``'s pulses.csv (its
  width, height, error, displacement, the table's band top, breakaway height and quantum,
  the bound ``max(1.5*abs(e) + q, quantum_m)`` and the ratio to it;
  :mod:`papwc.results.pulses`).
- ``spec.csv`` -- per battery, case and controller the figures of the spec and each
  requirement's verdict (:func:`papwc.battery.spec.spec_rows`; the targets are
  :data:`papwc.battery.spec.REQUIREMENTS`): within 1 um, one count, 1e-7 m and 20 um,
  settle median and p95, maneuvers that ended farther, false ``settled``, the pulses
  beyond their bound by error band and kind, ``time_ended``.
- ``summary.md`` -- per battery (and case) and controller: success rate, median,
  95th percentile and maximum of ``|final error|``, pulses and settle time, in the
  last iteration; then the spec table (``spec.csv``).
- ``identified.csv`` -- with ``[battery] identify_first``: per run, the identified plant,
  the stiction band, the deviations chosen and the identification's processor time
  (``cpu_s``), and the table's own values (``table.<name>``).
- ``final_error_<battery>.png`` -- distribution (empirical CDF) of ``|final error|``
  per controller on a log axis.

Its modules: :mod:`.schema` (the file), :mod:`.plan` (cases, grid and draws), :mod:`.worker`
(one run; :mod:`.identify_first` its table identified first), :mod:`.engines` (local
processes, Dask) and :mod:`.dask_cluster`, :mod:`.journal`,
:mod:`.report` (the files above) and :mod:`.orchestrate` (:func:`run_battery`: plan, journal,
engine, report).
"""

from papwc.battery.dask_cluster import local_dask_cluster
from papwc.battery.engines import default_workers
from papwc.battery.journal import JOURNAL_NAME, read_journal
from papwc.battery.orchestrate import BatteryOutcome, run_battery
from papwc.battery.plan import RunSpec, get_field, plan_runs
from papwc.battery.report import METRICS, result_rows, summary_markdown, write_outputs
from papwc.battery.schema import Battery, Distribution, load_battery, parse_battery
from papwc.battery.worker import execute_run
from papwc.errors import BatteryError

__all__ = [
    "JOURNAL_NAME",
    "METRICS",
    "Battery",
    "BatteryError",
    "BatteryOutcome",
    "Distribution",
    "RunSpec",
    "default_workers",
    "execute_run",
    "get_field",
    "load_battery",
    "local_dask_cluster",
    "parse_battery",
    "plan_runs",
    "read_journal",
    "result_rows",
    "run_battery",
    "summary_markdown",
    "write_outputs",
]
