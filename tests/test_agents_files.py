"""Atomic files, checkpoints, signals and the command lines' argument errors (exit code 2)."""

import os
import pickle
import signal
import zipfile

import numpy as np
import pytest

from smartcar_gym.agents import cli_eval, cli_train
from smartcar_gym.agents.atomic_files import output_path_error
from smartcar_gym.agents.callbacks import (
    CheckpointCallback,
    SuccessEvalCallback,
    atomic_path,
    atomic_write_text,
    checkpoint_steps,
    find_latest_checkpoint,
    replay_buffer_path_for,
    vecnormalize_path_for,
)
from smartcar_gym.agents.run_control import StopOnSigint


def test_atomic_write_replaces_the_file_or_leaves_it_untouched(tmp_path):
    target = tmp_path / "sub" / "model.zip"
    atomic_write_text(target, "first")
    assert target.read_text() == "first"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half a file")
        raise RuntimeError("killed while writing")
    assert target.read_text() == "first"
    assert sorted(p.name for p in target.parent.iterdir()) == ["model.zip"]
    with atomic_path(target) as tmp:
        assert tmp.parent == target.parent and tmp.suffix == ".zip"
        tmp.write_text("second")
    assert target.read_text() == "second"
    assert sorted(p.name for p in target.parent.iterdir()) == ["model.zip"]


def test_vecnormalize_file_names(tmp_path):
    assert vecnormalize_path_for(tmp_path / "model.zip").name == "vecnormalize.pkl"
    assert vecnormalize_path_for(tmp_path / "best_model.zip").name == "best_model_vecnormalize.pkl"
    assert (vecnormalize_path_for(tmp_path / "ckpt_5_steps.zip").name
            == "ckpt_5_steps_vecnormalize.pkl")


def test_latest_checkpoint_skips_incomplete_ones(tmp_path):
    folder = tmp_path / "checkpoints"
    folder.mkdir()
    assert find_latest_checkpoint(tmp_path, normalize=True) is None
    for steps in (512, 1024, 4096):
        (folder / f"ckpt_{steps}_steps.zip").write_text("zip")
    for steps in (512, 1024):
        (folder / f"ckpt_{steps}_steps_vecnormalize.pkl").write_text("pkl")
    (folder / ".ckpt_9999_steps.abc.zip").write_text("temporary file of a killed run")
    assert find_latest_checkpoint(tmp_path, normalize=True).name == "ckpt_1024_steps.zip"
    assert find_latest_checkpoint(tmp_path, normalize=False).name == "ckpt_4096_steps.zip"


