"""A closed MuJoCo batch (SmartCar-v0, SmartCarNav-v0, SmartCarGoal-v0): ``reset()`` reopens it,
as it does a single env, and ``step()`` before that says so in one line."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401

BATCHED = ("SmartCar-v0", "SmartCarNav-v0", "SmartCarGoal-v0")
N = 3


def make(env_id: str) -> gym.vector.VectorEnv:
    return gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point",
                        engine="mujoco", max_episode_steps=6)


def flat(obs) -> np.ndarray:
    """An observation batch as one array (the Goal batch's is a dict)."""
    if isinstance(obs, dict):
        return np.concatenate([obs[k].reshape(N, -1) for k in sorted(obs)], axis=1)
    return obs


def episode(envs: gym.vector.VectorEnv, seed: int) -> list[np.ndarray]:
    """Observations and rewards of 8 steps (an autoreset included) from ``reset(seed=seed)``."""
    rng = np.random.default_rng(seed)
    obs, _ = envs.reset(seed=seed)
    out = [flat(obs)]
    for _ in range(8):
        obs, reward, *_ = envs.step(rng.uniform(-1, 1, (N, 2)))
        out += [flat(obs), reward]
    return out


@pytest.mark.parametrize("env_id", BATCHED)
def test_reset_reopens_a_closed_batch(env_id):
    envs = make(env_id)
    first = episode(envs, 4)
    envs.close()
    with pytest.raises(RuntimeError, match=rf"^SmartCarBatchVectorEnv \({env_id} on mujoco\) is "
                                           r"closed: call reset\(\) to reopen it before "
                                           r"step\(\)$"):
        envs.step(np.zeros((N, 2)))
    again = episode(envs, 4)  # reopened: the same worlds, the same rollout
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert not envs.closed
    envs.close()  # and it closes again
    assert envs.closed and envs.unwrapped.cars.batch.models == []


def test_a_closed_numpy_batch_says_so_too():
    envs = gym.make_vec("SmartCarSim-v0", num_envs=N, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    envs.close()
    with pytest.raises(RuntimeError, match=r"^SmartCarSimVectorEnv is closed: call reset\(\)"):
        envs.step(np.zeros((N, 2)))
    obs, _ = envs.reset(seed=0)
    assert envs.step(np.zeros((N, 2)))[0].shape == obs.shape
    envs.close()
