"""The goal-reaching task through the env: success, failure, rewards, info, command timing."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401

FORWARD = np.array([1.0, 0.0], dtype=np.float32)
ZERO = np.zeros(2, dtype=np.float32)


def _check_info(info: dict) -> None:
    assert set(info) >= {"is_success", "distance", "pose", "odom_pose", "odom_error"}
    assert type(info["is_success"]) is bool
    assert type(info["distance"]) is float and info["distance"] >= 0
    for key in ("pose", "odom_pose"):
        assert isinstance(info[key], np.ndarray) and info[key].shape == (3,)
        assert np.all(np.isfinite(info[key]))
    assert type(info["odom_error"]) is float and info["odom_error"] >= 0
    expected = math.dist(info["pose"][:2], info["odom_pose"][:2])
    assert info["odom_error"] == pytest.approx(expected, abs=1e-12)


def test_driving_straight_reaches_a_goal_ahead():
    env = gym.make("SmartCar-v0")
    try:
        obs, info = env.reset(seed=0, options={"goal": (0.5, 0.0)})
        _check_info(info)
        distances = [info["distance"]]
        for _ in range(40):
            obs, reward, terminated, truncated, info = env.step(FORWARD)
            _check_info(info)
            distances.append(info["distance"])
            if terminated or truncated:
                break
        assert terminated is True and truncated is False
        assert info["is_success"] is True
        assert info["distance"] < 0.1  # the default goal_tolerance
        assert reward > 9  # progress + the +10 success bonus - small costs
        # 0.5 m at up to 0.5 m/s: a bit over 1 s, plus the one-step command delay
        assert 8 <= len(distances) - 1 <= 20
        tail = np.array(distances[-6:])
        assert np.all(np.diff(tail) < 0), distances
        assert info["odom_error"] < 0.01  # straight on flat ground: the encoders are right
    finally:
        env.close()


def test_success_reward_matches_task_formula():
    """The success step's reward is 10 x progress - 0.01 - 0.01 |a|^2 + 10, on ground truth."""
    env = gym.make("SmartCarSim-v0", goal_tolerance=0.05)
    try:
        _, info = env.reset(seed=0, options={"goal": (0.25, 0.0)})
        prev = info["distance"]
        for _ in range(10):  # 0.05 m per step in sim mode
            _, reward, terminated, _, info = env.step(FORWARD * 0.5)
            if terminated:
                break
            prev = info["distance"]
        assert terminated and info["is_success"]
        expected = 10 * (prev - info["distance"]) - 0.01 - 0.01 * 0.25 + 10
        assert reward == pytest.approx(expected, abs=1e-9)
    finally:
        env.close()


def test_leaving_the_arena_terminates_with_penalty():
    env = gym.make("SmartCar-v0", arena_size=1.2, goal_range=(0.3, 0.4))
    try:
        env.reset(seed=0, options={"goal": (0.35, 0.0)})
        steps = 0
        while steps < 40:
            _, reward, terminated, truncated, info = env.step(-FORWARD)  # reverse, away
            steps += 1
            if terminated:
                break
            assert reward < 0 and abs(info["pose"][0]) <= 0.6
        assert terminated is True and truncated is False
        assert info["is_success"] is False
        assert info["pose"][0] < -0.6  # past the arena edge (half size 0.6 m)
        assert reward < -9
        assert steps > 5  # it took real driving, not an instant failure
    finally:
        env.close()


def test_flipping_over_terminates_with_penalty():
    env = gym.make("SmartCar-v0")
    try:
        env.reset(seed=0)
        unwrapped = env.unwrapped
        # teleport the car upside down (180 degrees about x), a little above the ground
        unwrapped.robot.body.set_com_pose((0.0, 0.0, 0.1), (1.0, 0.0, 0.0, 0.0))
        _, reward, terminated, truncated, info = env.step(ZERO)
        assert terminated is True and truncated is False
        assert info["is_success"] is False
        assert reward < -9
    finally:
        env.close()


def test_zero_action_costs_only_time():
    env = gym.make("SmartCar-v0")
    try:
        env.reset(seed=2)
        _, reward, terminated, _, info = env.step(ZERO)
        assert not terminated and not info["is_success"]
        assert reward == pytest.approx(-0.01, abs=2e-3)  # the car barely moves
    finally:
        env.close()


