"""Bad input to smartcar-train and smartcar-eval: a one-line error and exit code 2 (never a
traceback), and a start-up that fails leaves no run folder behind (or one that can be started
again)."""

import zipfile

import pytest
import yaml

from smartcar_gym.agents import cli_eval, cli_train

# One env in this process and a tiny network: model construction is the only cost.
TINY = ["--n-envs", "1", "--timesteps", "64", "--eval-freq", "0", "--no-progress"]


def _exit_code(main, argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    return exc.value.code, capsys.readouterr().err


@pytest.mark.parametrize(("argv", "messages"), [
    (["--hyperparams", "n_envs=abc"], ["n_envs must be a whole number >= 1, got 'abc'"]),
    (["--hyperparams", "n_timesteps=1.5"], ["n_timesteps must be a whole number >= 1"]),
    (["--hyperparams", "gamma=abc"], ["gamma must be a number in [0, 1], got 'abc'"]),
    (["--hyperparams", "seed=3"], ["hyperparameter seed cannot be set: use --seed"]),
    (["--hyperparams", "device=cuda"], ["hyperparameter device cannot be set: use --device"]),
    (["--hyperparams", "verbose=1"], ["hyperparameter verbose cannot be set"]),
    (["--hyperparams", "tensorboard_log=tb"], ["tensorboard_log cannot be set", "<run-dir>/tb"]),
    (["--hyperparams", "_init_setup_model=false"], ["_init_setup_model cannot be set"]),
    (["--hyperparams", "batch_size=abc"],
     ["PPO refuses its hyperparameters: TypeError", "batch_size=abc"]),
    (["--hyperparams", "learning_rate=-1"],
     ["PPO refuses its hyperparameters: ValueError: Invalid learning rate", "learning_rate=-1"]),
    (["--n-envs", "2", "--env-kwargs", "bogus=1"],
     ["cannot make SmartCar-v0 with bogus=1", "unexpected keyword argument 'bogus'"]),
    (["--n-envs", "2", "--env-kwargs", "goal_range=abc"],
     ["goal_range must be a (min, max) pair of numbers, got 'abc'"]),
])
def test_train_refuses_bad_input_and_leaves_nothing(argv, messages, tmp_path, capsys):
    run = tmp_path / "runs" / "run"
    code, err = _exit_code(cli_train.main, [*TINY, "--run-dir", str(run), *argv], capsys)
    assert code == 2, err
    assert err.startswith("usage: smartcar-train") and "Traceback" not in err
    for message in messages:
        assert "smartcar-train: error: " in err and message in err, err
    assert list(tmp_path.iterdir()) == []  # not even the runs/ folder


def test_a_failed_start_in_the_default_folder_can_be_retried(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for _ in range(2):  # the second attempt is not refused as "already holds a run"
        code, err = _exit_code(cli_train.main, [*TINY, "--hyperparams", "learning_rate=-1"], capsys)
        assert code == 2 and "Invalid learning rate" in err, err
        assert list(tmp_path.iterdir()) == []


def test_a_folder_left_by_a_failed_start_is_started_again(tmp_path, capsys):
    """What older versions left behind: config.yaml and monitor/ but no checkpoint."""
    run = tmp_path / "run"
    (run / "monitor").mkdir(parents=True)
    (run / "monitor" / "seg0_0.monitor.csv").write_text('#{"t_start": 0}\nr,l,t\n')
    (run / "checkpoints").mkdir()
    (run / "config.yaml").write_text("algo: ppo\n")
    (run / "notes.txt").write_text("not ours")
    code, err = _exit_code(cli_train.main, ["--resume", str(run)], capsys)
    assert code == 2 and "lacks the key(s)" in err
    code, err = _exit_code(cli_train.main, [*TINY, "--run-dir", str(run), "--hyperparams",
                                        "learning_rate=-1"], capsys)
    assert code == 2 and "Invalid learning rate" in err, err
    assert "already holds a run" not in err
    assert f"{run} holds a run that never saved a checkpoint or a model; starting it again" in err
    assert "removed config.yaml, monitor/, checkpoints/" in err
    assert sorted(p.name for p in run.iterdir()) == ["notes.txt"]


def test_a_folder_with_a_checkpoint_or_a_best_model_is_not_restarted(tmp_path, capsys):
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text("algo: ppo\n")
    (run / "best_model.zip").write_bytes(b"zip")
    code, err = _exit_code(cli_train.main, [*TINY, "--run-dir", str(run)], capsys)
    assert code == 2 and "saved no checkpoint (it cannot be resumed) but has best_model.zip" in err
    (run / "checkpoints" / "ckpt_64_steps.zip").write_bytes(b"zip")
    code, err = _exit_code(cli_train.main, [*TINY, "--run-dir", str(run)], capsys)
    assert code == 2 and f"already holds a run; continue it with --resume {run}" in err
    assert (run / "config.yaml").read_text() == "algo: ppo\n"


def test_run_dir_that_is_a_file(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    code, err = _exit_code(cli_train.main, [*TINY, "--run-dir", str(tmp_path / "file")], capsys)
    assert code == 2 and f"--run-dir: cannot create {tmp_path / 'file' / 'config.yaml'}" in err


def _write_config(run, **config):
    run.mkdir(parents=True, exist_ok=True)
    (run / "config.yaml").write_text(yaml.safe_dump(config))


def test_resume_names_what_is_missing_or_broken(tmp_path, capsys):
    run = tmp_path / "run"
    _write_config(run, algo="ppo", env="SmartCar-v0", seed=0, hyperparams={"normalize": True})
    code, err = _exit_code(cli_train.main, ["--resume", str(run)], capsys)
    assert code == 2
    assert (f"--resume: {run / 'config.yaml'} lacks the key(s) n_envs, n_timesteps, eval_freq, "
            "eval_episodes, checkpoint_freq") in err
    # keys given on the command line are not missing
    code, err = _exit_code(cli_train.main, ["--resume", str(run), "--timesteps", "64",
                                        "--eval-freq", "0"], capsys)
    assert "lacks the key(s) n_envs, eval_episodes, checkpoint_freq" in err
    (run / "config.yaml").write_text("algo: [ppo\n")
    code, err = _exit_code(cli_train.main, ["--resume", str(run)], capsys)
    assert code == 2 and "is not valid YAML" in err
    _write_config(run, algo="ppo", env="SmartCar-v0", seed=0, n_envs=1, n_timesteps=64,
                  hyperparams={"normalize": True}, eval_freq=0, eval_episodes=1,
                  checkpoint_freq=0)
    code, err = _exit_code(cli_train.main, ["--resume", str(run)], capsys)
    assert code == 2 and "no complete checkpoint" in err and "start it again" in err


@pytest.fixture(scope="module")
def saved_models(tmp_path_factory):
    """Untrained PPO and SAC models of SmartCar-v0 (tiny networks), without run folders."""
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC

    folder = tmp_path_factory.mktemp("models")
    env = gym.make("SmartCar-v0")
    kwargs = {"policy_kwargs": {"net_arch": [8]}, "device": "cpu"}
    PPO("MlpPolicy", env, n_steps=64, **kwargs).save(folder / "ppo.zip")
    SAC("MlpPolicy", env, buffer_size=10, **kwargs).save(folder / "sac.zip")
    env.close()
    return folder


@pytest.mark.parametrize(("model", "algo", "message"), [
    ("ppo.zip", "sac", "ppo.zip holds a PPO model, not SAC: pass --algo ppo"),
    ("sac.zip", "td3", "sac.zip holds a SAC model, not TD3: pass --algo sac"),
    ("sac.zip", "ppo", "sac.zip holds a SAC model, not PPO: pass --algo sac"),
])
def test_eval_model_of_another_algorithm(saved_models, model, algo, message, capsys):
    code, err = _exit_code(cli_eval.main, ["--model", str(saved_models / model), "--algo", algo,
                                           "--episodes", "1", "--no-progress"], capsys)
    assert code == 2 and message in err, err


def test_eval_model_that_is_not_a_model(tmp_path, capsys):
    text = tmp_path / "model.zip"
    text.write_text("not a zip")
    code, err = _exit_code(cli_eval.main, ["--model", str(text), "--algo", "ppo"], capsys)
    assert code == 2 and f"--model: {text} is not a model (SB3 models are .zip files)" in err
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(other, "w") as archive:
        archive.writestr("hello.txt", "a zip, but not a model")
    code, err = _exit_code(cli_eval.main, ["--model", str(other), "--algo", "ppo"], capsys)
    assert code == 2 and f"--model: cannot load {other} as a PPO model" in err


@pytest.fixture
def no_evaluation(monkeypatch):
    """Fail the test if an evaluation starts: the error must come before."""
    def evaluate_policy_episodes(*args, **kwargs):
        raise AssertionError("the evaluation ran before the error")

    monkeypatch.setattr(cli_eval, "evaluate_policy_episodes", evaluate_policy_episodes)


@pytest.mark.parametrize(("argv", "message"), [
    (["--n-envs", "2", "--env-kwargs", "bogus=1"],
     "cannot make SmartCar-v0 with bogus=1: SmartCar-v0 got an unexpected keyword "
     "argument 'bogus'; it takes arena_size, "),
    (["--env-kwargs", "goal_range=abc"], "goal_range must be a (min, max) pair of numbers"),
    (["--env", "Nope-v0"], "unknown env id 'Nope-v0': Environment Nope doesn't exist; "
                           "registered smartcar ids: SmartCar-v0, "),
    (["--json", "{tmp}"], "--json: {tmp} is a directory"),
    (["--plot", "{tmp}/file/paths.png"], "--plot: cannot create {tmp}/file/paths.png: "
                                         "{tmp}/file is not a folder"),
    (["--video", "{tmp}/file/sub/run.mp4"], "--video: cannot create {tmp}/file/sub/run.mp4: "
                                            "{tmp}/file is not a folder"),
    (["--plot", "{tmp}/paths.xyz"], "--plot: cannot write .xyz images"),
])
def test_eval_bad_env_kwargs_and_outputs_fail_before_evaluating(argv, message, tmp_path, capsys,
                                                                no_evaluation):
    (tmp_path / "file").write_text("")
    argv = [a.format(tmp=tmp_path) for a in argv]
    code, err = _exit_code(cli_eval.main, ["--random", "--episodes", "1", "--no-progress", *argv],
                           capsys)
    assert code == 2, err
    assert "Traceback" not in err and message.format(tmp=tmp_path) in err, err


def test_eval_missing_vecnormalize_file(saved_models, capsys, no_evaluation):
    argv = ["--model", str(saved_models / "ppo.zip"), "--algo", "ppo", "--vecnormalize",
            "none.pkl"]
    code, err = _exit_code(cli_eval.main, argv, capsys)
    assert code == 2 and "--vecnormalize: no such file: none.pkl" in err


@pytest.mark.parametrize("batched", [[], ["--vectorization", "batched"]], ids=["seq", "batched"])
def test_the_box_policy_on_the_dict_goal_env_is_one_line(batched, capsys):
    code, err = _exit_code(cli_eval.main, ["--pretrained", "--env", "SmartCarGoal-v0",
                                           "--episodes", "1", "--no-progress", *batched], capsys)
    lines = [line for line in err.splitlines() if "error:" in line]
    assert code == 2 and "Traceback" not in err and len(lines) == 1
    assert "the model expects observations of shape (" in lines[0]
    assert "but SmartCarGoal-v0 gives a Dict of " in lines[0]
