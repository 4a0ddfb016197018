"""SmartCarArrive-v0: a goal is reached only with the car at rest, by truth and by odometry."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from smartcar_gym.controller.config_yaml import calibrated_config_path


@pytest.fixture
def env():
    env = gym.make("SmartCarArrive-v0")
    yield env
    env.close()


def test_arrive_is_smartcar_v0_on_calibrated_odometry_with_goals_0_3_to_2_m(env):
    base = env.unwrapped
    assert base.controller_config.source == calibrated_config_path()
    assert base.controller_config.base_width_m == 0.33
    assert (base.task.goal_range_m, base.task.stop_speed_m_s) == ((0.3, 2.0), 0.01)
    distances = []
    for seed in range(40):
        env.reset(seed=seed)
        distances.append(math.hypot(*base.goal))
    assert 0.3 <= min(distances) < 0.6 and 1.7 < max(distances) < 2.0


def test_driving_through_the_goal_is_not_arriving_stopping_there_is(env):
    obs, info = env.reset(seed=0, options={"goal": (0.5, 0.0)})
    inside_moving = 0
    for _ in range(40):  # straight at 0.15 m/s: through the 0.1 m circle without stopping
        obs, reward, terminated, truncated, info = env.step(np.array([0.3, 0.0]))
        assert not terminated
        inside_moving += info["distance"] < 0.1
        if info["distance"] < 0.05:
            break
    assert inside_moving >= 1 and info["distance"] < 0.1
    steps = 0
    while steps < 30:  # zero command: the controller ramps the wheels down
        obs, reward, terminated, truncated, info = env.step(np.zeros(2))
        steps += 1
        if terminated:
            break
    assert terminated and info["is_success"] and info["distance"] < 0.1 and steps >= 2
    (vx, vy, _), _ = env.unwrapped.robot.body.velocity()
    assert math.hypot(vx, vy) < 0.01
    assert reward > 9.0  # the bonus, less the costs of that step
