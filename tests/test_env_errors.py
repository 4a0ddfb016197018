"""Bad input: every error the env raises names what was wrong."""

from __future__ import annotations

import re
from importlib import resources

import gymnasium as gym
import numpy as np
import pytest
import yaml

import smartcar_gym  # noqa: F401
from smartcar_gym.controller.config import ControllerConfigError
from smartcar_gym.envs.smartcar_env import SmartCarEnv


@pytest.fixture(scope="module")
def env():
    env = gym.make("SmartCar-v0")
    env.reset(seed=0)
    yield env
    env.close()


# -- actions -------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("action", "match"),
    [
        ([np.nan, 0.0], r"action must be finite, got \[nan, 0\.0\]"),
        ([0.0, np.inf], r"action must be finite, got \[0\.0, inf\]"),
        ([-np.inf, 1.0], r"action must be finite, got \[-inf, 1\.0\]"),
        ([0.1, 0.2, 0.3], r"shape \(2,\).*got shape \(3,\)"),
        (0.5, r"shape \(2,\).*got shape \(\)"),
        ([[0.1, 0.2]], r"got shape \(1, 2\)"),
        ("fast", r"action must be 2 numbers .*'fast'"),
    ],
)
def test_bad_action_raises_value_error_naming_it(env, action, match):
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_bad_action_leaves_the_episode_usable(env):
    env.reset(seed=0)
    with pytest.raises(ValueError):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))
    obs, *_ = env.step(np.zeros(2, dtype=np.float32))
    assert obs in env.observation_space


# -- constructor kwargs --------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (
            {"controller_mode": "fast"},
            r"controller_mode must be None or one of .*'hardware'.*got 'fast'",
        ),
        pytest.param(  # gym.make warns about the unknown mode before the env refuses it
            {"render_mode": "video"}, r"render_mode must be None or one of .*got 'video'",
            marks=pytest.mark.filterwarnings("ignore:.*render_mode='video'"),
        ),
        ({"max_linear": 0}, r"max_linear must be a positive number, got 0"),
        ({"max_linear": -1}, r"max_linear must be a positive number, got -1"),
        ({"max_angular": float("nan")}, r"max_angular must be a positive number, got nan"),
        ({"max_angular": "2"}, r"max_angular must be a positive number, got '2'"),
        ({"arena_size": -1.0}, r"arena_size must be a positive number, got -1\.0"),
        ({"physics_hz": 5}, r"1 / physics_hz \(physics_hz=5\) must be a number of seconds in "
                            r"\[0\.0001, 0\.02\]"),
        ({"physics_hz": 1e7}, r"1 / physics_hz \(physics_hz=10000000\.0\) must be .*\[0\.0001"),
        ({"max_substep_s": 0.05}, r"max_substep_s must be a number of seconds in "
                                  r"\[0\.0001, 0\.02\] .*got 0\.05"),
        ({"max_substep_s": 1e-7}, r"max_substep_s must be .*got 1e-07"),
        ({"max_substep_s": "0.01"}, r"max_substep_s must be .*got '0\.01'"),
        ({"max_substep_s": True}, r"max_substep_s must be .*got True"),
        ({"max_substep_s": 0.01, "physics_hz": 500}, r"pass max_substep_s or physics_hz, not both"),
        ({"goal_range": (2, 1)}, r"goal_range must be \(min, max\).*got \(2\.0, 1\.0\)"),
        ({"goal_range": (-0.5, 1)}, r"0 <= min <= max"),
        ({"goal_range": (0.5, 3.0)}, r"goal_range max \(3\.0 m\) must lie inside the arena"),
        (
            {"goal_range": (0.3, 0.7), "arena_size": 1.2},
            r"goal_range max \(0\.7 m\).*half size 0\.6 m",
        ),
        ({"goal_tolerance": 0}, r"goal_tolerance must be a positive number, got 0"),
        ({"goal_tolerance": float("inf")}, r"goal_tolerance must be a positive number, got inf"),
        ({"goal_range": (1,)}, r"goal_range must be a \(min, max\) pair of numbers, got \(1,\)"),
        ({"goal_range": "ab"}, r"goal_range must be a \(min, max\) pair of finite numbers"),
        ({"physics_hz": "500"}, r"physics_hz must be a positive number, got '500'"),
        ({"render_width": 8000}, r"render_width must be at most 4096 \(rgb_array images are at "
                                 r"most 4096 px a side\), got 8000"),
        ({"goal_tolerance": 3.0}, r"goal_tolerance \(3\.0 m\) must be smaller than the arena"),
        ({"render_mode": 1}, r"render_mode must be None or one of \('human', 'rgb_array'\), got 1"),
        ({"max_linear": 1e6}, r"max_linear=1000000\.0 and max_angular=2\.0 ask a wheel for "
                              r"1e\+06 m/s.*ticks_meter 4100.*at most 239\.759 m/s"),
        ({"render_width": -5}, r"render_width must be a positive integer, got -5"),
        ({"render_height": 0}, r"render_height must be a positive integer, got 0"),
        ({"render_height": 240.5}, r"render_height must be a positive integer, got 240\.5"),
        ({"wheel_contact": "cylinder"},
         r"wheel_contact must be one of \('sphere', 'urdf'\), got 'cylinder'"),
    ],
)
def test_bad_kwargs_raise_value_error_naming_them(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make("SmartCar-v0", **kwargs)


@pytest.mark.parametrize("kwarg", ["model", "controller_config"])
def test_file_kwargs_of_the_wrong_type_are_named(kwarg):
    with pytest.raises(TypeError, match=rf"{kwarg} must be a file path or a .*got int: 123"):
        gym.make("SmartCar-v0", **{kwarg: 123})


def test_numpy_scalars_are_accepted_as_numbers():
    env = SmartCarEnv(max_linear=np.float32(0.4), max_angular=np.int64(1))
    try:
        assert env.max_linear == pytest.approx(0.4) and env.max_angular == 1.0
    finally:
        env.close()


def test_missing_model_file(tmp_path):
    missing = tmp_path / "nowhere" / "robot.urdf"
    with pytest.raises(FileNotFoundError, match=re.escape(f"no such robot description: {missing}")):
        gym.make("SmartCar-v0", model=str(missing))


def test_controller_config_without_base_width_names_file_and_key(tmp_path):
    shipped = resources.files("smartcar_gym") / "config" / "smartcar_arbotix.yaml"
    data = yaml.safe_load(shipped.read_text("utf-8"))
    del data["controllers"]["base_controller"]["base_width"]
    path = tmp_path / "no_width.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(
        ControllerConfigError,
        match=re.escape(f"{path}: controllers.base_controller: required key 'base_width'"),
    ):
        gym.make("SmartCar-v0", controller_config=str(path))


