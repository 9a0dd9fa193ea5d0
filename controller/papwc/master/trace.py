"""What one iteration of a closed loop recorded (:class:`Trace`) and its metrics.

A trace holds named columns, one value per sample t_k = k*T (SI units); the
plant's are its Real outputs (:data:`PLANT_COLUMNS`, from the model layer's
``PLANT_OUTPUTS``: a new Real output of the plant is a new column):

============ ============================================================================
``k``        sample number
``t``        time t_k, s
``x``        position at t_k, m
``v``        velocity at t_k, m/s
``x_meas``   position the controller saw at t_k (encoder, noise), m
``x_d``      motor (drive) position at t_k, m (``x`` on a rigid drive; NaN: the plant has
             none)
``x_d_meas`` the motor encoder's reading at t_k, m (NaN: the plant has none)
``u``        force applied over [t_k, t_k+1], N (NaN in the last row)
``e``        error x_ref - x, m
(then)       the controller's outputs after its sample at t_k, the model layer's
             ``CONTROLLER_OUTPUTS`` but ``u`` (:data:`papwc.controllers.OUTPUT_NAMES`):
             ``b_hat``, ``f_c_hat`` (m/s**2, N), ``pulses`` started so far, ``mode``
             (papwc.controllers.Mode), ``f_low`` (N), ``outcome``, ``outcome_reason``
             (:data:`papwc.model.controller_settings.OUTCOMES`, ``OUTCOME_REASONS``)
============ ============================================================================

The last row is the state at the end of the iteration.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass, field
from typing import Any

from papwc.controllers import OUTPUT_NAMES
from papwc.model.plant import PLANT_OUTPUTS
from papwc.output_files import atomic_open, format_value

__all__ = ["PLANT_COLUMNS", "REQUIRED_PLANT_COLUMNS", "TRACE_COLUMNS", "Trace"]

#: Columns read from the plant at t_k: its Real outputs, in the model layer's order.
PLANT_COLUMNS = tuple(var.name for var in PLANT_OUTPUTS if var.type == "Real")
#: The plant columns every plant must have (the others are NaN for a plant without them,
#: e.g. another tool's FMU).
REQUIRED_PLANT_COLUMNS = ("x", "v", "x_meas")
#: Columns of a trace, in the order of its CSV file.
TRACE_COLUMNS = ("k", "t") + PLANT_COLUMNS + ("u", "e") + OUTPUT_NAMES


@dataclass
class Trace:
    """Samples of one iteration, by column name.

    Attributes
    ----------
    controller : str
        Label of the controller.
    iteration : int
        Iteration number (from 1).
    T : float
        Sample period, s.
    x_ref : float
        Reference position, m.
    columns : dict of str to list
        The samples, one list per name of :data:`TRACE_COLUMNS`.
    error : str
        Why the iteration stopped early ("" if it ran to the end).
    """

    controller: str
    iteration: int
    T: float
    x_ref: float
    columns: dict[str, list[Any]] = field(
        default_factory=lambda: {name: [] for name in TRACE_COLUMNS}
    )
    error: str = ""

    def __len__(self) -> int:
        return len(self.columns["k"])

    def column(self, name: str) -> list[Any]:
        """The samples of column ``name`` as a list."""
        return self.columns[name]

    def __getitem__(self, name: str):
        """The samples of column ``name`` as a numpy array."""
        import numpy as np

        return np.asarray(self.columns[name])

    def row(self, i: int) -> dict[str, Any]:
        """Sample ``i`` (negative counts from the end) as a dict by column name."""
        return {name: values[i] for name, values in self.columns.items()}

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write the trace as CSV (floats in full precision), columns as :data:`TRACE_COLUMNS`."""
        cols = [self.columns[name] for name in TRACE_COLUMNS]
        with atomic_open(path, newline="") as f:
            w = csv.writer(f)
            w.writerow(TRACE_COLUMNS)
            for row in zip(*cols, strict=True):
                w.writerow([format_value(v) for v in row])
