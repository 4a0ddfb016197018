"""smartcar-eval loads a normaliser (a pickle) only from a file the user named or from the
model's own place (a smartcar-train run, an exported policy, an rl-baselines3-zoo run), says
which one it loaded, and warns when it loaded none."""

import json
import pickle
import shutil
from collections import OrderedDict
from contextlib import contextmanager
from importlib import resources

import pytest
import yaml

from smartcar_gym.agents import cli_eval, cli_train, policies
from smartcar_gym.agents.models import (
    SHIPPED,
    TRAIN_RUN,
    ZOO_RUN,
    find_run_config,
    find_vecnormalize,
    locate_model,
)
from smartcar_gym.agents.zoo_runs import Unreadable, load_zoo_yaml

EPISODES = ["--episodes", "2", "--no-progress"]


class _Payload:
    """Unpickling it creates ``marker``: proof that a pickle was loaded."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _plant(path, marker):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(_Payload(marker)))


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A PPO model trained for 128 steps with VecNormalize (one env, no evaluation)."""
    run_dir = tmp_path_factory.mktemp("trust") / "tiny"
    argv = ["--n-envs", "1", "--timesteps", "128", "--run-dir", str(run_dir), "--eval-freq",
            "0", "--no-progress", "--env-kwargs", "max_episode_steps=30", "--hyperparams",
            "n_steps=64", "batch_size=64", "n_epochs=1", "policy_kwargs=dict(net_arch=[8])"]
    assert cli_train.main(argv) == 0
    return run_dir


def _eval(argv, tmp_path, capsys):
    out = tmp_path / "eval.json"
    assert cli_eval.main([*argv, *EPISODES, "--json", str(out)]) == 0
    printed = capsys.readouterr()
    return json.loads(out.read_text()), printed.out, printed.err


def test_an_unnamed_pickle_near_a_model_is_not_loaded(tiny_run, tmp_path, capsys):
    """A downloaded model with a crafted vecnormalize.pkl beside it (and in the folder above,
    with a config.yaml: where older versions looked)."""
    marker = tmp_path / "code-ran"
    folder = tmp_path / "download" / "model"
    folder.mkdir(parents=True)
    shutil.copyfile(tiny_run / "model.zip", folder / "policy.zip")
    for path in (folder / "vecnormalize.pkl", folder / "policy_vecnormalize.pkl",
                 folder.parent / "vecnormalize.pkl"):
        _plant(path, marker)
    (folder.parent / "config.yaml").write_text("algo: ppo\nenv: SmartCar-v0\n")
    data, out, err = _eval(["--model", str(folder / "policy.zip"), "--algo", "ppo"], tmp_path,
                           capsys)
    assert not marker.exists()
    assert data["normalizer"] is None and data["normalizer_source"] == "none (see the warning)"
    [warning] = data["warnings"]
    assert "no normaliser loaded" in warning and "pass --vecnormalize FILE" in warning
    assert f"{folder / 'policy_vecnormalize.pkl'}, {folder / 'vecnormalize.pkl'}" in warning
    assert "is not loaded unnamed: it is a pickle" in warning
    assert err.count(f"smartcar-eval: warning: {warning}") == 2  # before and after the table
    assert "none (see the warning)" in out


def test_a_named_normaliser_is_loaded_and_reported(tiny_run, tmp_path, capsys):
    stats = tmp_path / "stats.pkl"
    shutil.copyfile(tiny_run / "vecnormalize.pkl", stats)
    shutil.copyfile(tiny_run / "model.zip", tmp_path / "lonely.zip")
    data, _, err = _eval(["--model", str(tmp_path / "lonely.zip"), "--algo", "ppo",
                          "--vecnormalize", str(stats)], tmp_path, capsys)
    assert data["normalizer"] == str(stats) and data["warnings"] == []
    assert f"smartcar-eval: normaliser: {stats} (named with --vecnormalize)" in err


