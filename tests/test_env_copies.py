"""Copies and threads: nothing shares or disconnects another env's pybullet world."""

from __future__ import annotations

import copy
import gc
import pickle
import threading

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401

FORWARD = np.array([1.0, 0.0], dtype=np.float32)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_gets_a_world_of_its_own(how):
    env = gym.make("SmartCar-v0")
    env.reset(seed=0)
    for _ in range(3):
        env.step(FORWARD)
    before = env.unwrapped.robot.pose()
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    with pytest.raises(RuntimeError, match=r"closed: call reset\(\)"):
        twin.step(FORWARD)  # the copy has no world yet
    twin.reset(seed=0)
    for _ in range(10):
        twin.step(FORWARD)  # drives its own car ...
    assert env.unwrapped.robot.pose() == before  # ... not the original's
    client = twin.unwrapped.sim.client._client
    assert client != env.unwrapped.sim.client._client
    del twin
    gc.collect()
    obs, *_ = env.step(FORWARD)  # the original still has its world
    assert obs in env.observation_space
    other = gym.make("SmartCar-v0")  # and a new env is not hurt either
    other.reset(seed=1)
    other.step(FORWARD)
    other.close()
    env.close()


def test_a_copy_replays_the_original_from_the_same_seed():
    env = gym.make("SmartCar-v0")
    twin = copy.deepcopy(env)
    a, _ = env.reset(seed=5)
    b, _ = twin.reset(seed=5)
    assert a.tobytes() == b.tobytes()
    for _ in range(5):
        assert env.step(FORWARD)[0].tobytes() == twin.step(FORWARD)[0].tobytes()
    env.close()
    twin.close()


def test_two_threads_in_one_env_get_a_clear_error():
    env = gym.make("SmartCar-v0")
    env.reset(seed=0)
    unwrapped = env.unwrapped
    inside = threading.Event()
    release = threading.Event()
    original = unwrapped.sim.run_until

    def slow_run_until(*args, **kwargs):
        inside.set()
        release.wait(5)
        return original(*args, **kwargs)

    unwrapped.sim.run_until = slow_run_until
    errors: list[BaseException] = []
    worker = threading.Thread(target=lambda: env.step(FORWARD))
    worker.start()
    assert inside.wait(5)
    try:
        with pytest.raises(RuntimeError, match=r"another thread is inside this env.*not "
                                               r"thread-safe"):
            env.step(FORWARD)
        with pytest.raises(RuntimeError, match="another thread"):
            env.reset()
    except BaseException as err:  # pragma: no cover - keep the worker from hanging
        errors.append(err)
    finally:
        release.set()
        worker.join(5)
    unwrapped.sim.run_until = original
    assert not errors
    env.step(FORWARD)  # one thread at a time is fine
    env.close()


def test_the_simulator_itself_refuses_to_be_copied(sim):
    with pytest.raises(TypeError, match="a Simulator cannot be copied or pickled"):
        copy.deepcopy(sim)
    with pytest.raises(TypeError, match="a Simulator cannot be copied or pickled"):
        pickle.dumps(sim)
    sim.run_until(1_000_000)  # untouched
