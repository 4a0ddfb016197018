"""``randomize`` batched: SmartCarNav-v0 and SmartCarBARN-v0 on the planar and MuJoCo batches
vary each car as its single env draws it (the builder's robot: body, track, motor, faulty
encoders, latency, start pose), per car bit for bit, ``info["randomization"]`` included; the
ids without a builder fall back to the loop."""

from __future__ import annotations

import importlib.util

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.vector import SmartCarBatchVectorEnv, SmartCarLoopVectorEnv
from tests.test_vector_batched import rollout

N = 3
ENGINES = ["planar", pytest.param("mujoco", marks=pytest.mark.skipif(
    importlib.util.find_spec("mujoco") is None, reason="needs the mujoco extra"))]


def make(env_id: str, engine: str, mode: str, vectorization: str, **kwargs) -> gym.vector.VectorEnv:
    if vectorization == "vector_entry_point":
        kwargs["autoreset_mode"] = mode
    else:
        kwargs["vector_kwargs"] = {"autoreset_mode": AutoresetMode(mode)}
    return gym.make_vec(env_id, num_envs=N, vectorization_mode=vectorization, engine=engine,
                        randomize="default", max_episode_steps=24, **kwargs)


def assert_same(got, want, where: str) -> None:
    """``got`` is ``want``: arrays equal with the same dtype, dicts key by key (what the loop
    leaves None in an object array, a car's info it did not give, is not compared)."""
    if isinstance(want, tuple):
        for k, (g, w) in enumerate(zip(got, want, strict=True)):
            assert_same(g, w, f"{where}, item {k}")
    elif isinstance(want, dict):
        assert set(got) >= set(want), f"{where}: missing {sorted(set(want) - set(got))}"
        for key in want:
            assert_same(got[key], want[key], f"{where}[{key!r}]")
    elif isinstance(want, np.ndarray) and want.dtype == object:
        for g, w in zip(got, want, strict=True):
            if w is not None:
                assert_same(g, w, where)
    else:
        assert np.array_equal(got, want), f"{where} differ"
        assert np.asarray(got).dtype == np.asarray(want).dtype, f"{where}: dtypes"


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize(("env_id", "mode"), [("SmartCarBARN-v0", "SameStep"),
                                              ("SmartCarNav-v0", "NextStep")])
def test_randomized_batch_equals_n_single_envs_bit_for_bit(env_id, engine, mode):
    batched = make(env_id, engine, mode, "vector_entry_point")
    single = make(env_id, engine, mode, "sync")
    assert isinstance(batched, SmartCarBatchVectorEnv)
    try:
        got, want = rollout(batched, 60, 3), rollout(single, 60, 3)
        assert_same(got[0], want[0], "reset")
        draws, ends = set(), 0
        for k, (g, w) in enumerate(zip(got[1:], want[1:], strict=True), 1):
            assert_same(g, w, f"step {k}")
            draws.update(w[4]["randomization"]["noise_seed"].tolist())
            ends += int((w[2] | w[3]).sum())
        # every car varies, episode by episode: delays, faulty encoders, the body
        assert ends >= N and len(draws) > N
        u = batched.unwrapped
        assert u.base.faulty and u.clocks.delays and len(set(u.base.base_width.tolist())) == N
        latency = got[-1][4]["randomization"]["latency"]
        assert latency.dtype == np.int64 and set(latency.tolist()) <= {0, 1}
    finally:
        batched.close()
        single.close()


def test_a_varied_car_drives_otherwise():
    """The draw reaches the physics: the same commands take differently drawn cars apart."""
    envs = gym.make_vec("SmartCarNav-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        engine="planar", randomize={"wheel_radius": [0.8, 1.2],
                                                    "track": [0.8, 1.2]})
    nominal = gym.make_vec("SmartCarNav-v0", num_envs=2,
                           vectorization_mode="vector_entry_point", engine="planar")
    try:
        poses = []
        for env in (envs, nominal):
            env.reset(seed=[4, 4], options={"obstacles": []})
            for _ in range(15):
                _, _, _, _, info = env.step(np.array([[1.0, 0.5], [1.0, 0.5]]))
            poses.append(info["pose"])
        varied, plain = poses
        assert np.array_equal(varied[0], varied[1])  # the same seed draws the same car
        assert np.abs(varied[0] - plain[0]).max() > 0.01
    finally:
        envs.close()
        nominal.close()


@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarGoal-v0"])
def test_ids_without_a_builder_fall_back_to_the_loop(env_id):
    with pytest.raises(ValueError, match=rf"cannot run randomize \(domain randomisation\) on "
                                         rf"{env_id}: the batch varies a car as the single env "
                                         r"that builds its episode draws it \(SmartCarNav-v0, "
                                         r"SmartCarBARN-v0\)"):
        SmartCarBatchVectorEnv(env_id, num_envs=2, engine="planar", randomize="default")
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                        engine="planar", randomize="default")
    assert isinstance(envs, SmartCarLoopVectorEnv)
    envs.close()
