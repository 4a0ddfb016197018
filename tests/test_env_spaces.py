"""Action and observation spaces, and what the observation entries mean."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import smartcar_gym  # noqa: F401


@pytest.fixture
def env():
    env = gym.make("SmartCar-v0")
    yield env
    env.close()


@pytest.fixture
def sim_env():
    env = gym.make("SmartCarSim-v0")
    yield env
    env.close()


def test_action_space_is_unit_box(env):
    space = env.action_space
    assert isinstance(space, spaces.Box)
    assert space.shape == (2,) and space.dtype == np.float32
    assert np.array_equal(space.low, [-1, -1]) and np.array_equal(space.high, [1, 1])


def test_observation_space_is_finite_float32_box_matching_the_names(env):
    space = env.observation_space
    assert isinstance(space, spaces.Box)
    assert space.dtype == np.float32
    assert space.shape == (len(env.unwrapped.observation_names),) == (21,)
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    assert np.all(space.low < space.high)
    half = 5.0 / 2
    # spot-check the documented table (A = arena_size / 2 = 2.5 m by default)
    assert space.high[0] == pytest.approx(2 * half) and space.low[0] == pytest.approx(-2 * half)
    assert space.high[2] == 1 and space.low[3] == -1
    assert space.high[6] == pytest.approx(math.pi, rel=1e-6)
    assert space.low[16] == 0 and space.high[16] == pytest.approx(4 * half)
    assert np.array_equal(space.low[17:19], [-1, -1])
    assert np.array_equal(space.high[17:19], [1, 1])
    assert space.high[19] == pytest.approx(2 * half) and space.low[20] == pytest.approx(-2 * half)


def test_observation_bounds_follow_arena_size():
    env = gym.make("SmartCar-v0", arena_size=2.0, goal_range=(0.3, 0.6))
    try:
        assert env.observation_space.high[0] == pytest.approx(2.0)
        assert env.observation_space.high[16] == pytest.approx(4.0)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarSim-v0"])
def test_observations_always_inside_the_space(env_id):
    env = gym.make(env_id)
    try:
        env.action_space.seed(1)
        obs, _ = env.reset(seed=1)
        assert obs in env.observation_space
        for _ in range(60):
            obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            assert obs.dtype == np.float32 and obs in env.observation_space
            assert np.all(np.isfinite(obs)) and math.isfinite(reward)
            if terminated or truncated:
                obs, _ = env.reset()
                assert obs in env.observation_space
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarSim-v0"])
def test_reset_observation_is_odometry_origin_and_goal(env_id):
    env = gym.make(env_id)
    try:
        obs, info = env.reset(seed=5)
        goal = env.unwrapped.goal
        assert np.array_equal(obs[0:6], [0, 0, 1, 0, 0, 0])  # pose, cos/sin yaw, twist
        # the goal in base_link is the goal itself: odom origin, heading +x
        np.testing.assert_allclose(obs[14:16], goal, atol=1e-6)
        assert obs[16] == pytest.approx(np.hypot(*goal), abs=1e-6)
        # the start pose is the odometry origin: the odometry distance is the true one
        assert obs[16] == pytest.approx(info["distance"], abs=1e-3)
        assert np.array_equal(obs[17:19], [0, 0])  # no previous action yet
        np.testing.assert_allclose(obs[19:21], goal, atol=1e-6)  # goal in the odom frame
        assert np.array_equal(info["odom_pose"], [0, 0, 0])
        np.testing.assert_allclose(info["pose"], [0, 0, 0], atol=1e-3)
        assert 0.5 <= info["distance"] <= 1.5 + 1e-3  # default goal_range
    finally:
        env.close()


def test_previous_action_entries_are_the_last_clipped_action(env):
    env.reset(seed=0)
    obs, *_ = env.step(np.array([0.3, -0.7], dtype=np.float32))
    assert np.array_equal(obs[17:19], np.array([0.3, -0.7], dtype=np.float32))
    obs, *_ = env.step(np.array([5.0, -2.0], dtype=np.float32))
    assert np.array_equal(obs[17:19], [1.0, -1.0])
    obs, *_ = env.step([-0.25, 0.5])  # a plain list is accepted too
    assert np.array_equal(obs[17:19], np.array([-0.25, 0.5], dtype=np.float32))


def test_out_of_range_actions_are_clipped():
    """[5, -5] behaves exactly like [1, -1]: same observations, rewards and infos."""
    big, unit = gym.make("SmartCar-v0"), gym.make("SmartCar-v0")
    try:
        big.reset(seed=11)
        unit.reset(seed=11)
        for _ in range(3):
            a = big.step(np.array([5.0, -5.0], dtype=np.float32))
            b = unit.step(np.array([1.0, -1.0], dtype=np.float32))
            assert np.array_equal(a[0], b[0])
            assert a[1:4] == b[1:4]
            assert np.array_equal(a[4]["pose"], b[4]["pose"])
    finally:
        big.close()
        unit.close()


def test_sim_mode_heading_and_goal_in_base_frame_after_a_quarter_turn():
    """Turning in place by pi/2 (exactly, in sim mode) moves a goal ahead to the right side."""
    env = gym.make("SmartCarSim-v0", max_angular=math.pi)
    try:
        env.reset(seed=0, options={"goal": (1.0, 0.0)})
        for _ in range(10):  # 0.5 * pi rad/s for 10 x 0.1 s
            obs, _, _, _, info = env.step(np.array([0.0, 0.5], dtype=np.float32))
        assert info["odom_pose"][2] == pytest.approx(math.pi / 2, abs=1e-9)
        assert info["pose"][2] == pytest.approx(math.pi / 2, abs=1e-6)
        np.testing.assert_allclose(obs[0:2], [0, 0], atol=1e-6)
        np.testing.assert_allclose(obs[2:4], [0, 1], atol=1e-6)  # cos, sin of yaw
        assert obs[5] == pytest.approx(math.pi / 2, rel=1e-6)  # odom angular.z
        np.testing.assert_allclose(obs[14:17], [0, -1, 1], atol=1e-6)  # ahead, left, distance
    finally:
        env.close()


def test_sim_mode_wheel_velocities_match_the_commanded_twist(sim_env):
    """Straight at 0.25 m/s: each wheel turns at v / r; obs[4] is the odometry's linear.x."""
    sim_env.reset(seed=0)
    obs, *_ = sim_env.step(np.array([0.5, 0.0], dtype=np.float32))
    radius = sim_env.unwrapped.robot_model.wheel_radius_m
    np.testing.assert_allclose(np.abs(obs[10:14]), 0.25 / radius, rtol=1e-5)
    assert obs[4] == pytest.approx(0.25)
    assert np.all(np.abs(obs[6:10]) <= np.pi)  # wrapped wheel angles


