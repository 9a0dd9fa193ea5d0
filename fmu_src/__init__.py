"""Sources of the project's FMUs: one folder per model, the shared physics beside them.

``papwc_stickslip`` is the stick-slip physics, bundled into ``FrictionPlant.fmu``
and imported by the rest of the project as ``papwc.fmu_src.papwc_stickslip``.
"""

from pathlib import Path

#: Folder holding the FMU sources (one sub-folder per model).
FMU_SRC_DIR = Path(__file__).resolve().parent
