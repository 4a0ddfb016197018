"""Atomic files, checkpoint discovery and the command lines' argument errors (exit code 2)."""

import pytest

from smartcar_gym.agents import evaluate, train
from smartcar_gym.agents.callbacks import (
    atomic_path,
    atomic_write_text,
    find_latest_checkpoint,
    vecnormalize_path_for,
)


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
    (["--env", "Unknown-v0"], "no hyperparameters for env 'Unknown-v0'"),
])
def test_train_argument_errors_exit_2_with_a_clear_message(argv, message, capsys, tmp_path):
    code, err = _exit_code(train.main, [*argv, "--run-dir", str(tmp_path / "run")], capsys)
    assert code == 2
    assert message in err
    assert not (tmp_path / "run").exists()


def test_train_refuses_to_overwrite_or_resume_badly(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text("algo: ppo\n")
    code, err = _exit_code(train.main, ["--run-dir", str(run), "--timesteps", "64"], capsys)
    assert code == 2 and "already holds a run" in err and f"--resume {run}" in err
    code, err = _exit_code(train.main, ["--resume", str(run), "--seed", "3"], capsys)
    assert code == 2 and "--seed cannot be changed" in err
    code, err = _exit_code(train.main, ["--resume", str(tmp_path / "nothing")], capsys)
    assert code == 2 and "config.yaml not found" in err
    (run / "config.yaml").write_text("algo: ppo\nhyperparams: {normalize: true}\n")
    code, err = _exit_code(train.main, ["--resume", str(run)], capsys)
    assert code == 2 and "no complete checkpoint" in err


@pytest.mark.parametrize(("argv", "message"), [
    ([], "one of the arguments --model --pretrained --random is required"),
    (["--model", "missing.zip"], "--model: no such file: missing.zip"),
    (["--pretrained", "--episodes", "0"], "expected a positive integer"),
    (["--pretrained", "--video", "out.avi"], "must end in .gif or .mp4"),
    (["--pretrained", "--env-kwargs", "goal_range"], "expected key=value"),
    (["--pretrained", "--algo", "a2c"], "invalid choice: 'a2c'"),
])
def test_eval_argument_errors_exit_2_with_a_clear_message(argv, message, capsys):
    code, err = _exit_code(evaluate.main, argv, capsys)
    assert code == 2
    assert message in err


def test_eval_model_without_a_run_needs_algo(tmp_path, capsys):
    model = tmp_path / "lonely.zip"
    model.write_bytes(b"not read before the algorithm is known")
    code, err = _exit_code(evaluate.main, ["--model", str(model)], capsys)
    assert code == 2 and "pass --algo" in err