def test_observation_names_say_which_wheel_each_entry_is(env):
    names = env.unwrapped.observation_names
    wheels = ["left_front_wheel_joint", "left_back_wheel_joint",
              "right_front_wheel_joint", "right_back_wheel_joint"]
    assert names[6:14] == tuple([f"{w}.position" for w in wheels]
                                + [f"{w}.velocity" for w in wheels])
    env.reset(seed=0)
    for _ in range(10):  # turn left in place: left wheels back, right wheels forward
        obs, *_ = env.step(np.array([0.0, 1.0], dtype=np.float32))
    states = env.unwrapped.robot.joint_states()
    by_name = dict(zip(states.name, states.velocity, strict=True))
    for i, wheel in enumerate(wheels):
        assert obs[10 + i] == pytest.approx(by_name[wheel], rel=1e-5)
        # the wheel axes all point +y in the model: forward rolling is a positive joint speed
        assert (obs[10 + i] > 1.0) == wheel.startswith("right")


def test_observation_is_odometry_not_ground_truth():
    """Once odometry and truth part (skid-steer turns), the observation follows odometry."""
    env = gym.make("SmartCar-v0", goal_range=(1.5, 2.0))
    try:
        env.reset(seed=3)
        for _ in range(40):
            obs, _, terminated, _, info = env.step(np.array([0.6, 1.0], dtype=np.float32))
            assert not terminated
        assert info["odom_error"] > 0.1  # they have parted by more than 10 cm
        odom_x, odom_y, odom_yaw = info["odom_pose"]
        np.testing.assert_allclose(obs[0:4], [odom_x, odom_y, math.cos(odom_yaw),
                                              math.sin(odom_yaw)], atol=1e-5)
        true_x, true_y, true_yaw = info["pose"]
        assert math.hypot(obs[0] - true_x, obs[1] - true_y) > 0.1

        def goal_in_base(x, y, yaw):  # (ahead, left) of the goal seen from pose (x, y, yaw)
            dx, dy = goal[0] - x, goal[1] - y
            return np.array([math.cos(yaw) * dx + math.sin(yaw) * dy,
                             -math.sin(yaw) * dx + math.cos(yaw) * dy])

        goal = env.unwrapped.goal
        np.testing.assert_allclose(obs[14:16], goal_in_base(odom_x, odom_y, odom_yaw), atol=1e-5)
        # the real robot would see it elsewhere: the odometry heading is off after the turns
        assert np.linalg.norm(obs[14:16] - goal_in_base(true_x, true_y, true_yaw)) > 0.1
        assert obs[16] == pytest.approx(math.hypot(goal[0] - odom_x, goal[1] - odom_y), abs=1e-5)
    finally:
        env.close()
