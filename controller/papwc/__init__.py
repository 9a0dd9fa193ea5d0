"""papwc: precise positioning of machines with friction by adaptive pulse control.

Imported as ``papwc`` (the source folder is ``controller/``). Its layers, each importing
only those above it in this list:

- ``papwc.model``: the model layer, standard library only: the plant's physics, the pulse
  model, and every parameter's, setting's and signal's name, unit, default and range;
- ``papwc.controllers``: the controllers from parts (standard library only, bundled into
  PulseController.fmu); ``papwc.fmi``: the FMI glue bundled into the pythonfmu FMUs;
- ``papwc.master``: the co-simulation master (slaves, algorithm, observers, manipulators,
  closed-loop runs, SSPs);
- ``papwc.results``: what runs produce (metrics, pulses, the results folder, plots);
- ``papwc.scenario`` and ``papwc.scenario_run``: scenario files and running them;
  ``papwc.battery``: batteries of runs; ``papwc.identify``: fitting the plant to a log;
  ``papwc.analysis``: the paper reproduced; ``papwc.fmubuild``: building the FMUs and the SSP;
  ``papwc.bench``: ``papwc bench``'s sections;
- ``papwc.cli`` and ``papwc.commands``: the ``papwc`` command line.

Beside them: ``papwc.errors``, ``papwc.output_files`` (files written whole or not at all),
``papwc.interrupts`` (Ctrl-C between steps), ``papwc.exit_status``, ``papwc.limits``,
``papwc.resources``, ``papwc.host_environment``.

The version is written here once; pyproject.toml and the FMUs' model descriptions read it.
"""

__version__ = "0.1.0"
