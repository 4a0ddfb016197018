"""--engine on smartcar-train, smartcar-eval, smartcar-tune, smartcar-calibrate and
smartcar-ros bringup: parsed, passed to the env (or the simulator), one short run each."""

from __future__ import annotations

import json

import pytest
import yaml

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")
pytest.importorskip("stable_baselines3", reason="the CLIs need the train extra")

from smartcar_gym.agents import cli_eval, cli_train  # noqa: E402
from smartcar_gym.calibration import cli as calibrate_cli  # noqa: E402
from smartcar_gym.ros.bringup import start_robot  # noqa: E402
from smartcar_gym.ros.cli import build_parser as ros_parser  # noqa: E402


def test_eval_engine_reaches_the_env(tmp_path):
    path = tmp_path / "e.json"
    assert cli_eval.main(["--random", "--episodes", "2", "--seed", "5", "--no-progress",
                          "--engine", "mujoco", "--json", str(path),
                          "--env-kwargs", "max_episode_steps=10"]) == 0
    data = json.loads(path.read_text())
    assert data["env_kwargs"]["engine"] == "mujoco"
    assert [r["length"] for r in data["episode_records"]] == [10, 10]


def test_eval_refuses_an_unknown_engine(capsys):
    with pytest.raises(SystemExit):
        cli_eval.main(["--random", "--engine", "ode"])
    err = capsys.readouterr().err
    assert "--engine: invalid choice: 'ode'" in err and "mujoco" in err


def test_train_stores_the_engine_with_the_run_and_resume_refuses_it(tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert cli_train.main(["--engine", "mujoco", "--n-envs", "1", "--timesteps", "128",
                       "--run-dir", str(run_dir), "--eval-freq", "0", "--no-progress",
                       "--hyperparams", "n_steps=128", "batch_size=64", "n_epochs=1"]) == 0
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert config["env_kwargs"] == {"engine": "mujoco"}
    with pytest.raises(SystemExit):
        cli_train.main(["--resume", str(run_dir), "--engine", "pybullet"])
    assert "--engine cannot be given with it" in capsys.readouterr().err


@pytest.mark.xdist_group("ray")
def test_tune_puts_the_engine_in_every_trial_s_env_kwargs(tmp_path):
    pytest.importorskip("ray", reason="smartcar-tune needs the ray extra")
    from smartcar_gym.scale import tune as tune_cli

    args = tune_cli.build_parser().parse_args(["--engine", "mujoco", "--out",
                                               str(tmp_path / "sweep")])
    sweep, _ = tune_cli.new_sweep(args)
    assert sweep.env_kwargs["engine"] == "mujoco"
    resumed = tune_cli.build_parser().parse_args(["--engine", "mujoco", "--resume",
                                                  str(tmp_path / "sweep")])
    with pytest.raises(tune_cli.SweepSetupError, match="--engine cannot be changed"):
        tune_cli.resumed_sweep(resumed)


@pytest.mark.slow
def test_calibrate_on_mujoco(tmp_path, capsys):
    path = tmp_path / "c.json"
    assert calibrate_cli.main(["--engine", "mujoco", "--side", "0.5", "--json", str(path)]) == 0
    figures = json.loads(path.read_text())
    # the car's effective track on MuJoCo: 0.322 m (pybullet's: 0.33, the shipped calibration)
    assert figures["base_width_m"]["after"] == pytest.approx(0.322, abs=0.01)


def test_ros_bringup_engine_is_parsed_and_starts_a_mujoco_robot(shipped_model, shipped_config):
    assert ros_parser().parse_args(["bringup"]).engine == "pybullet"
    assert ros_parser().parse_args(["bringup", "--engine", "mujoco"]).engine == "mujoco"
    robot = start_robot(shipped_model, shipped_config, "hardware", "mujoco")
    try:
        assert robot.sim.engine == "mujoco" and robot.pose().up_z > 0.99
    finally:
        robot.sim.close()
