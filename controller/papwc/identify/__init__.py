"""Identification of the friction plant from a measured log (``papwc identify``).

A log of a machine (time, force held over each sample, table position) is read and checked
(:mod:`.log_file`); the motion in it is told apart from the rests and the encoder's count and
noise are estimated (:mod:`.motion`); ``m``, ``f_c``, ``c`` are started by linear regression on
the sliding samples, then refined by output error on the moves from rest, simulated through
the model layer's plant (:mod:`.simulate`) with the force replayed, and the deviations the
data support are added -- the Stribeck curve, the actuator lag and the friction ripple, whose
wavelength is searched (:mod:`.ripple`) -- with the stiction band of the breakaways
(:mod:`.band`) (:mod:`.fit`). :mod:`.excitation` designs the force to apply to a machine and
applies it to a plant or an FMU; :mod:`.fit_report` writes ``plant.toml`` (with the
``[identified]`` table of :mod:`.plant_model`, which ``papwc run --plant-model`` and the
battery's ``identify_first`` give the controllers), ``identified.csv``, ``report.md`` and its
figures.

Examples
--------
The excitation's defaults, which ``papwc identify --design`` and ``--fmu`` use:

>>> from papwc.identify import DESIGN_DURATION, DESIGN_F_P_MAX, DESIGN_T, DESIGN_TRAVEL
>>> DESIGN_T, DESIGN_F_P_MAX, DESIGN_TRAVEL, DESIGN_DURATION
(0.01, 300.0, 0.05, 60.0)

From a log to a plant in Python: :func:`papwc.identify.log_file.read_log`, then
:func:`papwc.identify.fit.identify` (its example runs the whole path); from the command
line, ``papwc identify machine.csv --out id/``.
"""

from papwc.errors import PapwcError
from papwc.model.maneuver import LOG_SAMPLE_PERIOD

__all__ = ["DESIGN_DURATION", "DESIGN_F_P_MAX", "DESIGN_T", "DESIGN_TRAVEL", "IdentifyError",
           "require_scipy"]

#: The excitation's defaults (``papwc identify --design``): sample period, s; largest force,
#: N; the travel the table stays within, m; length, s.
DESIGN_T = LOG_SAMPLE_PERIOD.default
DESIGN_F_P_MAX = 300.0
DESIGN_TRAVEL = 0.05
DESIGN_DURATION = 60.0


class IdentifyError(PapwcError):
    """A log, an option or an FMU cannot be identified: the message says where and why."""


def require_scipy(what: str) -> None:
    """Refuse in one line (:class:`IdentifyError`) where scipy, whose least squares the fit
    uses, is not installed: papwc installs it with its extra ``identify``.

    Parameters
    ----------
    what : str
        What needs it, for the message (``"papwc identify"``).
    """
    try:
        import scipy  # noqa: F401
    except ImportError:
        raise IdentifyError(f"{what} needs scipy, which is not installed: pip install "
                            "'papwc[identify]' (papwc's extra for identification)") from None
