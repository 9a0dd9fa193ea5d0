"""Exceptions of the project: each says what is wrong, where, and what is allowed."""


class PapwcError(Exception):
    """Base class of the errors the command line reports without a traceback."""


class ScenarioError(PapwcError, ValueError):
    """A scenario or battery file is invalid; the message names the file and the field."""


class FmuError(PapwcError, RuntimeError):
    """An FMU returned Discard, Error or Fatal; the message names the time and the call."""


class BuildError(PapwcError, RuntimeError):
    """An FMU or SSP could not be built."""


class BatteryError(PapwcError):
    """A battery cannot run: its output folder, journal, FMU or cluster is not usable."""


class SspError(PapwcError, ValueError):
    """An SSP archive cannot be run; the message names the archive and the SSD element."""


class OutputError(PapwcError, OSError):
    """A result could not be written (a read-only or full disk, a file in the way).

    The message names the path and the operation; what was written before stays.
    The command line exits with code 1 (a failure while running, not bad input).
    """

    exit_code = 1