def test_controller_config_that_does_not_exist(tmp_path):
    path = tmp_path / "missing.yaml"
    with pytest.raises(ControllerConfigError, match=re.escape(f"{path}: controller config file")):
        gym.make("SmartCar-v0", controller_config=path)


def test_physics_hz_is_a_deprecated_alias_of_the_substep():
    with pytest.warns(DeprecationWarning, match=r"physics_hz is deprecated.*max_substep_s=0\.002"):
        env = gym.make("SmartCar-v0", physics_hz=500)
    try:
        assert env.unwrapped.max_substep_s == 0.002
        assert env.unwrapped.sim.max_substep_s == 0.002
    finally:
        env.close()


def test_any_controller_rate_steps_one_period(tmp_path):
    """The step is one controller period whatever the rate (no physics-rate multiple needed)."""
    shipped = resources.files("smartcar_gym") / "config" / "smartcar_arbotix.yaml"
    data = yaml.safe_load(shipped.read_text("utf-8"))
    data["controllers"]["base_controller"]["rate"] = 30
    path = tmp_path / "fast_rate.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    env = gym.make("SmartCar-v0", controller_config=path)
    try:
        env.reset(seed=0)
        env.step(np.zeros(2, dtype=np.float32))
        assert env.unwrapped.sim.now_ns == 33_333_333  # round(1e9 / 30)
        assert env.metadata["render_fps"] == 30  # one step per controller update
    finally:
        env.close()


# -- reset options -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "goal", [(np.nan, 0.0), (0.0, np.inf), (1.0, 2.0, 3.0), 1.0]
)
def test_bad_goal_option(env, goal):
    with pytest.raises(ValueError, match=r"options\['goal'\] must be a finite \(x, y\) pair"):
        env.reset(options={"goal": goal})


