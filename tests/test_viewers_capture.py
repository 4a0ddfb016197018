"""The capture behind the recordings: episodes handed over in order, reward terms, rotations."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401  (registers the envs)
from smartcar_gym.model.kinematics import matrix_quaternion, quaternion_matrix
from smartcar_gym.viewers.capture import CAPTURE_KEY, CaptureWrapper, EpisodeCollector


def test_matrix_quaternion_inverts_quaternion_matrix():
    rng = np.random.default_rng(0)
    for q in rng.normal(size=(50, 4)):
        q /= np.linalg.norm(q)
        back = np.array(matrix_quaternion(quaternion_matrix(q)))
        assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12  # q and -q alike


def _frame(done):
    class Frame:
        terminated, truncated = done, False
    return Frame()


def test_collector_writes_whole_episodes_in_episode_order():
    written = []
    collector = EpisodeCollector(written.append)
    collector.begin(0, 0, 10, ("scene", _frame(False)))
    collector.begin(1, 1, 11, ("scene", _frame(False)))
    collector.add(1, _frame(True))  # episode 1 ends first: it waits for episode 0
    assert written == []
    collector.begin(1, 2, 12, ("scene", _frame(False)))
    collector.add(0, _frame(False))
    collector.add(0, _frame(True))
    assert [(e.index, e.seed, e.steps) for e in written] == [(0, 10, 2), (1, 11, 1)]
    collector.add(1, _frame(True))
    assert [e.index for e in written] == [0, 1, 2]


@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarNav-v0"])
def test_reward_terms_add_up_to_the_reward(env_id):
    env = CaptureWrapper(gym.make(env_id, max_episode_steps=40))
    _, info = env.reset(seed=2)
    scene, first = info[CAPTURE_KEY]
    assert first.reward == 0.0 and first.time_ns == 0 and scene.goal == tuple(env.unwrapped.goal)
    env.action_space.seed(2)
    done = False
    while not done:
        action = env.action_space.sample() * 1.5  # out of range: clipped as the env clips
        _, reward, terminated, truncated, info = env.step(action)
        frame = info[CAPTURE_KEY]
        assert sum(frame.reward_terms.values()) == pytest.approx(reward, abs=1e-12)
        assert frame.action == tuple(float(a) for a in np.clip(action, -1, 1))
        np.testing.assert_array_equal(frame.position[:2], info["pose"][:2])
        done = terminated or truncated
    env.close()
    assert ("collision" in frame.reward_terms) == (env_id == "SmartCarNav-v0")
