"""SmartCarGoal-v0 on MuJoCo batched in C (``SmartCarBatchVectorEnv``): per-car equality
with N single MuJoCo Goal envs (dict observations, goal-conditioned reward and ends),
Gymnasium's vector conventions and the fallbacks."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401
from smartcar_gym.envs.vector import (  # noqa: E402
    SmartCarBatchVectorEnv,
    SmartCarLoopVectorEnv,
)

N = 8
EPISODE = 30
#: near goals in a small arena: goals reached, the arena left and time limits within 60 steps
SHORT = {"goal_range": (0.25, 0.4), "arena_size": 1.2}
HALF = 0.6


def policy(obs: dict, rng: np.random.Generator) -> np.ndarray:
    """Cars 0-1 steer for the desired goal by odometry, 2 drives straight out, the rest act at
    random (beyond [-1, 1]: clipped)."""
    o = obs["observation"]
    c, s = o[:, 2], o[:, 3]  # odom heading
    d = obs["desired_goal"] - obs["achieved_goal"]
    bearing = np.arctan2(-s * d[:, 0] + c * d[:, 1], c * d[:, 0] + s * d[:, 1])
    a = rng.uniform(-1.3, 1.3, (len(o), 2))
    a[:2, 0], a[:2, 1] = 1.0, np.clip(3.0 * bearing[:2], -1.0, 1.0)
    a[2] = (1.0, 0.0)
    return a


def rollout(envs: gym.vector.VectorEnv, steps: int, seed: int) -> list[tuple]:
    rng = np.random.default_rng(seed)
    obs, info = envs.reset(seed=seed)
    out = [(obs, info)]
    for _ in range(steps):
        out.append(envs.step(policy(obs, rng)))
        obs = out[-1][0]
    return out


def make(num_envs: int = N, **kwargs) -> gym.vector.VectorEnv:
    return gym.make_vec("SmartCarGoal-v0", num_envs=num_envs,
                        vectorization_mode="vector_entry_point", engine="mujoco", **kwargs)


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_goal_batch_equals_n_single_envs_bit_for_bit(mode):
    batched = make(max_episode_steps=EPISODE, autoreset_mode=mode, num_threads=2, **SHORT)
    single = gym.make_vec("SmartCarGoal-v0", num_envs=N, vectorization_mode="sync",
                          engine="mujoco", max_episode_steps=EPISODE, **SHORT,
                          vector_kwargs={"autoreset_mode": AutoresetMode(mode)})
    assert isinstance(batched, SmartCarBatchVectorEnv)
    assert (batched.env_id, batched.engine) == ("SmartCarGoal-v0", "mujoco")
    try:
        got, want = rollout(batched, 60, 2), rollout(single, 60, 2)
        for key in want[0][0]:
            assert np.array_equal(got[0][0][key], want[0][0][key]), key
        reached = left = 0
        for k, (g, w) in enumerate(zip(got[1:], want[1:], strict=True), 1):
            for key in w[0]:
                assert np.array_equal(g[0][key], w[0][key]), f"step {k}: obs[{key!r}]"
            assert np.array_equal(g[1], w[1]), f"step {k}: rewards differ"
            assert np.array_equal(g[2], w[2]) and np.array_equal(g[3], w[3]), f"step {k}"
            for key in ("is_success", "_is_success", "flipped", "distance", "pose", "odom_pose"):
                assert np.array_equal(g[4][key], w[4][key]), f"step {k}: info[{key!r}]"
            last = w[0]["achieved_goal"]
            if mode == "SameStep":
                assert np.array_equal(g[4].get("_final_obs", np.zeros(N, bool)),
                                      w[4].get("_final_obs", np.zeros(N, bool)))
                for i in np.flatnonzero(w[4].get("_final_obs", [])):
                    for key in w[4]["final_obs"][i]:
                        assert np.array_equal(g[4]["final_obs"][i][key],
                                              w[4]["final_obs"][i][key])
                    last = last.copy()
                    last[i] = w[4]["final_obs"][i]["achieved_goal"]
            reached += int(w[2].sum())
            left += int((w[3] & (np.abs(last) > HALF).any(axis=1)).sum())
        assert reached >= 2 and left >= 1, (reached, left)
    finally:
        batched.close()
        single.close()


def test_goal_batch_follows_gymnasium_conventions():
    envs = make(3)
    try:
        assert envs.observation_space == gym.vector.utils.batch_space(
            envs.single_observation_space, 3)
        assert envs.unwrapped.max_episode_steps == 100  # SmartCarGoal-v0's limit
        obs, info = envs.reset(seed=5)
        other, _ = envs.reset(seed=6)
        assert np.array_equal(other["desired_goal"][0], obs["desired_goal"][1])
        assert obs in envs.observation_space and not info["is_success"].any()
        obs, rewards, terminated, truncated, info = envs.step(np.full((3, 2), 0.5))
        assert obs in envs.observation_space
        assert np.array_equal(rewards, envs.unwrapped.compute_reward(
            obs["achieved_goal"], obs["desired_goal"], None))
        assert info["flipped"].dtype == bool and info["_flipped"].all()
        # a goal within goal_tolerance of the start is reached at reset
        _, info = envs.reset(options={"goal": (0.05, 0.0)})
        assert info["is_success"].all()
    finally:
        envs.close()


def test_what_the_goal_batch_cannot_run_falls_back_to_the_loop():
    for kwargs in ({"randomize": "default"}, {"controller_mode": "sim"}):
        envs = make(2, **kwargs)
        assert isinstance(envs, SmartCarLoopVectorEnv), kwargs
        envs.close()
    pybullet = gym.make_vec("SmartCarGoal-v0", num_envs=2,
                            vectorization_mode="vector_entry_point")
    assert isinstance(pybullet, SmartCarLoopVectorEnv)
    pybullet.close()
