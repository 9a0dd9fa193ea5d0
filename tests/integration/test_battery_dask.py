"""The battery on a real Dask cluster (``dask scheduler`` and ``dask worker`` CLI processes)."""

from __future__ import annotations

from pathlib import Path

import pytest
from harness import PAPWC_PAPER, PWC_PAPER, scenario_toml

from papwc.battery import load_battery, local_dask_cluster, run_battery

BATTERY = scenario_toml("dasksmall", maneuver={"x_ref": 0.01, "duration": 0.5, "iterations": 2},
                        controllers=[PWC_PAPER, PAPWC_PAPER], tables={
    "sweep": {"plant.f_s": [130.0, 90.0]},
    "monte_carlo": {"n": 5, "seed": 5, "plant.m": {"dist": "uniform", "rel": 0.3},
                    "plant.c": {"dist": "normal", "rel_std": 0.1},
                    "controller.m_est": {"dist": "uniform", "low": 0.8, "high": 1.2,
                                         "of": "plant.m"}}})


@pytest.mark.dask
@pytest.mark.slow
def test_dask_cluster_gives_the_local_results_value_for_value(
    tmp_path: Path, friction_plant_fmu: Path
):
    path = tmp_path / "dasksmall.toml"
    path.write_text(BATTERY)
    battery = load_battery(path)
    local = run_battery([battery], tmp_path / "local", friction_plant_fmu, workers=2,
                        progress=False)
    # one `dask worker` process with two threads; the scheduler and the worker are
    # stopped when the block ends, whatever happens inside it
    with local_dask_cluster(n_workers=1, nthreads=2) as address:
        assert address.startswith("tcp://127.0.0.1:")
        remote = run_battery([battery], tmp_path / "dask", friction_plant_fmu,
                             scheduler=address, progress=False)
    assert remote.runs == local.runs == 10
    assert len(remote.failed) == len(local.failed) == 5  # f_s = 90 N < f_c
    for name in ("results.csv", "runs.csv"):
        assert (tmp_path / "dask" / name).read_text() == (tmp_path / "local" / name).read_text()
