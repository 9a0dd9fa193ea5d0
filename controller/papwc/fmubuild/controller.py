"""Build ``PulseController.fmu``: the project's pulse controllers as an FMI 2.0 CS FMU.

The FMU runs the same code as the Python master: the package ``papwc.core``
(``controller/core/``, standard library only, relative imports) is copied at
build time as ``papwc_pulse_core/`` beside the model script
``fmu_src/PulseController/PulseController.py`` and bundled by pythonfmu into
``resources/``. pythonfmu FMUs import their bundled modules by name into the one
Python interpreter of the process, so the name differs from every module the
plant FMU bundles (``FrictionPlant``, ``papwc_stickslip``) and from the
project's own ``papwc``: both FMUs, and the project itself, load in one process.

After pythonfmu, the model description is completed: units
(:func:`papwc.build.model_description.add_units`), ``InitialUnknowns`` for the
outputs computed from the parameters (``b_hat``, ``f_c_hat``), and the XML
spelling ``INF`` of an infinite start value. The FMU is then checked with
``fmpy.validation.validate_fmu``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import papwc.core
from papwc.build.fmus import build_pythonfmu
from papwc.errors import BuildError
from papwc.fmu_src import FMU_SRC_DIR

__all__ = [
    "CONTROLLER_CORE_DIR",
    "CORE_PACKAGE",
    "PULSE_CONTROLLER_OPTIONS",
    "PULSE_CONTROLLER_UNITS",
    "build_pulse_controller",
]

#: The controller package bundled into the FMU (``papwc.core``).
CONTROLLER_CORE_DIR = Path(papwc.core.__file__).resolve().parent

#: Name of the bundled copy of ``papwc.core`` inside the FMU.
CORE_PACKAGE = "papwc_pulse_core"

#: Unit of every Real variable of PulseController.fmu.
PULSE_CONTROLLER_UNITS: dict[str, str] = {
    "f_p_max": "N",
    "t_p_max": "s",
    "K_c": "1",
    "tolerance": "m",
    "m_est": "kg",
    "f_c_est": "N",
    "f_p_min": "N",
    "floor_raise": "1",
    "F_inv0": "s4",
    "lambda_1": "1",
    "lambda_2": "1",
    "delta_inv": "1",
    "lambda": "1",
    "e_band": "m",
    "rest_band": "m",
    "k_p": "N/m",
    "k_d": "N.s/m",
    "T": "s",
    "x_meas": "m",
    "x_ref": "m",
    "u": "N",
    "b_hat": "m/s2",
    "f_c_hat": "N",
}

#: Units beyond :data:`papwc.build.model_description.UNIT_DEFINITIONS`.
PULSE_CONTROLLER_UNIT_DEFINITIONS: dict[str, dict[str, int]] = {
    "N/m": {"kg": 1, "s": -2},
    "s4": {"s": 4},
}

#: CoSimulation capability flags: fixed communication step T, full state handling.
PULSE_CONTROLLER_OPTIONS: dict[str, bool] = {
    "canHandleVariableCommunicationStepSize": False,
    "canGetAndSetFMUstate": True,
    "canSerializeFMUstate": True,
}

#: Outputs whose initial value is computed from the parameters.
_CALCULATED_OUTPUTS = ("b_hat", "f_c_hat")

def _complete_model_description(root: ET.Element) -> None:
    """Add ``InitialUnknowns`` for the calculated outputs; write infinite starts as ``INF``."""
    variables = list(root.iter("ScalarVariable"))
    for sv in variables:
        for typed in sv:
            start = typed.get("start")
            if start in ("inf", "-inf", "nan"):
                typed.set("start", {"inf": "INF", "-inf": "-INF", "nan": "NaN"}[start])
    index = {sv.get("name"): i + 1 for i, sv in enumerate(variables)}
    structure = root.find("ModelStructure")
    if structure is None:
        raise BuildError("PulseController.fmu: the model description has no <ModelStructure>")
    outputs = structure.find("Outputs")
    if outputs is None:
        raise BuildError("PulseController.fmu: the model description lists no outputs")
    old = structure.find("InitialUnknowns")
    if old is not None:
        structure.remove(old)
    unknowns = ET.Element("InitialUnknowns")
    for position in sorted(index[name] for name in _CALCULATED_OUTPUTS):
        ET.SubElement(unknowns, "Unknown", index=str(position))
    # Order of <ModelStructure>: Outputs, Derivatives, InitialUnknowns.
    structure.append(unknowns)


def build_pulse_controller(out_dir: Path) -> Path:
    """Build ``PulseController.fmu`` (adaptive PWC/PAPWC controller) into ``out_dir``.

    Bundles ``controller/core/`` as the package ``papwc_pulse_core`` and
    ``fmu_src/PulseController/readme.md`` as documentation; the FMU supports
    getFMUstate/setFMUstate and serialization and requires the communication
    step to be the sample period ``T``.

    Parameters
    ----------
    out_dir : Path
        Output folder, created if needed; an existing ``PulseController.fmu``
        there is replaced.

    Returns
    -------
    Path
        ``out_dir / "PulseController.fmu"``.

    Raises
    ------
    BuildError
        If a source is missing, pythonfmu fails, the model description cannot
        be completed, or ``fmpy`` reports a validation problem.
    """
    model_dir = FMU_SRC_DIR / "PulseController"
    script = model_dir / "PulseController.py"
    return build_pythonfmu(
        script,
        out_dir,
        project_files=[(CONTROLLER_CORE_DIR, CORE_PACKAGE)],
        units=PULSE_CONTROLLER_UNITS,
        unit_definitions=PULSE_CONTROLLER_UNIT_DEFINITIONS,
        documentation=[model_dir / "readme.md"],
        default_experiment=(0.0, 1.0, 0.01),
        options=PULSE_CONTROLLER_OPTIONS,
        edit=_complete_model_description,
        shadowed_modules=(script.stem, CORE_PACKAGE),
    )