def test_a_run_that_lost_its_normaliser_is_named_in_the_warning(tiny_run, tmp_path, capsys):
    run_dir = tmp_path / "run"
    shutil.copytree(tiny_run, run_dir)
    (run_dir / "vecnormalize.pkl").unlink()
    data, _, _ = _eval(["--model", str(run_dir / "model.zip")], tmp_path, capsys)
    assert data["normalizer"] is None
    [warning] = data["warnings"]
    assert (f"the smartcar-train run {run_dir} trained with VecNormalize but "
            f"{run_dir / 'vecnormalize.pkl'} does not exist") in warning


def test_run_folders_assign_each_model_its_own_statistics(tiny_run):
    files = locate_model(tiny_run / "model.zip")
    assert (files.place, files.folder, files.normalizer) == (TRAIN_RUN, tiny_run,
                                                             tiny_run / "vecnormalize.pkl")
    [checkpoint] = (tiny_run / "checkpoints").glob("ckpt_*_steps.zip")
    assert find_vecnormalize(checkpoint) == checkpoint.with_name(
        checkpoint.stem + "_vecnormalize.pkl")
    assert find_run_config(checkpoint)["algo"] == "ppo"
    assert locate_model(tiny_run).model == tiny_run / "model.zip"  # a run folder: its model


@pytest.fixture
def fake_package(tiny_run, tmp_path, monkeypatch):
    """The shipped-policy folder of a package, with a crafted pickle where older versions
    looked first, and a config.yaml in the folder above."""
    marker = tmp_path / "code-ran"
    folder = tmp_path / "smartcar_gym" / "pretrained"
    folder.mkdir(parents=True)
    shutil.copyfile(tiny_run / "model.zip", folder / "policy.zip")
    shutil.copyfile(tiny_run / "vecnormalize.pkl", folder / "vecnormalize.pkl")
    shipped = resources.files("smartcar_gym") / "pretrained" / "provenance.json"
    provenance = {**json.loads(shipped.read_text()), "env_kwargs": {"max_episode_steps": 30}}
    (folder / "provenance.json").write_text(json.dumps(provenance))
    _plant(folder / "ppo_smartcar_vecnormalize.pkl", marker)
    (folder.parent / "config.yaml").write_text("algo: sac\nenv: Elsewhere-v0\n")

    @contextmanager
    def pretrained_files(name="default"):
        yield folder

    monkeypatch.setattr(policies, "pretrained_files", pretrained_files)
    return folder, marker


def test_pretrained_reads_only_the_package_files(fake_package, tmp_path, capsys):
    folder, marker = fake_package
    data, out, err = _eval(["--pretrained"], tmp_path, capsys)
    assert not marker.exists()
    assert (data["algo"], data["env"], data["env_kwargs"]) == ("ppo", "SmartCar-v0",
                                                               {"max_episode_steps": 30})
    assert data["normalizer"] == str(folder / "vecnormalize.pkl") and data["warnings"] == []
    assert f"(that of the {SHIPPED} {folder})" in err


def _zoo_run(tiny_run, log, normalize=True, config_extra=None, args_extra=None):
    """What ``python -m rl_zoo3.train --algo ppo --env SmartCar-v0 --gym-packages smartcar_gym
    -f log`` writes, with zoo's YAML (``yaml.dump`` of ``OrderedDict``)."""
    run = log / "ppo" / "SmartCar-v0_1"
    params = run / "SmartCar-v0"
    params.mkdir(parents=True)
    shutil.copyfile(tiny_run / "model.zip", run / "SmartCar-v0.zip")
    shutil.copyfile(tiny_run / "model.zip", run / "best_model.zip")
    if normalize:
        shutil.copyfile(tiny_run / "vecnormalize.pkl", params / "vecnormalize.pkl")
    config = {"env_kwargs": {"max_episode_steps": 30}, "n_envs": 1, "n_timesteps": 128.0,
              "normalize": normalize, "policy": "MlpPolicy",
              "policy_kwargs": "dict(net_arch=[8])", **(config_extra or {})}
    args = {"algo": "ppo", "env": "SmartCar-v0", "env_kwargs": None, "eval_freq": 25000,
            "gym_packages": ["smartcar_gym"], "seed": 0, **(args_extra or {})}
    for name, values in (("config.yml", config), ("args.yml", args)):
        text = yaml.dump(OrderedDict(sorted(values.items())))
        (params / name).write_text(text)
    assert (params / "config.yml").read_text().startswith(
        "!!python/object/apply:collections.OrderedDict")
    return run


