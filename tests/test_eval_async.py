"""eval_async: a batched run's evaluations in a second process while it trains. They are the
evaluations the training process makes itself, number for number, and their best model the
same; a worker that fails or dies is an error that says so, never a hang."""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

pytest.importorskip("stable_baselines3", reason="smartcar-train needs the train extra")

from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.running_mean_std import RunningMeanStd  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize  # noqa: E402

from smartcar_gym.agents import cli_train  # noqa: E402
from smartcar_gym.agents.eval_worker import (  # noqa: E402
    EvalWorker,
    EvalWorkerError,
    apply_normalization_stats,
    normalization_stats,
)

# 4 planar cars trained for 3 updates, evaluated on pybullet at 512, 1024 and 1536 steps on 3
# episodes of at most 40 steps (the planar preset's eval_async, on another engine)
ARGV = ["--engine", "planar", "--vectorization", "batched", "--n-envs", "4", "--seed", "3",
        "--eval-engine", "pybullet",
        "--timesteps", "1536", "--eval-freq", "512", "--eval-episodes", "3", "--eval-start", "0",
        "--checkpoint-freq", "0", "--no-progress", "--env-kwargs", "max_episode_steps=40",
        "goal_range=[0.3, 0.4]", "--hyperparams", "n_steps=128", "batch_size=128",
        "n_epochs=2", "policy_kwargs=dict(net_arch=[16, 16])"]


