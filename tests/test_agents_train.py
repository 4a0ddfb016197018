"""smartcar-train smoke tests on SmartCar-v0: a few hundred steps per algorithm, the run
folder's contents, resume (with SAC's replay buffer), restart after a failed start, and
Ctrl-C / SIGTERM."""

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

from smartcar_gym.agents import cli_train, runs
from smartcar_gym.agents.hyperparams import algo_class

TINY_NET = "policy_kwargs=dict(net_arch=[16, 16])"
SMALL = {
    "ppo": ["n_steps=128", "batch_size=64", "n_epochs=2", TINY_NET],
    "sac": ["learning_starts=100", "buffer_size=2000", "batch_size=32", TINY_NET],
    "td3": ["learning_starts=100", "buffer_size=2000", "batch_size=32", TINY_NET],
}
# Every episode lasts exactly 32 steps: in 3.2 s the car (0.5 m/s at most) can neither reach a
# goal 2 m away nor leave the 5 m arena. So step counts of episodes are known exactly.
EPISODE = 32
ENV_KWARGS = [f"max_episode_steps={EPISODE}", "goal_range=[2.0, 2.2]"]


def _argv(algo: str, run_dir: Path, timesteps: int = 512) -> list[str]:
    return [
        "--algo", algo, "--n-envs", "2", "--seed", "1", "--timesteps", str(timesteps),
        "--run-dir", str(run_dir), "--eval-freq", "256", "--eval-episodes", "2",
        "--checkpoint-freq", "256", "--no-progress",
        "--env-kwargs", *ENV_KWARGS, "--hyperparams", *SMALL[algo],
    ]


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("train") / "ppo"
    assert cli_train.main(_argv("ppo", run_dir)) == 0
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
    assert config["env_kwargs"] == {"max_episode_steps": EPISODE, "goal_range": [2.0, 2.2]}
    assert config["hyperparams"]["policy_kwargs"] == "dict(net_arch=[16, 16])"
    assert config["hyperparams"]["n_envs"] == 2
    assert config["versions"]["smartcar_gym"] and config["versions"]["stable_baselines3"]
    assert config["command"].startswith(f"smartcar-train --algo {algo} --n-envs 2")
    assert config["resumes"] == [] and config["save_replay_buffer"] is False
    assert config["eval_start"] == 256  # default: half the run, so evaluations at 256 and 512

    names = sorted(p.name for p in (run_dir / "checkpoints").iterdir())
    assert names[:3] == ["ckpt_256_steps.json", "ckpt_256_steps.zip",
                         "ckpt_256_steps_vecnormalize.pkl"]
    info = json.loads((run_dir / "checkpoints" / "ckpt_256_steps.json").read_text())
    assert info == {"segment": 0, "monitor_episodes": [256 // 2 // EPISODE] * 2}
    assert f"ckpt_{steps}_steps.zip" in names and not [n for n in names if n.startswith(".")]

    for rank in (0, 1):
        monitor = pd.read_csv(run_dir / "monitor" / f"seg0_{rank}.monitor.csv", skiprows=1)
        assert list(monitor.columns) == ["r", "l", "t", "is_success"]
        assert len(monitor) == steps // 2 // EPISODE and (monitor["l"] == EPISODE).all()

    evals = np.load(run_dir / "eval" / "evaluations.npz")
    assert evals["timesteps"].tolist()[:2] == [256, 512]
    n_evals = len(evals["timesteps"])
    assert evals["successes"].shape == evals["final_distances"].shape == (n_evals, 2)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["num_timesteps"] == steps and not summary["interrupted"]
    assert summary["final_eval"]["timesteps"] == steps
    assert algo_class(algo).load(run_dir / "model.zip").num_timesteps == steps
    umask = os.umask(0)
    os.umask(umask)
    modes = {oct(p.stat().st_mode & 0o777) for p in run_dir.rglob("*") if p.is_file()}
    assert modes == {oct(0o666 & ~umask)}  # checkpoints as monitor files: not 0600


@pytest.mark.slow
def test_ppo_run_folder(ppo_run):
    _check_run_folder(ppo_run, "ppo", 512)
    hp = yaml.safe_load((ppo_run / "config.yaml").read_text())["hyperparams"]
    assert (hp["n_steps"], hp["batch_size"], hp["n_epochs"]) == (128, 64, 2)
    # the run's Adam took the multi-tensor update (optimizers.foreach_updates), saved with it
    from stable_baselines3 import PPO

    saved = PPO.load(ppo_run / "model.zip", device="cpu")
    assert saved.policy.optimizer.param_groups[0]["foreach"] is True


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_off_policy_run_folder(algo, tmp_path):
    run_dir = tmp_path / algo
    assert cli_train.main(_argv(algo, run_dir)) == 0
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
    assert cli_train.main(["--resume", str(run_dir), "--timesteps", "1024", "--no-progress"]) == 0

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

    # 2 envs x 8 episodes of 32 steps per segment; the second segment starts at step 512
    episodes = load_training_episodes(run_dir)
    assert episodes["steps"].tolist() == list(range(EPISODE, 1024 + 1, EPISODE))


@pytest.mark.slow
def test_resume_after_a_kill_counts_the_repeated_episodes_once(ppo_run, tmp_path):
    """A run killed between checkpoints went on past its last one: as if killed just before
    writing ckpt_512, after 512 steps of episodes."""
    run_dir = tmp_path / "killed"
    shutil.copytree(ppo_run, run_dir)
    for path in (run_dir / "checkpoints").glob("ckpt_512_steps*"):
        path.unlink()
    assert cli_train.main(["--resume", str(run_dir), "--timesteps", "768", "--no-progress",
                       "--eval-freq", "0"]) == 0
    [resume] = yaml.safe_load((run_dir / "config.yaml").read_text())["resumes"]
    assert resume["from_timesteps"] == 256
    assert resume["kept_episodes"] == {"segment": 0, "per_env": [4, 4]}

    from smartcar_gym.agents.plots import load_training_episodes

    # 8 episodes of the first run up to step 256 (not its 16), then 16 of the resumed run
    episodes = load_training_episodes(run_dir)
    assert episodes["steps"].tolist() == list(range(EPISODE, 768 + 1, EPISODE))


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
    args = cli_train.build_parser().parse_args(_argv("ppo", tmp_path / "x"))
    config = runs.new_config(args, "test")
    config["checkpoint_freq"] = 0
    run_dir = tmp_path / "interrupted"
    result = cli_train.train(config, run_dir, progress=False, extra_callbacks=[_InterruptAt(300)])
    assert result.interrupted and result.num_timesteps == 300
    assert (run_dir / "checkpoints" / "ckpt_300_steps.zip").is_file()
    assert (run_dir / "checkpoints" / "ckpt_300_steps_vecnormalize.pkl").is_file()
    assert algo_class("ppo").load(run_dir / "model.zip").num_timesteps == 300
    assert json.loads((run_dir / "summary.json").read_text())["interrupted"] is True
    assert cli_train.main(["--resume", str(run_dir), "--no-progress", "--eval-freq", "0"]) == 0
    assert algo_class("ppo").load(run_dir / "model.zip").num_timesteps >= 512


def _buffer_pos(path: Path) -> int:
    import pickle

    with open(path, "rb") as f:
        return int(pickle.load(f).pos)


@pytest.mark.slow
def test_sac_resume_keeps_the_replay_buffer_only_if_it_was_saved(tmp_path, capsys):
    run_dir = tmp_path / "sac"
    argv = [*_argv("sac", run_dir, timesteps=256), "--eval-freq", "0", "--save-replay-buffer"]
    assert cli_train.main(argv) == 0
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["save_replay_buffer"] is True
    assert _buffer_pos(run_dir / "checkpoints" / "ckpt_256_steps_replay_buffer.pkl") == 128
    without = tmp_path / "sac_without_buffer"
    shutil.copytree(run_dir, without)
    (without / "checkpoints" / "ckpt_256_steps_replay_buffer.pkl").unlink()
    capsys.readouterr()

    # the choice is stored: no --save-replay-buffer needed; 2 envs x 192 steps in the buffer
    assert cli_train.main(["--resume", str(run_dir), "--timesteps", "384", "--no-progress"]) == 0
    assert "replay buffer" not in capsys.readouterr().err
    names = sorted(p.name for p in (run_dir / "checkpoints").glob("*replay_buffer.pkl"))
    assert names == ["ckpt_384_steps_replay_buffer.pkl"]
    assert _buffer_pos(run_dir / "checkpoints" / names[0]) == 192

    assert cli_train.main(["--resume", str(without), "--timesteps", "384", "--no-progress"]) == 0
    assert ("SAC resumes with an empty replay buffer: no replay buffer was saved with "
            "ckpt_256_steps.zip") in capsys.readouterr().err
    assert _buffer_pos(without / "checkpoints" / "ckpt_384_steps_replay_buffer.pkl") == 64


@pytest.mark.slow
def test_a_run_that_failed_to_start_is_simply_started_again(tmp_path, capsys):
    run_dir = tmp_path / "retry"
    argv = [*_argv("ppo", run_dir, timesteps=128), "--n-envs", "1", "--eval-freq", "0"]
    with pytest.raises(SystemExit) as exc:
        cli_train.main([*argv, "--hyperparams", "learning_rate=-1"])
    assert exc.value.code == 2 and "Invalid learning rate" in capsys.readouterr().err
    assert not run_dir.exists()
    # a folder left behind by a start that failed before this was fixed
    (run_dir / "monitor").mkdir(parents=True)
    (run_dir / "monitor" / "seg0_0.monitor.csv").write_text('#{"t_start": 0}\nr,l,t\n')
    (run_dir / "config.yaml").write_text("algo: ppo\n")
    assert cli_train.main(argv) == 0
    assert "starting it again" in capsys.readouterr().err
    assert algo_class("ppo").load(run_dir / "model.zip").num_timesteps == 128
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["n_timesteps"] == 128


@pytest.mark.slow
@pytest.mark.parametrize(("signum", "exit_code"), [
    (signal.SIGINT, cli_train.INTERRUPTED_EXIT_CODE),
    (signal.SIGTERM, cli_train.TERMINATED_EXIT_CODE),
])
def test_a_signal_to_the_process_group_saves_a_checkpoint(signum, exit_code, tmp_path):
    """Ctrl-C in a terminal (or ``timeout``, a batch system...) signals the whole process
    group: the workers ignore it and the main process stops cleanly."""
    run_dir = tmp_path / "signal"
    argv = _argv("ppo", run_dir, timesteps=1_000_000)
    proc = subprocess.Popen(
        [sys.executable, "-m", "smartcar_gym.agents.cli_train", *argv],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
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
        os.killpg(proc.pid, signum)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == exit_code, err
    assert f"Interrupted ({signal.Signals(signum).name}): checkpoint saved" in err
    assert f"smartcar-train --resume {run_dir}" in err
    assert "interrupted" in out
    checkpoints = list((run_dir / "checkpoints").glob("ckpt_*_steps.zip"))
    assert checkpoints and (run_dir / "model.zip").is_file()