def _exit_code(main, argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    return exc.value.code, capsys.readouterr().err


@pytest.mark.parametrize(("argv", "message"), [
    (["--algo", "dqn"], "argument --algo: invalid choice: 'dqn'"),
    (["--hyperparams", "learning_rate"], "argument --hyperparams: expected key=value"),
    (["--env-kwargs", "=0.5"], "argument --env-kwargs: expected key=value"),
    (["--hyperparams", "n_step=64"], "unknown hyperparameter(s) for ppo: n_step"),
    (["--hyperparams", "policy_kwargs=dict(net_arch=os.system)"], "cannot read"),
    (["--n-envs", "0"], "expected a positive integer"),
    (["--timesteps", "many"], "expected an integer"),
    (["--eval-start", "-1"], "argument --eval-start: expected a non-negative integer, got '-1'"),
    (["--env", "Unknown-v0"], "unknown env id 'Unknown-v0'"),  # not the hyperparameters
])
def test_train_argument_errors_exit_2_with_a_clear_message(argv, message, capsys, tmp_path):
    code, err = _exit_code(cli_train.main, [*argv, "--run-dir", str(tmp_path / "run")], capsys)
    assert code == 2
    assert message in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(("freq", "start", "schedule"), [
    (20_000, 0, [20_000, 40_000, 60_000]),
    (20_000, 40_000, [40_000, 60_000, 80_000]),  # a multiple: evaluated there
    (20_000, 124_928, [140_000, 160_000, 180_000]),  # half of the default 249,856 steps
    (256, 256, [256, 512, 768]),
])
def test_evaluations_run_at_multiples_of_eval_freq_from_eval_start(freq, start, schedule):
    callback = SuccessEvalCallback(None, "eval", None, freq, eval_start=start)
    steps, due = 0, []
    for _ in range(3):
        steps = callback._next_after(steps)
        due.append(steps)
    assert due == schedule
    assert callback._next_after(schedule[0] - 1) == schedule[0]


def test_train_refuses_to_overwrite_or_resume_badly(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text("algo: ppo\n")
    (run / "model.zip").write_bytes(b"a finished run")
    code, err = _exit_code(cli_train.main, ["--run-dir", str(run), "--timesteps", "64"], capsys)
    assert code == 2 and "already holds a run" in err and f"--resume {run}" in err
    code, err = _exit_code(cli_train.main, ["--resume", str(run), "--seed", "3"], capsys)
    assert code == 2 and "--seed cannot be changed" in err
    code, err = _exit_code(cli_train.main, ["--resume", str(tmp_path / "nothing")], capsys)
    assert code == 2 and "config.yaml not found" in err
    assert sorted(p.name for p in run.iterdir()) == ["config.yaml", "model.zip"]


def test_output_path_errors(tmp_path):
    (tmp_path / "file").write_text("")
    assert output_path_error(tmp_path / "new" / "deeper" / "x.json") is None
    assert output_path_error(tmp_path / "file") is None  # overwritten
    assert output_path_error(tmp_path) == f"{tmp_path} is a directory"
    assert output_path_error(tmp_path / "file" / "x.json") == (
        f"cannot create {tmp_path / 'file' / 'x.json'}: {tmp_path / 'file'} is not a folder")
    assert "is not a folder" in output_path_error(tmp_path / "file" / "a" / "b.png")


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_stop_training_at_the_next_step(signum, capsys):
    before = signal.getsignal(signum)
    with StopOnSigint() as stop:
        os.kill(os.getpid(), signum)
        assert stop.requested and stop.signum == signum
        assert stop._on_step() is False  # SB3 then ends learn()
        with pytest.raises(KeyboardInterrupt):  # a second signal stops at once
            os.kill(os.getpid(), signum)
    assert signal.getsignal(signum) is before
    name = "Ctrl-C" if signum == signal.SIGINT else "SIGTERM"
    assert f"{name}: stopping after this step and saving a checkpoint" in capsys.readouterr().err


def test_checkpoints_keep_the_replay_buffer_of_the_latest_one_only(tmp_path):
    import gymnasium as gym
    from stable_baselines3 import SAC

    model = SAC("MlpPolicy", gym.make("Pendulum-v1"), buffer_size=100,
                policy_kwargs={"net_arch": [4]}, device="cpu")
    callback = CheckpointCallback(tmp_path, save_freq=0, save_replay_buffer=True)
    callback.init_callback(model)
    model.replay_buffer.add(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 1)),
                            np.zeros(1), np.zeros(1), [{}])
    first = callback.save()
    assert first == tmp_path / "checkpoints" / "ckpt_0_steps.zip"
    assert replay_buffer_path_for(first).name == "ckpt_0_steps_replay_buffer.pkl"
    assert replay_buffer_path_for(first).is_file()
    model.num_timesteps = 7
    second = callback.save()
    names = sorted(p.name for p in (tmp_path / "checkpoints").iterdir() if p.suffix != ".json")
    assert names == ["ckpt_0_steps.zip", "ckpt_7_steps.zip", "ckpt_7_steps_replay_buffer.pkl"]
    with open(replay_buffer_path_for(second), "rb") as f:
        assert pickle.load(f).size() == 1
    assert checkpoint_steps(second) == 7
    model.num_timesteps = 9
    plain = CheckpointCallback(tmp_path, 0)
    plain.init_callback(model)
    plain.save()
    assert not replay_buffer_path_for(tmp_path / "checkpoints" / "ckpt_9_steps.zip").exists()


@pytest.mark.parametrize(("argv", "message"), [
    ([], "one of the arguments --model --pretrained --random is required"),
    (["--model", "missing.zip"], "--model: no such file: missing.zip"),
    (["--pretrained", "--episodes", "0"], "expected a positive integer"),
    (["--pretrained", "--video", "out.avi"], "must end in .gif or .mp4"),
    (["--pretrained", "--env-kwargs", "goal_range"], "expected key=value"),
    (["--pretrained", "--algo", "a2c"], "invalid choice: 'a2c'"),
])
def test_eval_argument_errors_exit_2_with_a_clear_message(argv, message, capsys):
    code, err = _exit_code(cli_eval.main, argv, capsys)
    assert code == 2
    assert message in err


def test_eval_model_without_a_run_needs_algo(tmp_path, capsys):
    model = tmp_path / "lonely.zip"
    with zipfile.ZipFile(model, "w") as archive:
        archive.writestr("data", "not read before the algorithm is known")
    code, err = _exit_code(cli_eval.main, ["--model", str(model)], capsys)
    assert code == 2 and "pass --algo" in err