def test_goal_option_is_used(env):
    obs, info = env.reset(seed=0, options={"goal": (0.6, -0.8)})
    assert np.array_equal(env.unwrapped.goal, [0.6, -0.8])
    assert info["distance"] == pytest.approx(1.0, abs=1e-3)
    np.testing.assert_allclose(obs[14:17], [0.6, -0.8, 1.0], atol=1e-6)


def test_goal_option_outside_the_arena(env):
    with pytest.raises(ValueError, match=r"options\[.goal.\] \[3\.0, 0\.0\] lies outside"):
        env.reset(options={"goal": (3.0, 0.0)})


def test_a_bad_goal_is_refused_before_the_world_is_rebuilt(env):
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.array([1.0, 0.0], dtype=np.float32))
    pose = env.unwrapped.robot.pose()
    assert pose.x > 0.05  # it has driven off the start
    with pytest.raises(ValueError, match=r"options\['goal'\] must be a finite"):
        env.reset(options={"goal": (np.nan, 0.0)})
    assert env.unwrapped.robot.pose() == pose  # the car is where it was: nothing was rebuilt


def test_a_closed_env_refuses_steps_until_reset_reopens_it():
    env = gym.make("SmartCar-v0", render_mode="rgb_array")
    first, _ = env.reset(seed=0)
    env.close()
    for name, call in (("step", lambda: env.unwrapped.step(np.zeros(2))),
                       ("render", env.unwrapped.render)):
        with pytest.raises(RuntimeError, match=rf"SmartCarEnv is closed: call reset\(\) to "
                                               rf"reopen it before {name}\(\)"):
            call()
    again, _ = env.reset(seed=0)  # a new client, the same episode
    assert np.array_equal(again, first)
    assert env.render().shape == (360, 480, 3)
    env.close()


def test_a_directly_built_env_needs_reset_before_step_and_render():
    env = SmartCarEnv(controller_mode="sim", render_mode="rgb_array")
    try:
        for name, call in (("step", lambda: env.step(np.zeros(2))), ("render", env.render)):
            with pytest.raises(gym.error.ResetNeeded, match=rf"call reset\(\) before {name}"):
                call()
        env.reset(seed=0)
        env.step(np.zeros(2))
    finally:
        env.close()


def test_complex_action_and_unknown_reset_option(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must be real numbers, got \[\(0\.5\+1j\), 0j\]"):
        env.step(np.array([0.5 + 1j, 0.0]))
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['gaol'\]; .* 'goal'"):
        env.reset(options={"gaol": (1.0, 0.0)})
    with pytest.raises(ValueError, match=r"options\['goal'\] must be a finite \(x, y\) pair"):
        env.reset(options={"goal": "north"})


def test_yaml_sim_true_picks_the_sim_mode_unless_told_otherwise(tmp_path):
    shipped = resources.files("smartcar_gym") / "config" / "smartcar_arbotix.yaml"
    data = yaml.safe_load(shipped.read_text("utf-8"))
    data["sim"] = True  # the driver's fake mode
    path = tmp_path / "fake.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    modes = {}
    for given in (None, "hardware"):
        env = gym.make("SmartCar-v0", controller_config=path, controller_mode=given)
        modes[given] = env.unwrapped.robot.mode
        env.close()
    assert modes == {None: "sim", "hardware": "hardware"}
    env = gym.make("SmartCar-v0")  # the shipped YAML has no `sim`: hardware
    assert env.unwrapped.robot.mode == "hardware"
    env.close()


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"model": ""}, ValueError, r"model is an empty path: pass a file path, or None"),
    ({"controller_config": ""}, ValueError, r"controller_config is an empty path"),
    ({"wheels": "x"}, Exception, r"wheels='x': expected a dict \{'left'"),
    ({"wheels": 5}, Exception, r"wheels=5: expected a dict"),
    ({"package_path": 123}, Exception, r"package_path=123: expected a list of folders"),
])
def test_unclear_arguments_are_named_through_gym_make(kwargs, error, match):
    with pytest.raises(error, match=match):
        gym.make("SmartCar-v0", **kwargs)


def test_reset_options_must_be_a_dict(env):
    with pytest.raises(TypeError, match=r"^reset options must be a dict of 'goal', got str: "
                                        r"'notadict'"):
        env.reset(options="notadict")
    env.reset(seed=0)  # still usable
