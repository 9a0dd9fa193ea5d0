"""papwc: precise positioning of machines with friction by adaptive pulse control.

Imported as ``papwc`` (the source folder is ``controller/``). Its parts, one job each:

- ``papwc.core``: the control laws and estimators (standard library only, so
  they can be bundled into an FMU);
- ``papwc.master``: the co-simulation master that steps an FMU at period T;
- ``papwc.recording``: what a run records and writes;
- ``papwc.scenario``: scenario files (TOML) and their validation;
- ``papwc.cli`` and ``papwc.commands``: the ``papwc`` command line.
"""

__version__ = "0.1.0"