def test_a_zoo_run_is_evaluated_with_its_normaliser(tiny_run, tmp_path, capsys):
    run = _zoo_run(tiny_run, tmp_path / "logs")
    stats = run / "SmartCar-v0" / "vecnormalize.pkl"
    ours, _, _ = _eval(["--model", str(tiny_run / "model.zip")], tmp_path, capsys)
    for model in (run / "SmartCar-v0.zip", run, run / "best_model.zip"):
        data, out, err = _eval(["--model", str(model)], tmp_path, capsys)
        assert data["normalizer"] == str(stats) and data["warnings"] == []
        assert f"normaliser: {stats} (that of the {ZOO_RUN} {run})" in err
        assert (data["algo"], data["env"], data["env_kwargs"]) == ("ppo", "SmartCar-v0",
                                                                   {"max_episode_steps": 30})
        # the same model and statistics as the smartcar-train run: the same episodes
        assert data["episode_records"] == ours["episode_records"]
        assert "│ normaliser" in out


def test_a_zoo_run_without_normalize_loads_none_and_does_not_warn(tiny_run, tmp_path, capsys):
    run = _zoo_run(tiny_run, tmp_path / "logs", normalize=False)
    data, _, _ = _eval(["--model", str(run)], tmp_path, capsys)
    assert data["normalizer"] is None and data["warnings"] == []
    assert data["normalizer_source"] == (f"none (the {ZOO_RUN} {run} trained without "
                                         "VecNormalize)")


def test_zoo_yaml_is_read_without_running_code(tiny_run, tmp_path, capsys):
    marker = tmp_path / "code-ran"
    run = _zoo_run(tiny_run, tmp_path / "logs",
                   config_extra={"callback": "placeholder"}, args_extra={"env_kwargs": None})
    config = run / "SmartCar-v0" / "config.yml"
    config.write_text(config.read_text().replace(
        "- placeholder", f"- !!python/object/apply:os.system ['touch {marker}']"))
    assert load_zoo_yaml(config)["callback"] == Unreadable("!!python/object/apply:os.system")
    data, _, _ = _eval(["--model", str(run)], tmp_path, capsys)
    assert not marker.exists() and data["normalizer"] is not None
    args = run / "SmartCar-v0" / "args.yml"
    args.write_text(args.read_text().replace(
        "env_kwargs\n    - null", f"env_kwargs\n    - !!python/object/apply:os.system ['touch "
                                  f"{marker}']"))
    with pytest.raises(SystemExit) as exc:
        cli_eval.main(["--model", str(run), *EPISODES])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and not marker.exists()
    assert f"{args}: env_kwargs must be a mapping of plain values" in err
    assert "pass --env-kwargs instead" in err


def test_zoo_yaml_keeps_ordered_dicts_and_tuples_as_plain_values(tmp_path):
    path = tmp_path / "config.yml"
    path.write_text(yaml.dump(OrderedDict([("normalize", "{'norm_obs': True}"),
                                           ("net", (64, 64)), ("n_envs", 8)])))
    assert load_zoo_yaml(path) == {"normalize": "{'norm_obs': True}", "net": (64, 64),
                                   "n_envs": 8}


def test_a_folder_that_is_no_run_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli_eval.main(["--model", str(tmp_path)])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert f"--model: {tmp_path} is a folder but not a run folder" in err


@pytest.mark.parametrize("parser", [cli_eval.build_parser, cli_train.build_parser])
def test_help_says_model_and_normaliser_files_are_pickles(parser):
    text = " ".join(parser().format_help().split())
    assert "are pickles" in text and "trust" in text
