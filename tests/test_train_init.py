"""smartcar-train --init: a new run that starts from another model's weights and normaliser
statistics (a fine-tune: the mapless BARN policy starts from the known-map one), and its
refusals in one line."""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from smartcar_gym.agents import cli_train
from smartcar_gym.agents.hyperparams import algo_class

TINY = ["n_steps=32", "batch_size=32", "n_epochs=1", "policy_kwargs=dict(net_arch=[16, 16])"]


def _argv(run_dir: Path, *extra: str, timesteps: int = 64) -> list[str]:
    return ["--algo", "ppo", "--engine", "planar", "--n-envs", "2", "--seed", "3",
            "--timesteps", str(timesteps), "--run-dir", str(run_dir), "--eval-freq", "0",
            "--checkpoint-freq", "0", "--no-progress", "--env-kwargs", "max_episode_steps=16",
            "--hyperparams", *TINY, *extra]


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("init") / "source"
    assert cli_train.main(_argv(run_dir)) == 0
    return run_dir


def _weights(path: Path) -> dict[str, torch.Tensor]:
    return algo_class("ppo").load(path).policy.state_dict()


def test_a_run_from_init_starts_with_its_weights_and_normaliser(source, tmp_path):
    run_dir = tmp_path / "tuned"
    # a learning rate of 0: the weights stay the source's through the run
    assert cli_train.main(_argv(run_dir, "learning_rate=0.0", "--init", str(source))) == 0
    before, after = _weights(source / "model.zip"), _weights(run_dir / "model.zip")
    assert all(torch.equal(before[k], after[k]) for k in before)
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert config["init"] == {"model": str((source / "model.zip").resolve()),
                              "normalizer": str((source / "vecnormalize.pkl").resolve())}
    # the normaliser went on from the source's statistics: its count is theirs plus the 64
    # steps' observations and the two cars' first ones (the source's own: 66)
    with open(source / "vecnormalize.pkl", "rb") as f:
        old = pickle.load(f)
    with open(run_dir / "vecnormalize.pkl", "rb") as f:
        new = pickle.load(f)
    assert old.obs_rms.count == pytest.approx(66, abs=1e-3)
    assert new.obs_rms.count == pytest.approx(old.obs_rms.count + 66, abs=1e-3)
    # a run without --init (another seed) starts elsewhere
    fresh = tmp_path / "fresh"
    assert cli_train.main([*_argv(fresh, "learning_rate=0.0"), "--seed", "4"]) == 0
    other = _weights(fresh / "model.zip")
    assert not all(torch.equal(before[k], other[k]) for k in before)
    assert yaml.safe_load((fresh / "config.yaml").read_text())["init"] is None


@pytest.mark.parametrize("extra, message", [
    (["--hyperparams", *TINY[:3], "policy_kwargs=dict(net_arch=[8])"],
     "its network is not the run's"),
    (["--env-kwargs", "max_episode_steps=16", "obs_noise=0.1"], None),
])
def test_a_model_that_does_not_fit_is_one_line(source, tmp_path, capsys, extra, message):
    argv = _argv(tmp_path / "run", "--init", str(source))
    if message is None:  # another env: SmartCarNav-v0's observation is not SmartCar-v0's
        argv = [*argv, "--env", "SmartCarNav-v0"]
        message = "its normaliser .* does not fit the run's observations"
    else:
        argv = [*argv, *extra]
    with pytest.raises(SystemExit) as exit_info:
        cli_train.main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--init" in err
    assert re.search(message, err), err
    assert not (tmp_path / "run" / "config.yaml").exists()


def test_init_with_resume_or_without_a_model_is_one_line(source, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli_train.main(["--resume", str(source), "--init", str(source)])
    assert exit_info.value.code == 2
    assert "--init starts a new run" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        cli_train.main(_argv(tmp_path / "run", "--init", str(tmp_path / "nothing.zip")))
    assert exit_info.value.code == 2
    assert "--init" in capsys.readouterr().err
    np.testing.assert_equal((tmp_path / "run" / "config.yaml").exists(), False)


def test_a_bare_zip_without_its_normaliser_is_refused_when_the_run_normalises(source, tmp_path,
                                                                             capsys):
    """The model alone, outside its run folder: the weights would start on fresh statistics
    (a fine-tune that fails from its first step), and the pickle beside it is not looked for."""
    bare = tmp_path / "elsewhere"
    bare.mkdir()
    (bare / "model.zip").write_bytes((source / "model.zip").read_bytes())
    (bare / "vecnormalize.pkl").write_bytes((source / "vecnormalize.pkl").read_bytes())
    with pytest.raises(SystemExit) as exit_info:
        cli_train.main(_argv(tmp_path / "run", "--init", str(bare / "model.zip")))
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "no normaliser comes with this model" in err and "run folder" in err
    assert not (tmp_path / "run" / "config.yaml").exists()
    # without normalising, the bare model is fine
    assert cli_train.main(_argv(tmp_path / "raw", "normalize=False", "--init",
                                str(bare / "model.zip"))) == 0
