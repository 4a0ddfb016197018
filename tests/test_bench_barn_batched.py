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


def test_worker_processes_give_one_processs_records_in_the_order_of_the_jobs(tmp_path,
                                                                           capsys):
    """Two processes, each on a car of its own, take the next job none has taken as their car
    frees: the records (with the laser's noise, so every run differs) are one process's to
    the bit, in the jobs' order."""
    argv = ["barn", "--engine", "planar", "--worlds", "0", "6", "--runs", "2", "--quiet",
            "--env-kwargs", "laser={noise_std_m: 0.01}", "--json"]
    assert main([*argv, str(tmp_path / "one.json"), "--n-envs", "2"]) == 0
    assert main([*argv, str(tmp_path / "two.json"), "--workers", "2"]) == 0
    one, two = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("one", "two"))
    assert [(r["world"], r["run"]) for r in two["records"]] == [
        (w, k) for w in (0, 6) for k in (0, 1)]
    assert two["records"] == one["records"]
    assert len({r["time_s"] for r in one["records"]}) == 4  # the runs differ
    assert capsys.readouterr().out.count("| dwa | 4 |") == 2


def test_a_workers_refusal_is_the_same_one_line(capsys):
    pytest.importorskip("stable_baselines3")
    with pytest.raises(SystemExit) as exit_:
        main(["barn", "--engine", "planar", "--pretrained", "nav", "--worlds", "0", "6",
              "--workers", "2"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "smartcar-bench barn: error: pretrained:nav takes observations of shape (57,) (it was "
        "trained on SmartCarNav-v0) but SmartCarBARN-v0 gives (59,): train a policy on "
        "SmartCarBARN-v0")


def test_each_worker_takes_its_share_of_the_cores(monkeypatch):
    """``--workers 2`` on 4 CPUs: each worker's vector env and DWA driver run their compiled
    loops on 2 threads (4 would wait on one another)."""
    from smartcar_gym.bench import cli, workers

    seen = {}
    monkeypatch.setattr(workers.os, "cpu_count", lambda: 4)
    monkeypatch.setattr(cli, "run_here", lambda driver, n, kwargs, *rest: seen.update(
        driver=driver, kwargs=kwargs))
    options = {"model": None, "pretrained": None, "driver": "dwa", "env_kwargs": [],
               "goal_rate": None, "workers": 2, "n_envs": 1, "quiet": True}
    workers._shard(options, {"map_mode": "laser"}, [0], [], set(), 1)
    assert seen["kwargs"] == {"map_mode": "laser", "num_threads": 2}
    assert isinstance(seen["driver"], DWADriver) and seen["driver"].threads == 2


def test_a_driver_acts_with_torch_on_one_thread_and_the_count_comes_back():
    """``run_barn`` runs its steps with torch on one thread (``runner.one_torch_thread``:
    100 cars' predict took 3.8 ms a step beside the batch's worker threads, 0.6 alone)."""
    torch = pytest.importorskip("torch")
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    seen = []

    class Counting(DWADriver):
        def act(self, cars, obs, idx):
            seen.append(torch.get_num_threads())
            return super().act(cars, obs, idx)

    batch = SmartCarBatchVectorEnv("SmartCarBARN-v0", num_envs=1, engine="planar")
    try:
        [record] = run_barn(batch, Counting(), barn_jobs((0,), runs=1, seed=3))
        assert record.outcome == "success" and set(seen) == {1}
        assert torch.get_num_threads() == 2
    finally:
        batch.close()
        torch.set_num_threads(before)
