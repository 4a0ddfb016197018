"""The vector_entry_point envs: per-car equality with N single envs, Gymnasium's vector
conventions, and bad input."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.vector import SmartCarLoopVectorEnv, SmartCarSimVectorEnv
from smartcar_gym.registration import ENV_IDS

N = 5
EPISODE = 60


def policy(obs: np.ndarray, rng: np.random.Generator, step: int) -> np.ndarray:
    """Cars 0-1 steer for the goal (successes), 2 drives straight out (failures), the rest
    act at random, with actions beyond [-1, 1] that must be clipped."""
    gx, gy = obs[:, 14], obs[:, 15]  # goal_x_base, goal_y_base
    steer = np.stack([np.clip(gx, -1, 1), np.clip(2 * np.arctan2(gy, gx), -1, 1)], axis=1)
    actions = rng.uniform(-1.3, 1.3, (len(obs), 2))
    actions[:2] = steer[:2] + rng.normal(0, 0.05, (2, 2))
    if len(obs) > 2:
        actions[2] = (1.0, 0.05 * math.sin(step))
    return actions.astype(np.float32)


def rollout(envs: gym.vector.VectorEnv, steps: int, seed: int) -> list[tuple]:
    rng = np.random.default_rng(seed)
    obs, info = envs.reset(seed=seed)
    out = [(obs, info)]
    for k in range(steps):
        step = envs.step(policy(obs, rng, k))
        obs = step[0]
        out.append(step)
    return out


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_kinematic_batch_equals_n_single_envs_bit_for_bit(mode):
    kwargs = {"max_episode_steps": EPISODE, "autoreset_mode": mode}
    batched = gym.make_vec("SmartCarSim-v0", num_envs=N, vectorization_mode="vector_entry_point",
                           **kwargs)
    single = gym.make_vec("SmartCarSim-v0", num_envs=N, vectorization_mode="sync",
                          max_episode_steps=EPISODE,
                          vector_kwargs={"autoreset_mode": AutoresetMode(mode)})
    assert isinstance(batched, SmartCarSimVectorEnv)
    try:
        got, want = rollout(batched, 150, 11), rollout(single, 150, 11)
        assert np.array_equal(got[0][0], want[0][0])
        ends = {"success": 0, "failure": 0, "truncated": 0}
        for k, (g, w) in enumerate(zip(got[1:], want[1:], strict=True), 1):
            assert np.array_equal(g[0], w[0]), f"step {k}: observations differ"
            assert np.array_equal(g[1], w[1]), f"step {k}: rewards differ"
            assert np.array_equal(g[2], w[2]) and np.array_equal(g[3], w[3]), f"step {k}"
            gi, wi = g[4], w[4]
            assert np.array_equal(gi["is_success"], wi["is_success"])
            assert np.array_equal(gi["_is_success"], wi["_is_success"])
            assert np.array_equal(gi["distance"], wi["distance"])
            np.testing.assert_allclose(gi["pose"], wi["pose"], atol=1e-6)
            np.testing.assert_allclose(gi["odom_pose"], wi["odom_pose"], atol=1e-9)
            if mode == "SameStep":
                assert np.array_equal(gi.get("_final_obs", np.zeros(N, bool)),
                                      wi.get("_final_obs", np.zeros(N, bool)))
                for i in np.flatnonzero(wi.get("_final_obs", [])):
                    assert np.array_equal(gi["final_obs"][i], wi["final_obs"][i])
                    assert gi["final_info"]["is_success"][i] == wi["final_info"]["is_success"][i]
                    ends["success"] += int(wi["final_info"]["is_success"][i])
            else:
                ends["success"] += int(wi["is_success"].sum())
            ends["failure"] += int((w[2] & (w[1] < -5)).sum())
            ends["truncated"] += int(w[3].sum())
        assert min(ends.values()) >= 1, ends  # every way an episode ends was compared
    finally:
        batched.close()
        single.close()


def test_loop_batch_equals_n_single_envs():
    """SmartCar-v0 (pybullet) through the vector_entry_point: the same rollouts as sync."""
    kwargs = {"max_episode_steps": 8}
    looped = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                          **kwargs)
    single = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="sync", **kwargs)
    assert isinstance(looped, SmartCarLoopVectorEnv)
    try:
        for g, w in zip(rollout(looped, 12, 3)[1:], rollout(single, 12, 3)[1:], strict=True):
            for a, b in zip(g[:4], w[:4], strict=True):
                assert np.array_equal(a, b)
    finally:
        looped.close()
        single.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_vector_entry_point_follows_gymnasium_conventions(env_id):
    n = 2 if env_id != "SmartCarSim-v0" else 3
    envs = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                        max_episode_steps=5)
    try:
        assert envs.num_envs == n
        assert envs.observation_space == gym.vector.utils.batch_space(
            envs.single_observation_space, n)
        assert envs.action_space.shape == (n, 2)
        assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        obs, info = envs.reset(seed=5)
        again, _ = envs.reset(seed=5)
        other, _ = envs.reset(seed=6)
        assert obs in envs.observation_space
        assert np.array_equal(_goals(obs, envs), _goals(again, envs))
        # car i is seeded 5 + i: seed 6 gives car 0 what seed 5 gave car 1
        assert np.array_equal(_goals(other, envs)[0], _goals(obs, envs)[1])
        envs.reset(seed=5)
        envs.action_space.seed(0)
        done = np.zeros(n, dtype=bool)
        for k in range(6):
            obs, rewards, terminated, truncated, info = envs.step(envs.action_space.sample())
            assert obs in envs.observation_space
            assert rewards.shape == (n,) and rewards.dtype == np.float64
            assert terminated.dtype == bool and truncated.dtype == bool
            assert np.all(rewards[done] == 0)  # next-step autoreset: those cars were reset
            assert info["is_success"].dtype == bool and info["_is_success"].all()
            done = terminated | truncated
            if k == 4:
                assert done.all()  # every car reached the 5-step limit
        assert not done.any()
    finally:
        envs.close()


def _goals(obs: np.ndarray, envs: gym.vector.VectorEnv) -> np.ndarray:
    if isinstance(obs, dict):  # SmartCarGoal-v0
        return obs["desired_goal"]
    return obs[:, -2:]


def test_kinematic_render_tiles_the_first_cars():
    envs = gym.make_vec("SmartCarSim-v0", num_envs=20, vectorization_mode="vector_entry_point",
                        render_mode="rgb_array", render_width=160, render_height=120)
    envs.reset(seed=0)
    frame = envs.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    colours = {tuple(c) for c in frame.reshape(-1, 3)}
    assert (40, 80, 200) in colours and (40, 170, 60) in colours  # cars and goals are drawn
    with pytest.warns(UserWarning, match="render_mode"):
        assert gym.make_vec("SmartCarSim-v0", num_envs=2,
                            vectorization_mode="vector_entry_point").render() is None


def test_what_numpy_cannot_batch_falls_back_to_the_loop():
    envs = gym.make_vec("SmartCarSim-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        randomize="default")
    assert isinstance(envs, SmartCarLoopVectorEnv)
    envs.close()
    # stop_speed's arrival terms are the single env's: the loop, not a numpy env without them
    envs = gym.make_vec("SmartCarSim-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        stop_speed=0.01)
    assert isinstance(envs, SmartCarLoopVectorEnv)
    envs.close()


@pytest.mark.parametrize("num_envs", [0, -3, 2.5, True])
def test_bad_num_envs_is_one_line(num_envs):
    with pytest.raises(ValueError, match=r"^SmartCarSim-v0: num_envs must be an integer >= 1"):
        gym.make_vec("SmartCarSim-v0", num_envs=num_envs, vectorization_mode="vector_entry_point")


@pytest.mark.parametrize("env_id", ["SmartCarSim-v0", "SmartCar-v0"])
def test_num_envs_too_large_for_memory_is_one_line(env_id):
    with pytest.raises(MemoryError, match=rf"^{env_id}: num_envs=\d+ needs about .* GiB"):
        gym.make_vec(env_id, num_envs=10**12, vectorization_mode="vector_entry_point")


@pytest.mark.parametrize("env_id", ["SmartCarSim-v0", "SmartCar-v0"])
def test_bad_action_batches_name_the_expected_shape(env_id):
    envs = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3, 2\).*mixed batch"):
        envs.step([np.zeros(2), np.zeros(3), np.zeros(2)])
    with pytest.raises(ValueError, match=r"shape \(3, 2\).*got shape \(2, 2\)"):
        envs.step(np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"cars \[1\] have NaN"):
        envs.step(np.array([[0, 0], [np.nan, 0], [0, 0]]))
    with pytest.raises(ValueError, match="autoreset_mode must be one of"):
        gym.make_vec("SmartCarSim-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     autoreset_mode="Disabled")


def test_reset_goal_option_for_all_cars_or_each():
    envs = gym.make_vec("SmartCarSim-v0", num_envs=3, vectorization_mode="vector_entry_point")
    obs, _ = envs.reset(seed=0, options={"goal": (1.0, -0.5)})
    assert np.array_equal(obs[:, -2:], np.tile(np.float32([1.0, -0.5]), (3, 1)))
    goals = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    obs, info = envs.reset(options={"goal": goals})
    assert np.array_equal(obs[:, -2:], goals.astype(np.float32))
    assert np.allclose(info["distance"], 1.0)
    with pytest.raises(ValueError, match=r"\(3, 2\) array"):
        envs.reset(options={"goal": np.zeros((2, 2))})
    with pytest.raises(ValueError, match="outside the arena"):
        envs.reset(options={"goal": (9.0, 0.0)})
