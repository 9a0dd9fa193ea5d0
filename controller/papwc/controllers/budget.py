"""The work one update of the exact-model controller may do, counted in operations.

An update must end within half the sample period (T/2 = 5 ms at 100 Hz, in Python as it
ships). The exact-model controller's planning is bounded by design: every search it makes
has a fixed number of steps, and what can wait (the refit of Eq. (3) after a pulse) waits.
Its work is counted in *operations*, units of about the same cost:

* one evaluation of Eq. (3) (:func:`papwc.model.pulse.pulse_displacement`: the fit's
  residuals, a plan's searches, the correction by earlier pulses) counts 1;
* one evaluation of the likelihood of the breakaway evidence's move curve
  (:meth:`papwc.controllers.breakaway.BreakawayEvidence.fit`) counts
  :data:`LIKELIHOOD_OPS` (it costs about twice an Eq. (3) evaluation).

:class:`Ops` counts them over one update against :data:`UPDATE_OPS`. The refit of Eq. (3)
(a Levenberg-Marquardt iteration at a time, :meth:`~papwc.controllers.exact_fit.
PulseModelEstimator.advance`) takes what the update has left after the plan's reserve
(:data:`PLAN_RESERVE`); what it cannot do goes on at the next updates (the table coasts and
settles after every pulse: the readings say when the next plan is due), and a plan made
meanwhile uses the last completed fit, with the correction through every pulse measured.

Standard library only (bundled into the controller FMU).
"""

from __future__ import annotations

__all__ = ["HISTORY_MAX", "LIKELIHOOD_OPS", "PLAN_RESERVE", "UPDATE_OPS", "Ops"]

#: Operations one update may make: measured on this project's machine at about 1.3 us an
#: Eq. (3) evaluation (the figures of ``python -m papwc_studies.update_time``), well within
#: T/2 = 5 ms at T = 10 ms.
UPDATE_OPS = 1800
#: Operations kept for the plan when the refit runs before it (in the update that learns a
#: pulse): the most a plan makes (the evidence's curves and the searches of the height).
PLAN_RESERVE = 700
#: Operations one likelihood evaluation of the breakaway evidence counts.
LIKELIHOOD_OPS = 2
#: Most pulses the fit of Eq. (3) keeps (the ``history`` setting's maximum): a step of the
#: fit, 21 evaluations of Eq. (3) per pulse (:meth:`~papwc.controllers.exact_fit.
#: PulseModelEstimator.lm_cost`), must fit an update's budget beside the plan's reserve.
HISTORY_MAX = (UPDATE_OPS - PLAN_RESERVE) // 21


class Ops:
    """Operations made in the present update (see the module).

    Attributes
    ----------
    eq3 : int
        Evaluations of Eq. (3).
    likelihood : int
        Evaluations of the breakaway evidence's likelihood.
    limit : int
        Operations one update may make (:data:`UPDATE_OPS`).
    """

    __slots__ = ("eq3", "likelihood", "limit", "in_update")

    def __init__(self, limit: int = UPDATE_OPS) -> None:
        self.limit = int(limit)
        self.eq3 = 0
        self.likelihood = 0
        #: Whether an update is under way (:meth:`reset` until :meth:`end`): outside one (a
        #: law's methods called directly) nothing waits for a later update.
        self.in_update = False

    def reset(self) -> None:
        """A new update: nothing made yet."""
        self.eq3 = 0
        self.likelihood = 0
        self.in_update = True

    def end(self) -> None:
        """The update is over (the counts stay readable until the next :meth:`reset`)."""
        self.in_update = False

    def total(self) -> int:
        """Operations made in this update."""
        return self.eq3 + LIKELIHOOD_OPS * self.likelihood

    def left(self) -> int:
        """Operations this update may still make (negative: over the limit); outside an
        update, as many as asked."""
        if not self.in_update:
            return 1 << 62
        return self.limit - self.total()