def test_sim_mode_moves_exactly_the_commanded_distance():
    """sim mode: cmd_vel reaches the kinematic body in the step it is sent (no delay).

    ``advance`` sends the cmd_vel, then ``_move_kinematically`` moves the body with
    ``commanded_twist`` (= that cmd_vel) for 0.1 s, then the controller integrates the same
    twist over the same 0.1 s. So action [0.5, 0] (0.25 m/s) moves x by 0.025 m per step,
    0.25 m after 10 steps, and odometry equals ground truth. (pybullet stores poses in float32:
    the body is exact to ~1e-8 m, not to double precision.)
    """
    env = gym.make("SmartCarSim-v0")
    try:
        env.reset(seed=0, options={"goal": (2.0, 0.0)})
        for k in range(1, 11):
            obs, _, terminated, _, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
            assert not terminated
            assert info["pose"][0] == pytest.approx(0.025 * k, abs=1e-7)
            np.testing.assert_allclose(info["pose"][1:], [0, 0], atol=1e-7)
            np.testing.assert_allclose(info["odom_pose"], info["pose"], atol=1e-6)
            assert info["odom_error"] < 1e-6
        assert info["odom_pose"][0] == pytest.approx(0.25, abs=1e-12)  # 10 x 0.25 m/s x 0.1 s
        assert info["pose"][0] == pytest.approx(0.25, abs=1e-7)
        assert obs[0] == pytest.approx(0.25, abs=1e-6) and obs[4] == pytest.approx(0.25)
        assert info["distance"] == pytest.approx(1.75, abs=1e-7)
    finally:
        env.close()


def test_hardware_mode_command_reaches_the_wheels_one_step_later():
    """hardware mode: the controller writes the cmd_vel to the board at the end of the step."""
    env = gym.make("SmartCar-v0")
    try:
        _, info0 = env.reset(seed=0, options={"goal": (2.0, 0.0)})
        obs1, _, _, _, info1 = env.step(FORWARD)
        assert abs(info1["pose"][0] - info0["pose"][0]) < 1e-3  # nothing driven yet
        assert obs1[4] == 0.0 and obs1[0] == 0.0  # the encoders saw nothing
        obs2, _, _, _, info2 = env.step(FORWARD)
        assert info2["pose"][0] - info1["pose"][0] > 1e-3  # now it drives
        assert obs2[4] > 0
        # and stays on the line: the odometry agrees with ground truth
        for _ in range(8):
            obs, _, _, _, info = env.step(FORWARD)
        assert info["pose"][0] > 0.2
        assert info["odom_error"] < 0.01
        assert 0.3 < obs[4] < 0.7  # measured linear.x near the commanded 0.5 m/s
    finally:
        env.close()


def _go_to_goal(obs: np.ndarray) -> np.ndarray:
    """A hand-written controller that sees only the observation: turn to the goal, drive."""
    ahead, left, distance = float(obs[14]), float(obs[15]), float(obs[16])
    bearing = math.atan2(left, ahead)
    linear = min(1.0, 3.0 * distance) * max(0.0, math.cos(bearing)) ** 2
    return np.array([linear, np.clip(2.0 * bearing, -1.0, 1.0)], dtype=np.float32)


def test_reward_threshold_is_reachable_from_the_observation_alone():
    """In sim mode the odometry follows the body closely: a scripted controller always wins.

    This pins down that ``reward_threshold`` is attainable and the observation suffices.
    """
    env = gym.make("SmartCarSim-v0")
    try:
        returns, successes = [], []
        for seed in range(10):
            obs, _ = env.reset(seed=seed)
            total = 0.0
            while True:
                obs, reward, terminated, truncated, info = env.step(_go_to_goal(obs))
                total += reward
                if terminated or truncated:
                    break
            returns.append(total)
            successes.append(info["is_success"])
        assert all(successes)
        assert np.mean(returns) >= env.spec.reward_threshold
    finally:
        env.close()


def test_sim_mode_body_is_where_its_odometry_says_while_turning():
    """sim mode: body and fake odometry take the same Euler step (heading at period start)."""
    env = gym.make("SmartCarSim-v0")
    env.reset(seed=0)
    for _ in range(10):  # 0.5 m/s and 2 rad/s for 1 s: an arc
        _, _, _, _, info = env.step(np.array([1.0, 1.0], dtype=np.float32))
    # hand-derived: x += 0.05 cos(th), y += 0.05 sin(th), th += 0.2 from th = 0, ten times
    th = 0.2 * np.arange(10)
    expected = [0.05 * np.cos(th).sum(), 0.05 * np.sin(th).sum(), 2.0]
    np.testing.assert_allclose(info["odom_pose"][:2], expected[:2], atol=1e-9)
    np.testing.assert_allclose(info["pose"], expected, atol=1e-6)
    assert info["odom_error"] < 1e-6
    env.close()
