"""FrictionPlant.fmu against its reference result in the FMI cross-check layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from fmpy import simulate_fmu
from fmpy.util import read_csv, read_ref_opt_file, validate_result

from papwc.fmubuild.reference import write_reference

TOL = 1e-12


def test_reference_files_are_regenerated_identically(project_dir: Path, tmp_path: Path) -> None:
    """The committed reference is what build/make_reference.py writes."""
    for path in write_reference(tmp_path):
        committed = project_dir / "fmu_src" / "FrictionPlant" / path.name
        assert committed.read_text() == path.read_text(), path.name


def test_fmu_matches_reference(friction_plant_fmu: Path, project_dir: Path) -> None:
    folder = project_dir / "fmu_src" / "FrictionPlant"
    opts = read_ref_opt_file(str(folder / "FrictionPlant_ref.opt"))
    signals = read_csv(folder / "FrictionPlant_in.csv")
    reference = read_csv(folder / "FrictionPlant_ref.csv")
    result = simulate_fmu(
        str(friction_plant_fmu),
        start_time=opts["StartTime"],
        stop_time=opts["StopTime"],
        output_interval=opts["StepSize"],
        input=signals,
        output=["x", "v"],
    )
    assert len(result) == len(reference)
    np.testing.assert_allclose(result["time"], reference["time"], rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(result["x"], reference["x"], rtol=0.0, atol=TOL)
    np.testing.assert_allclose(result["v"], reference["v"], rtol=0.0, atol=TOL)
    assert validate_result(result, reference, stop_time=opts["StopTime"]) == 0
    # the reference covers breakaway both ways, rest, and a reversal while sliding
    v = reference["v"]
    assert (v > 0).any() and (v < 0).any() and (v == 0).sum() > 20
