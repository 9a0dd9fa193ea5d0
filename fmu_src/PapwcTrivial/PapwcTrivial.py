"""PapwcTrivial: one Real input copied to one Real output, the floor of ``papwc bench``.

It goes through the same pythonfmu machinery as ``FrictionPlant`` with no physics,
so the cost of one ``setReal + doStep + getReal`` on it is the cost of the FMI
wrapper alone.
"""

from __future__ import annotations

from typing import Any

from pythonfmu import (
    DefaultExperiment,
    Fmi2Causality,
    Fmi2Initial,
    Fmi2Slave,
    Fmi2Variability,
    Real,
)


class PapwcTrivial(Fmi2Slave):
    """Copies the input ``u`` to the output ``y`` at every step (unit-less)."""

    author = "papwc"
    license = "BSD-2-Clause"
    description = "One Real input copied to one Real output at every step (benchmark floor)"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.0, step_size=0.01)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(
            Real(
                "u",
                causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous,
                description="Input value",
            )
        )
        self.register_variable(
            Real(
                "y",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.continuous,
                initial=Fmi2Initial.exact,
                description="Output value: the input at the last step",
            )
        )

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Copy ``u`` to ``y``; always succeeds."""
        self.y = self.u
        return True