@pytest.mark.slow
def test_async_evaluations_are_the_training_process_s_own(tmp_path):
    sync, asynchronous = tmp_path / "sync", tmp_path / "async"
    assert cli_train.main([*ARGV, "--run-dir", str(sync), "--no-eval-async"]) == 0
    assert cli_train.main([*ARGV, "--run-dir", str(asynchronous)]) == 0  # the preset's eval_async
    config = yaml.safe_load((asynchronous / "config.yaml").read_text())
    assert config["eval_async"] is True and config["eval_engine"] == "pybullet"
    assert yaml.safe_load((sync / "config.yaml").read_text())["eval_async"] is False

    a, b = (np.load(run / "eval" / "evaluations.npz") for run in (sync, asynchronous))
    assert a["timesteps"].tolist() == [512, 1024, 1536]
    for key in ("timesteps", "results", "ep_lengths", "successes", "final_distances"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert (json.loads((sync / "best_model.json").read_text())
            == json.loads((asynchronous / "best_model.json").read_text()))
    params = [PPO.load(run / "best_model.zip", device="cpu").policy.state_dict()
              for run in (sync, asynchronous)]
    for name, value in params[0].items():
        assert torch.equal(value, params[1][name]), name
    saved = [pickle.loads((run / "best_model_vecnormalize.pkl").read_bytes())  # written here
             for run in (sync, asynchronous)]
    for rms in ("obs_rms", "ret_rms"):
        first, second = (getattr(v, rms) for v in saved)
        assert (first.count, first.mean.tolist(), first.var.tolist()) == (
            second.count, second.mean.tolist(), second.var.tolist()), rms
    assert not list((asynchronous / "eval").glob("pending_*"))  # each snapshot kept or removed
    summary = json.loads((asynchronous / "summary.json").read_text())
    assert summary["final_eval"]["timesteps"] == 1536 and summary["final_eval_s"] > 0


@pytest.mark.parametrize("forkserver", [True, False], ids=["forkserver", "spawn"])
def test_a_worker_whose_env_fails_says_why(forkserver, monkeypatch):
    if not forkserver:  # as on Windows, which has no forkserver
        monkeypatch.setattr("multiprocessing.get_all_start_methods", lambda: ["spawn"])

    def make_env():
        raise ValueError("no world here")

    worker = EvalWorker(make_env)
    try:
        with pytest.raises(EvalWorkerError, match="failed: ValueError: no world here"):
            worker.submit(512, None, [], n_episodes=1, seed=0)
            worker.wait()
        assert worker.pending == []
    finally:
        worker.close()


def test_a_worker_that_could_not_start_says_why_at_its_first_call(monkeypatch):
    """The process starts in a thread (the training sets up meanwhile): a start that fails is
    raised by the first call, and closing such a worker stops nothing."""
    import multiprocessing.process

    def refuse(self):
        raise OSError("no processes left")

    monkeypatch.setattr(multiprocessing.process.BaseProcess, "start", refuse)
    worker = EvalWorker(lambda: None)
    with pytest.raises(EvalWorkerError, match="could not start: OSError: no processes left"):
        worker.submit(512, None, [], n_episodes=1, seed=0)
    assert worker.pending == []
    with pytest.raises(EvalWorkerError, match="could not start"):
        worker.wait()
    worker.close()


def test_a_worker_that_died_is_an_error_not_a_hang():
    worker = EvalWorker(lambda: None)  # waits for requests
    try:
        worker.submit(512, None, [], n_episodes=1, seed=0)  # taken, then the worker dies
        worker._process.kill()
        with pytest.raises(EvalWorkerError, match=r"stopped \(exit code -9\)"):
            worker.wait()
        with pytest.raises(EvalWorkerError, match="stopped"):
            worker.submit(1024, None, [], n_episodes=1, seed=0)
    finally:
        worker.close()


def test_normalization_stats_go_to_the_same_wrappers():
    def stats(mean: float) -> RunningMeanStd:
        rms = RunningMeanStd(shape=(3,))
        rms.mean[:] = mean
        return rms

    def env() -> DummyVecEnv:
        return DummyVecEnv([lambda: gym.make("Pendulum-v1")])  # 3 observations

    source, target = VecNormalize(env()), VecNormalize(env())
    source.obs_rms, source.ret_rms = stats(1.5), stats(-2.0)
    apply_normalization_stats(target, normalization_stats(source))
    assert target.obs_rms.mean.tolist() == [1.5] * 3 and target.ret_rms.mean.tolist() == [-2] * 3
    with pytest.raises(EvalWorkerError, match="0 VecNormalize wrappers, the training env 1"):
        apply_normalization_stats(env(), normalization_stats(source))


def test_eval_async_needs_a_batched_run_and_a_boolean(tmp_path, capsys):
    argv = ["--timesteps", "128", "--n-envs", "2", "--run-dir", str(tmp_path / "r"),
            "--no-progress", "--eval-async"]
    with pytest.raises(SystemExit) as exc:
        cli_train.main(argv)
    assert exc.value.code == 2
    assert "eval_async evaluates in a second process beside a batched run" in (
        capsys.readouterr().err)
    assert not (tmp_path / "r").exists()
    with pytest.raises(SystemExit):
        cli_train.main([*argv[:-1], "--hyperparams", "eval_async=1"])
    assert "eval_async must be true or false, got 1" in capsys.readouterr().err


@pytest.mark.slow
def test_a_signal_to_the_process_group_drains_the_worker_and_stops(tmp_path):
    """The worker ignores the Ctrl-C that reaches the whole group: the run stops at its next
    step, records the evaluations already sent, and leaves no snapshot behind."""
    run_dir = tmp_path / "signal"
    argv = [*ARGV, "--timesteps", "1000000", "--run-dir", str(run_dir), "--eval-async"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "smartcar_gym.agents.cli_train", *argv],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if (run_dir / "eval" / "evaluations.npz").exists():
                break  # an evaluation came back from the worker
            time.sleep(0.2)
        assert proc.poll() is None, proc.communicate()
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == cli_train.INTERRUPTED_EXIT_CODE, err
    assert "Interrupted (SIGINT): checkpoint saved" in err and "Traceback" not in err
    assert not list((run_dir / "eval").glob("pending_*"))
    steps = json.loads((run_dir / "summary.json").read_text())["num_timesteps"]
    evaluated = np.load(run_dir / "eval" / "evaluations.npz")["timesteps"].tolist()
    assert evaluated == list(range(512, steps + 1, 512))  # every one sent was recorded
