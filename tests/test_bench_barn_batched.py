"""``smartcar-bench barn`` on a batched env: the same records as the row of single envs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.bench.cli import main
from smartcar_gym.bench.dwa import DWADriver
from smartcar_gym.bench.runs import barn_jobs, run_barn
from smartcar_gym.envs.vector import SmartCarBatchVectorEnv, SmartCarLoopVectorEnv


@pytest.mark.parametrize("kwargs", [{}, {"localize": True}])
def test_dwa_on_a_batch_gives_the_single_envs_records_bit_for_bit(kwargs):
    """Three runs on two cars: the third job goes to the car that ends first, the other car
    is parked; every record (outcome, times, scores, way) is the single envs' row's, with DWA
    following the path from the odometry or (``localize``) from the pose on the map. A car
    left without a run is parked where it stands: three worlds are built, one per run."""
    jobs = barn_jobs((0, 6), runs=2, seed=3)[:3]
    singles = SmartCarLoopVectorEnv("SmartCarBARN-v0", num_envs=2, engine="planar", **kwargs)
    batch = SmartCarBatchVectorEnv("SmartCarBARN-v0", num_envs=2, engine="planar", **kwargs)
    builds = []
    reset = batch.builder.reset
    batch.builder.reset = lambda **kw: builds.append(kw["options"]["world"]) or reset(**kw)
    try:
        want = run_barn(singles, DWADriver(), jobs, keep=lambda job: True)
        got = run_barn(batch, DWADriver(), jobs, keep=lambda job: True)
    finally:
        batch.close()
        singles.close()
    assert [r.outcome for r in want] == ["success"] * 3
    assert builds == [job.world for job in jobs]
    for g, w in zip(got, want, strict=True):
        assert g.to_dict() == w.to_dict()
        assert np.array_equal(g.trajectory, w.trajectory)


def test_the_command_runs_batched_where_the_engine_batches(tmp_path, capsys):
    out_json = tmp_path / "dwa.json"
    assert main(["barn", "--engine", "planar", "--worlds", "0", "--n-envs", "2", "--quiet",
                 "--json", str(out_json)]) == 0
    assert "| dwa | 1 | 1.000 |" in capsys.readouterr().out
    data = json.loads(out_json.read_text())
    assert data["vectorization"] == "batched" and data["engine"] == "planar"
