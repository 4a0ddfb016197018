"""Copies of the batched envs (``copy.deepcopy``, pickle) are those of the single env: the same
settings and generators, never the original's worlds; a MuJoCo batch's copy opens worlds of its
own at its first reset, also after worker threads stepped the original."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401

#: 9 cars on 2 threads: the worker threads run (4 cars or more each)
N = 9
ACTIONS = np.tile([0.6, 0.3], (N, 1))


def make(env_id: str) -> gym.vector.VectorEnv:
    kwargs = {} if env_id == "SmartCarSim-v0" else {"engine": "mujoco", "num_threads": 2}
    return gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)


def copied(envs: gym.vector.VectorEnv, how: str) -> gym.vector.VectorEnv:
    return copy.deepcopy(envs) if how == "deepcopy" else pickle.loads(pickle.dumps(envs))


def flat(obs) -> np.ndarray:
    if isinstance(obs, dict):
        return np.concatenate([obs[k].reshape(N, -1) for k in sorted(obs)], axis=1)
    return obs


def steps(envs: gym.vector.VectorEnv, seed: int | None) -> list[np.ndarray]:
    obs, _ = envs.reset(seed=seed)
    out = [flat(obs)]
    for _ in range(3):
        obs, reward, *_ = envs.step(ACTIONS)
        out += [flat(obs), reward]
    return out


def same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarNav-v0", "SmartCarGoal-v0"])
def test_a_copy_of_a_mujoco_batch_is_a_closed_twin(env_id, how):
    envs = make(env_id)
    steps(envs, 2)  # the worker threads have run
    twin = copied(envs, how)
    with pytest.raises(RuntimeError, match=r"is closed: call reset\(\) to reopen it"):
        twin.step(ACTIONS)  # no world yet, as a copied single env
    # the same generators: both go on with the same goals ...
    assert same(steps(twin, None), steps(envs, None))
    # ... and the same seed gives the same rollout
    assert same(steps(twin, 7), steps(envs, 7))
    twin_worlds, worlds = twin.unwrapped.cars.batch.datas, envs.unwrapped.cars.batch.datas
    assert twin_worlds[0] is not worlds[0]
    twin.close()
    envs.step(ACTIONS)  # the original keeps its worlds
    envs.close()


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_of_the_numpy_batch_goes_on_where_it_was(how):
    envs = make("SmartCarSim-v0")
    steps(envs, 2)
    twin = copied(envs, how)  # no world to leave behind: the whole state
    assert np.array_equal(twin.step(ACTIONS)[0], envs.step(ACTIONS)[0])
    twin.close()
    envs.close()
