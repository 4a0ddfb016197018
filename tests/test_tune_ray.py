"""smartcar-tune on Ray: a local 2-CPU head, a two-node cluster on this machine
(``ray.cluster_utils.Cluster``), a batched sweep on a head started by ``ray start --head``
(through ``RAY_ADDRESS``), and a sweep killed mid-run then resumed. Tiny budgets (a few hundred
steps) and hard timeouts; nothing here says anything about speed.
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import yaml

pytest.importorskip("ray.tune", reason='Ray Tune is not installed: pip install "smartcar-gym[ray]"')
pytestmark = pytest.mark.xdist_group("ray")  # one Ray cluster at a time (pytest-xdist)

from smartcar_gym.agents.callbacks import find_latest_checkpoint  # noqa: E402
from smartcar_gym.agents.hyperparams import load_hyperparams  # noqa: E402
from smartcar_gym.scale import tune as tune_cli  # noqa: E402
from smartcar_gym.scale.ray_session import ray_session  # noqa: E402

TINY = {"n_envs": 1, "n_steps": 128, "batch_size": 64, "n_epochs": 1}
# goals 0.5-0.6 m away: a 0.7 m tolerance succeeds at the first step, 0.05 m never here
EASY, HARD = 0.7, 0.05


@pytest.fixture(autouse=True)
def no_auth_token(monkeypatch):
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")  # throwaway heads: no token under $HOME


def write_space(path: Path, **space) -> Path:
    path.write_text(yaml.safe_dump({"hyperparams": TINY, "eval_episodes": 1, **space}))
    return path


def results(out: Path) -> list[dict]:
    with open(out / "results.csv") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize(("setting", "expected"), [(None, 0), ("7", 7)])
def test_a_local_head_runs_its_workers_at_this_process_niceness(setting, expected, monkeypatch,
                                                                 hard_timeout):
    """Ray starts workers at nice 15, where two busy loops beside a sweep starved its trials
    (a 20 s sweep ran for over 15 minutes); a local head runs them as this process runs,
    unless RAY_worker_niceness says otherwise."""
    hard_timeout(120)
    if setting is None:
        monkeypatch.delenv("RAY_worker_niceness", raising=False)
    else:
        monkeypatch.setenv("RAY_worker_niceness", setting)
    with ray_session(num_cpus=1) as ray:
        niceness = ray.get(ray.remote(num_cpus=1)(lambda: os.nice(0)).remote())
    assert niceness == os.nice(0) + expected


def test_local_head_sweep_with_asha(tmp_path, hard_timeout, capsys):
    hard_timeout(150)
    space = write_space(
        tmp_path / "space.yaml", timesteps=256, eval_freq=128, cpus_per_trial=2,
        env_kwargs={"goal_range": [0.5, 0.6], "goal_tolerance": {"grid": [EASY, HARD]}},
        early_stopping={"grace_period": 128, "reduction_factor": 2})
    out = tmp_path / "sweep"
    # 2 CPUs, 2 per trial: the trials run one after the other, in order, so ASHA has the
    # first (100 % success at 128 steps) when the second reports 0 % there, and stops it
    code = tune_cli.main(["--space", str(space), "--num-cpus", "2", "--out", str(out)])
    assert code == 0
    rows = results(out)
    assert [(r["trial"], r["env_kwargs.goal_tolerance"]) for r in rows] == [
        ("trial_00000", str(EASY)), ("trial_00001", str(HARD))]
    easy, hard = rows
    assert (easy["status"], easy["timesteps"], easy["success_rate"]) == ("completed", "256", "1.0")
    assert (hard["status"], hard["timesteps"], hard["success_rate"]) == (
        "stopped early", "128", "0.0")
    # the completed trial is a whole smartcar-train run
    run = out / "trial_00000"
    for name in ("config.yaml", "hyperparams.yaml", "model.zip", "best_model.zip",
                 "summary.json", "eval/evaluations.npz", "checkpoints/ckpt_256_steps.zip"):
        assert (run / name).exists(), name
    summary = json.loads((run / "summary.json").read_text())
    assert summary["num_timesteps"] == 256 and summary["final_eval"]["success_rate"] == 1.0
    # the stopped one has everything up to its last evaluation: it can be continued
    assert find_latest_checkpoint(out / "trial_00001", normalize=True) == (
        out / "trial_00001" / "checkpoints" / "ckpt_128_steps.zip")
    # the best configuration, as a file smartcar-train reads
    best = load_hyperparams("ppo", "SmartCar-v0", out / "best_hyperparams.yaml")
    assert best == {**yaml.safe_load((run / "hyperparams.yaml").read_text())["SmartCar-v0"]}
    assert "goal_tolerance=0.7" in (out / "best_hyperparams.yaml").read_text()
    summary = json.loads((out / "results.json").read_text())
    assert summary["best"]["trials"] == ["trial_00000"]
    printed = capsys.readouterr().out
    assert "trial_00001" in printed and "stopped early" in printed


def test_two_node_cluster(tmp_path, hard_timeout, capsys):
    hard_timeout(150)
    from ray.cluster_utils import Cluster

    # the nodes' workers at nice 0, as smartcar-tune's local head has them (nice 15, Ray's
    # default, starves them on a loaded machine)
    cluster = Cluster(initialize_head=True, head_node_args={
        "num_cpus": 1, "include_dashboard": False, "_system_config": {"worker_niceness": 0}})
    try:
        worker = cluster.add_node(num_cpus=1)
        nodes = {cluster.head_node.node_id, worker.node_id}
        space = write_space(tmp_path / "space.yaml", timesteps=256, eval_freq=256,
                            seed={"grid": [0, 1]})
        # a trial of 2 CPUs fits no node: refused at once (Ray would wait forever)
        code = tune_cli.main(["--space", str(space), "--cpus-per-trial", "2",
                              "--address", cluster.address, "--out", str(tmp_path / "no")])
        assert code == 2
        assert "needs 2 CPUs on one node, but the largest node of the Ray cluster has 1" in (
            capsys.readouterr().err)
        assert not (tmp_path / "no").exists()  # refused before the folder became a sweep
        out = tmp_path / "sweep"
        code = tune_cli.main(["--space", str(space), "--address", cluster.address,
                              "--out", str(out)])
        assert code == 0
    finally:
        cluster.shutdown()
    rows = results(out)
    assert [(r["seed"], r["status"], r["timesteps"]) for r in rows] == [
        ("0", "completed", "256"), ("1", "completed", "256")]
    # one CPU per node and per trial: the two trials ran at once, one on each node
    assert {r["node_id"] for r in rows} == nodes


def test_a_killed_sweep_resumes_from_its_checkpoints(tmp_path, hard_timeout):
    hard_timeout(170)
    space = write_space(tmp_path / "space.yaml", timesteps=384, eval_freq=128)
    out = tmp_path / "sweep"
    run = out / "trial_00000"
    # the whole sweep (driver and local Ray) dies at once, as in a crash of the machine.
    # (384 steps: each segment of the run ends an episode of 200 steps; smartcar-train's
    # learning-curve plot fails on a segment that ends none.)
    sweep = subprocess.Popen(
        [sys.executable, "-m", "smartcar_gym.scale.tune", "--space", str(space),
         "--num-cpus", "2", "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 100
        while not (list((run / "checkpoints").glob("ckpt_*_steps.zip"))
                   and list((out / "tune").glob("experiment_state-*.json"))):
            assert sweep.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() < deadline, "no checkpoint within 100 s"
            time.sleep(0.1)
    finally:
        os.killpg(sweep.pid, signal.SIGKILL)
        sweep.wait()
    assert not (run / "summary.json").exists()  # killed in the middle of the run
    done = sorted(int(p.name.split("_")[1]) for p in (run / "checkpoints").glob("ckpt_*.zip"))

    assert tune_cli.main(["--resume", str(out), "--num-cpus", "2"]) == 0
    config = yaml.safe_load((run / "config.yaml").read_text())
    # continued from the checkpoint on disk, not started again
    assert [r["from_timesteps"] for r in config["resumes"]] == [done[-1]]
    assert config["resumes"][0]["command"] == f"smartcar-train --resume {run} --no-progress"
    assert json.loads((run / "summary.json").read_text())["num_timesteps"] == 384
    assert sorted(p.name for p in (run / "monitor").glob("*.csv")) == [
        "seg0_0.monitor.csv", "seg1_0.monitor.csv"]
    [row] = results(out)
    assert (row["status"], row["timesteps"]) == ("completed", "384")


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture
def ray_head():
    """``ray start --head`` on 2 CPUs in a temporary folder; its address. Stopped by its own
    process group (``ray stop`` would stop every Ray instance of the machine)."""
    ray_cli = shutil.which("ray", path=os.path.dirname(sys.executable)) or shutil.which("ray")
    if ray_cli is None:
        pytest.skip("the ray command is not installed")
    port, folder = free_port(), tempfile.mkdtemp(prefix="ray")  # short: Ray's socket paths
    env = {**os.environ, "RAY_AUTH_MODE": "disabled", "RAY_worker_niceness": "0"}
    env.pop("RAY_ADDRESS", None)
    head = subprocess.Popen(
        [ray_cli, "start", "--head", "--port", str(port), "--num-cpus", "2", "--temp-dir",
         folder, "--block", "--include-dashboard", "false", "--disable-usage-stats",
         "--ray-client-server-port", str(free_port())],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert head.poll() is None, "ray start --head exited"
                assert time.monotonic() < deadline, "ray start --head: no head within 60 s"
                time.sleep(0.2)
        yield f"127.0.0.1:{port}"
    finally:
        head.terminate()  # `ray start --block` stops its processes (in about 2 s)
        try:
            head.wait(timeout=30)
        finally:
            with contextlib.suppress(ProcessLookupError):  # whatever is left of them
                os.killpg(head.pid, signal.SIGKILL)
            head.wait()
            shutil.rmtree(folder, ignore_errors=True)


def test_a_batched_sweep_on_a_ray_start_head_through_ray_address(ray_head, tmp_path,
                                                                 monkeypatch, hard_timeout):
    """The planar batched preset (4 cars here, evaluated on planar in a second process) on a
    running head named by RAY_ADDRESS: ASHA stops the weaker trial at its first evaluation."""
    hard_timeout(150)
    space = tmp_path / "space.yaml"
    space.write_text(yaml.safe_dump({
        "vectorization": "batched", "timesteps": 256, "eval_freq": 128, "eval_episodes": 1,
        "hyperparams": {"n_envs": 4, "n_steps": 32, "batch_size": 64, "n_epochs": 1},
        "env_kwargs": {"goal_range": [0.5, 0.6], "goal_tolerance": {"grid": [EASY, HARD]}},
        "early_stopping": {"grace_period": 128, "reduction_factor": 2}}))
    monkeypatch.setenv("RAY_ADDRESS", ray_head)
    out = tmp_path / "sweep"
    # the preset's 2 CPUs a trial (training, eval_async) on the 2-CPU head: one at a time
    assert tune_cli.main(["--space", str(space), "--engine", "planar", "--out", str(out)]) == 0
    easy, hard = results(out)
    assert (easy["status"], easy["timesteps"], easy["success_rate"]) == ("completed", "256", "1.0")
    assert (hard["status"], hard["timesteps"], hard["success_rate"]) == (
        "stopped early", "128", "0.0")
    for name in ("trial_00000", "trial_00001"):
        config = yaml.safe_load((out / name / "config.yaml").read_text())
        assert (config["vectorization"], config["n_envs"]) == ("batched", 4)
        assert (config["eval_engine"], config["eval_async"]) == (None, True)
        assert (out / name / "monitor" / "seg0_batched.monitor.csv").is_file()
    import ray

    ray.init(address=ray_head, logging_level="WARNING")
    try:
        [head] = [node["NodeID"] for node in ray.nodes() if node["Alive"]]
    finally:
        ray.shutdown()
    assert {easy["node_id"], hard["node_id"]} == {head}  # the head ran them, not a new Ray
