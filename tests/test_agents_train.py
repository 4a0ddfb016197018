"""smartcar-train smoke tests on SmartCar-v0: a few hundred steps per algorithm, the run
folder's contents, resume, and Ctrl-C."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from smartcar_gym.agents import train
from smartcar_gym.agents.hyperparams import algo_class

TINY_NET = "policy_kwargs=dict(net_arch=[16, 16])"
SMALL = {
    "ppo": ["n_steps=128", "batch_size=64", "n_epochs=2", TINY_NET],
    "sac": ["learning_starts=100", "buffer_size=2000", "batch_size=32", TINY_NET],
    "td3": ["learning_starts=100", "buffer_size=2000", "batch_size=32", TINY_NET],
}


def _argv(algo: str, run_dir: Path, timesteps: int = 512) -> list[str]:
    return [
        "--algo", algo, "--n-envs", "2", "--seed", "1", "--timesteps", str(timesteps),
        "--run-dir", str(run_dir), "--eval-freq", "256", "--eval-episodes", "2",
        "--checkpoint-freq", "256", "--no-progress",
        "--env-kwargs", "max_episode_steps=50", "--hyperparams", *SMALL[algo],
    ]


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("train") / "ppo"
    assert train.main(_argv("ppo", run_dir)) == 0
    return run_dir


def _check_run_folder(run_dir: Path, algo: str, steps: int) -> None:
    for name in ("model.zip", "vecnormalize.pkl", "config.yaml", "summary.json",
                 "best_model.zip", "best_model_vecnormalize.pkl", "best_model.json",
                 "learning_curve.png", "eval/evaluations.npz"):
        assert (run_dir / name).is_file(), name
    assert (run_dir / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert list((run_dir / "tb").rglob("events.out.tfevents.*"))

    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert (config["algo"], config["env"], config["seed"]) == (algo, "SmartCar-v0", 1)
    assert (config["n_envs"], config["n_timesteps"]) == (2, 512)
    assert config["env_kwargs"] == {"max_episode_steps": 50}
    assert config["hyperparams"]["policy_kwargs"] == "dict(net_arch=[16, 16])"
    assert config["hyperparams"]["n_envs"] == 2
    assert config["versions"]["smartcar_gym"] and config["versions"]["stable_baselines3"]
    assert config["command"].startswith(f"smartcar-train --algo {algo} --n-envs 2")
    assert config["resumes"] == []

    names = sorted(p.name for p in (run_dir / "checkpoints").iterdir())
    assert names[:2] == ["ckpt_256_steps.zip", "ckpt_256_steps_vecnormalize.pkl"]
    assert f"ckpt_{steps}_steps.zip" in names and not [n for n in names if n.startswith(".")]

    for rank in (0, 1):
        monitor = pd.read_csv(run_dir / "monitor" / f"seg0_{rank}.monitor.csv", skiprows=1)
        assert list(monitor.columns) == ["r", "l", "t", "is_success"]
        assert len(monitor) >= 1 and (monitor["l"] <= 50).all()

    evals = np.load(run_dir / "eval" / "evaluations.npz")
    assert evals["timesteps"].tolist()[:2] == [256, 512]
    n_evals = len(evals["timesteps"])
    assert evals["successes"].shape == evals["final_distances"].shape == (n_evals, 2)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["num_timesteps"] == steps and not summary["interrupted"]
    assert summary["final_eval"]["timesteps"] == steps
    assert algo_class(algo).load(run_dir / "model.zip").num_timesteps == steps


@pytest.mark.slow
def test_ppo_run_folder(ppo_run):
    _check_run_folder(ppo_run, "ppo", 512)
    hp = yaml.safe_load((ppo_run / "config.yaml").read_text())["hyperparams"]
    assert (hp["n_steps"], hp["batch_size"], hp["n_epochs"]) == (128, 64, 2)


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_off_policy_run_folder(algo, tmp_path):
    run_dir = tmp_path / algo
    assert train.main(_argv(algo, run_dir)) == 0
    _check_run_folder(run_dir, algo, 512)
    stats = yaml.safe_load((run_dir / "config.yaml").read_text())["hyperparams"]["normalize"]
    assert "'norm_reward': False" in stats


def _obs_count(path: Path) -> float:
    import pickle

    with open(path, "rb") as f:
        return float(pickle.load(f).obs_rms.count)


@pytest.mark.slow
def test_resume_continues_steps_normaliser_and_logs(ppo_run, tmp_path):
    run_dir = tmp_path / "resumed"
    shutil.copytree(ppo_run, run_dir)
    count_before = _obs_count(run_dir / "vecnormalize.pkl")
    assert train.main(["--resume", str(run_dir), "--timesteps", "1024", "--no-progress"]) == 0

    model = algo_class("ppo").load(run_dir / "model.zip")
    assert model.num_timesteps == 1024
    assert _obs_count(run_dir / "vecnormalize.pkl") > count_before + 400
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert config["n_timesteps"] == 1024 and config["seed"] == 1
    [resume] = config["resumes"]
    assert resume["from_timesteps"] == 512
    assert resume["from_checkpoint"] == "checkpoints/ckpt_512_steps.zip"
    assert resume["command"].startswith("smartcar-train --resume")
    assert (run_dir / "monitor" / "seg1_0.monitor.csv").is_file()
    assert (run_dir / "checkpoints" / "ckpt_1024_steps.zip").is_file()
    evals = np.load(run_dir / "eval" / "evaluations.npz")["timesteps"].tolist()
    assert evals == [256, 512, 768, 1024]

    from smartcar_gym.agents.plots import load_training_episodes

    episodes = load_training_episodes(run_dir)
    assert episodes["steps"].is_monotonic_increasing or episodes["steps"].max() <= 1024 + 100
    assert (episodes["steps"] > 512).any()


class _InterruptAt:
    """Raises KeyboardInterrupt (as Ctrl-C would) once training reaches a step count."""

    def __new__(cls, steps):
        from stable_baselines3.common.callbacks import BaseCallback

        class Interrupt(BaseCallback):
            def _on_step(self):
                if self.num_timesteps >= steps:
                    raise KeyboardInterrupt
                return True

        return Interrupt()


@pytest.mark.slow
def test_keyboard_interrupt_saves_a_checkpoint_that_resumes(tmp_path):
    args = train.build_parser().parse_args(_argv("ppo", tmp_path / "x"))
    config = train.new_config(args, "test")
    config["checkpoint_freq"] = 0
    run_dir = tmp_path / "interrupted"
    result = train.train(config, run_dir, progress=False, extra_callbacks=[_InterruptAt(300)])
    assert result.interrupted and result.num_timesteps == 300
    assert (run_dir / "checkpoints" / "ckpt_300_steps.zip").is_file()
    assert (run_dir / "checkpoints" / "ckpt_300_steps_vecnormalize.pkl").is_file()
    assert algo_class("ppo").load(run_dir / "model.zip").num_timesteps == 300
    assert json.loads((run_dir / "summary.json").read_text())["interrupted"] is True
    assert train.main(["--resume", str(run_dir), "--no-progress", "--eval-freq", "0"]) == 0
    assert algo_class("ppo").load(run_dir / "model.zip").num_timesteps >= 512


@pytest.mark.slow
def test_ctrl_c_on_the_command_line_exits_130_with_a_checkpoint(tmp_path):
    run_dir = tmp_path / "sigint"
    argv = _argv("ppo", run_dir, timesteps=1_000_000)
    proc = subprocess.Popen(
        [sys.executable, "-m", "smartcar_gym.agents.train", *argv],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # a background shell may have ignored SIGINT; give the child the default handler
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        monitor = run_dir / "monitor" / "seg0_0.monitor.csv"
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if monitor.exists() and len(monitor.read_text().splitlines()) > 2:
                break  # an episode has finished: training is under way
            time.sleep(0.2)
        assert proc.poll() is None, proc.communicate()
        os.kill(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == train.INTERRUPTED_EXIT_CODE, err
    assert f"smartcar-train --resume {run_dir}" in err
    assert "interrupted" in out
    checkpoints = list((run_dir / "checkpoints").glob("ckpt_*_steps.zip"))
    assert checkpoints and (run_dir / "model.zip").is_file()
