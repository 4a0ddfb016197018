"""smartcar-train when things go wrong: a full disk, a read-only run folder, a config.yaml that
does not match its checkpoints; and the modes of the files it writes."""

import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
import yaml

from smartcar_gym.agents import cli_train, vec_envs
from smartcar_gym.agents.atomic_files import atomic_write_text, file_mode
from smartcar_gym.agents.callbacks import CheckpointCallback

# A model's "data" as SB3 writes it: the policy class names the algorithm.
PPO_DATA = {"policy_class": {"__module__": "stable_baselines3.common.policies"}}

FULL_DISK = """
import errno, sys
from stable_baselines3.common.base_class import BaseAlgorithm
from smartcar_gym.agents import cli_train

save = BaseAlgorithm.save

def save_on_a_full_disk(self, path, *args, **kwargs):
    if self.num_timesteps >= 512:  # the first checkpoint (256 steps) is written
        raise OSError(errno.ENOSPC, "No space left on device", str(path))
    return save(self, path, *args, **kwargs)

if __name__ == "__main__":
    BaseAlgorithm.save = save_on_a_full_disk
    sys.exit(cli_train.main(sys.argv[1:]))
"""


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.slow
def test_a_full_disk_stops_the_run_closes_the_workers_and_keeps_the_checkpoint(tmp_path):
    script = tmp_path / "full_disk.py"
    script.write_text(FULL_DISK)
    run_dir = tmp_path / "run"
    argv = ["--n-envs", "2", "--timesteps", "2048", "--checkpoint-freq", "256", "--eval-freq",
            "0", "--run-dir", str(run_dir), "--no-progress", "--env-kwargs",
            "max_episode_steps=32", "--hyperparams", "n_steps=128", "batch_size=64",
            "n_epochs=1", "policy_kwargs=dict(net_arch=[8])"]
    proc = subprocess.Popen([sys.executable, str(script), *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=180)  # before the fix: it never ended
        deadline = time.monotonic() + 20  # the forkserver leaves once its parent is gone
        while _group_alive(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not _group_alive(proc.pid), "a worker process survived the run"
    finally:
        if _group_alive(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == cli_train.FAILED_EXIT_CODE, err
    assert "Traceback" not in err
    [line] = [line for line in err.splitlines() if line.startswith("smartcar-train: error:")]
    checkpoint = run_dir / "checkpoints" / "ckpt_256_steps.zip"
    assert "the run stopped: OSError: No space left on device: " in line
    assert f"the last checkpoint, {checkpoint} (256 steps), is intact" in line
    assert f"continue with smartcar-train --resume {run_dir}" in line
    assert f"(traceback in {run_dir / 'error.log'})" in line
    assert "OSError: [Errno 28] No space left on device" in (run_dir / "error.log").read_text()
    names = sorted(p.name for p in (run_dir / "checkpoints").iterdir())
    assert names == ["ckpt_256_steps.json", "ckpt_256_steps.zip",
                     "ckpt_256_steps_vecnormalize.pkl"]  # no temporary file is left
    with zipfile.ZipFile(checkpoint) as archive:
        assert archive.testzip() is None


def _fake_run(run_dir: Path, algo: str = "ppo") -> None:
    """A run folder with a config.yaml and one checkpoint (only its "data" is read before
    the checks)."""
    (run_dir / "checkpoints").mkdir(parents=True)
    (run_dir / "monitor").mkdir()
    config = {"algo": algo, "env": "SmartCar-v0", "seed": 0, "n_envs": 2, "n_timesteps": 512,
              "hyperparams": {"normalize": True}, "eval_freq": 0, "eval_episodes": 1,
              "checkpoint_freq": 256}
    (run_dir / "config.yaml").write_text(yaml.safe_dump(config))
    with zipfile.ZipFile(run_dir / "checkpoints" / "ckpt_256_steps.zip", "w") as archive:
        archive.writestr("data", json.dumps(PPO_DATA))
    (run_dir / "checkpoints" / "ckpt_256_steps_vecnormalize.pkl").write_bytes(b"statistics")


@pytest.fixture
def no_workers(monkeypatch):
    """Fail the test if env workers start: the error must come before."""
    def make_vec_env(*args, **kwargs):
        raise AssertionError("workers were started before the error")

    monkeypatch.setattr(vec_envs, "make_vec_env", make_vec_env)


def test_resume_with_a_config_of_another_algorithm_is_refused(tmp_path, capsys, no_workers):
    run_dir = tmp_path / "run"
    _fake_run(run_dir, algo="sac")
    with pytest.raises(SystemExit) as exc:
        cli_train.main(["--resume", str(run_dir), "--no-progress"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "Traceback" not in err
    assert (f"--resume: {run_dir / 'config.yaml'} says algo: sac but "
            f"{run_dir / 'checkpoints' / 'ckpt_256_steps.zip'} holds a PPO model") in err


def test_resume_into_a_read_only_folder_is_refused(tmp_path, capsys, no_workers,
                                                  monkeypatch):
    """What ``os.access`` says of the folders decides (root may write anywhere, so the real
    thing is tested below, as a user)."""
    from smartcar_gym.agents import runs

    run_dir = tmp_path / "run"
    _fake_run(run_dir)
    read_only = {run_dir / "monitor"}
    monkeypatch.setattr(runs.os, "access", lambda path, mode: Path(path) not in read_only)
    with pytest.raises(SystemExit) as exc:
        cli_train.main(["--resume", str(run_dir), "--no-progress"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "Traceback" not in err
    assert (f"smartcar-train: error: --resume: {run_dir / 'monitor'} is not writable: the run "
            "cannot continue there") in err


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into read-only folders")
def test_resume_into_a_read_only_folder_exits_2_with_one_line(tmp_path):
    run_dir = tmp_path / "run"
    _fake_run(run_dir)
    for folder in (run_dir / "checkpoints", run_dir / "monitor", run_dir):
        folder.chmod(0o555)
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "smartcar_gym.agents.cli_train", "--resume", str(run_dir),
             "--no-progress"], capture_output=True, text=True, timeout=120)
    finally:
        for folder in (run_dir, run_dir / "checkpoints", run_dir / "monitor"):
            folder.chmod(0o755)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert (f"smartcar-train: error: --resume: {run_dir} is not writable: the run cannot "
            "continue there") in proc.stderr


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_run_files_get_the_mode_of_any_new_file(umask, tmp_path):
    import gymnasium as gym
    from stable_baselines3 import PPO

    previous = os.umask(umask)
    try:
        assert file_mode() == 0o666 & ~umask
        atomic_write_text(tmp_path / "config.yaml", "algo: ppo\n")
        with open(tmp_path / "monitor.csv", "w") as f:  # as Monitor and TensorBoard write
            f.write("r,l,t\n")
        model = PPO("MlpPolicy", gym.make("Pendulum-v1"), n_steps=64,
                    policy_kwargs={"net_arch": [4]}, device="cpu")
        callback = CheckpointCallback(tmp_path, 0)
        callback.init_callback(model)
        callback.save()
    finally:
        os.umask(previous)
    modes = {p.relative_to(tmp_path).as_posix(): oct(p.stat().st_mode & 0o777)
             for p in tmp_path.rglob("*") if p.is_file()}
    assert set(modes.values()) == {oct(0o666 & ~umask)}, modes
    assert "checkpoints/ckpt_0_steps.zip" in modes and "config.yaml" in modes
