"""FrictionPlant.fmu against its reference result in the FMI cross-check layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from fmpy import simulate_fmu
from fmpy.util import read_csv, read_ref_opt_file, validate_result

from papwc.fmubuild.reference import U_SEGMENTS, reference_input, write_reference
from papwc.model.plant import PLANT_DEFAULTS
from papwc.model.stickslip import simulate

# fmpy steps with h = t_(k+1) - t_k on its own time grid, which differs from the
# reference's 0.01 s in the last bits. Measured: 1.1e-16 s in time, 3.0e-18 m in x,
# 7.3e-17 m/s in v (formerly checked to 1e-12).
TOL_T = 2e-16
TOL_X = 1e-17
TOL_V = 2e-16


def test_reference_files_are_regenerated_identically(project_dir: Path, tmp_path: Path) -> None:
    """The committed reference is what papwc.fmubuild.reference writes."""
    for path in write_reference(tmp_path):
        committed = project_dir / "fmu_src" / "FrictionPlant" / path.name
        assert committed.read_text() == path.read_text(), path.name


def test_reference_is_the_exact_solution(project_dir: Path) -> None:
    reference = read_csv(project_dir / "fmu_src" / "FrictionPlant" / "FrictionPlant_ref.csv")
    params = {k: PLANT_DEFAULTS[k] for k in ("m", "f_c", "f_s", "c")}
    states = simulate(reference_input(), 0.01, **params)
    assert list(reference["x"]) == [x for x, _ in states]  # written with repr: exact
    assert list(reference["v"]) == [v for _, v in states]
    assert len(reference_input()) == 100 and reference_input()[0] == U_SEGMENTS[0][1]


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
    np.testing.assert_allclose(result["time"], reference["time"], rtol=0.0, atol=TOL_T)
    np.testing.assert_allclose(result["x"], reference["x"], rtol=0.0, atol=TOL_X)
    np.testing.assert_allclose(result["v"], reference["v"], rtol=0.0, atol=TOL_V)
    assert validate_result(result, reference, stop_time=opts["StopTime"]) == 0
    # the reference covers breakaway both ways, rest, and a reversal while sliding
    v = reference["v"]
    assert (v > 0).any() and (v < 0).any() and (v == 0).sum() > 20
