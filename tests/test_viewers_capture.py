"""The capture behind the recordings: episodes handed over in order, reward terms, rotations."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401  (registers the envs)
from smartcar_gym.envs.tasks.obstacles import Obstacle
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
    # the episode's obstacles, each one (the single env's car's)
    assert all(isinstance(o, Obstacle) for o in scene.obstacles)
    assert len(scene.obstacles) == (8 if env_id == "SmartCarNav-v0" else 0)
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


def _scan(ranges, angle_min=-1.0, increment=0.5):
    from smartcar_gym.envs.sensors.scan import LaserScan

    ranges = np.array(ranges, dtype=np.float32)
    return LaserScan(0.0, "laser", angle_min, angle_min + increment * (len(ranges) - 1),
                     increment, 0.0, 0.1, 0.05, 5.0, ranges)


def test_scan_points_keep_finite_ranges_in_the_laser_frame():
    pytest.importorskip("rerun")
    from smartcar_gym.viewers.packing import scan_points

    scans = [_scan([1.0, np.inf, 2.0, 0.5, -np.inf]), _scan([np.inf] * 5),
             _scan([3.0, 1.0, 1.0, 1.0, 1.0])]
    positions, lengths = scan_points(scans)  # one geometry: all scans at once
    assert lengths == [3, 0, 5]
    # hand-derived: beam i at -1 + 0.5 i rad; the first scan's hits are beams 0, 2, 3
    expected = [(r * np.cos(a), r * np.sin(a), 0.0)
                for r, a in [(1.0, -1.0), (2.0, 0.0), (0.5, 0.5)]]
    np.testing.assert_allclose(positions[:3], expected, atol=1e-12)
    np.testing.assert_allclose(positions[3:], [(3 * np.cos(-1.0), 3 * np.sin(-1.0), 0.0),
                                               *[(np.cos(a), np.sin(a), 0.0)
                                                 for a in (-0.5, 0.0, 0.5, 1.0)]], atol=1e-12)
    # a frame without a scan, or scans of another geometry: one scan at a time, same points
    mixed, mixed_lengths = scan_points([None, *scans, _scan([2.0, 2.0], 0.0, 0.25)])
    assert mixed_lengths == [0, 3, 0, 5, 2]
    np.testing.assert_array_equal(mixed[:8], positions)
    np.testing.assert_allclose(mixed[8:], [(2.0, 0.0, 0.0), (2 * np.cos(0.25),
                                                             2 * np.sin(0.25), 0.0)])
    empty, none_lengths = scan_points([None, None])
    assert empty.shape == (0, 3) and none_lengths == [0, 0]


def test_scene_shapes_are_worked_out_once_per_model():
    from smartcar_gym.viewers.capture import scene_of

    env = gym.make("SmartCar-v0")
    env.reset(seed=0)
    first = scene_of(env)
    env.reset(seed=1)
    again = scene_of(env)
    assert again.shapes is first.shapes and again.goal != first.goal  # goal per episode
    assert {s.type for s in first.shapes} >= {"box", "cylinder"}
    env.close()
