"""SmartCar-v0 on MuJoCo batched in C (``SmartCarBatchVectorEnv``): per-car equality with N
single MuJoCo envs, Gymnasium's vector conventions, the fallbacks and bad input."""

from __future__ import annotations

from pathlib import Path

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
from tests.test_vector_batched import rollout  # noqa: E402

N = 6
EPISODE = 25
CASTERBOT = Path(__file__).resolve().parent / "fixtures/casterbot_description"
#: a near goal and a small arena: successes and failures come before the time limit
SHORT = {"goal_range": (0.25, 0.4), "arena_size": 1.2}


def make(num_envs: int = N, **kwargs) -> gym.vector.VectorEnv:
    return gym.make_vec("SmartCar-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
                        engine="mujoco", **kwargs)


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_mujoco_batch_equals_n_single_envs_bit_for_bit(mode):
    """Each car's observations, rewards, ends and info are those of its own single env, across
    autoresets that leave cars at different points of the board's PID frame cycle, with the
    physics split between two worker threads."""
    batched = make(max_episode_steps=EPISODE, autoreset_mode=mode, num_threads=2, **SHORT)
    single = gym.make_vec("SmartCar-v0", num_envs=N, vectorization_mode="sync",
                          engine="mujoco", max_episode_steps=EPISODE, **SHORT,
                          vector_kwargs={"autoreset_mode": AutoresetMode(mode)})
    assert isinstance(batched, SmartCarBatchVectorEnv)
    assert (batched.env_id, batched.engine) == ("SmartCar-v0", "mujoco")
    try:
        got, want = rollout(batched, 45, 7), rollout(single, 45, 7)
        assert np.array_equal(got[0][0], want[0][0])
        terminated = truncated = 0
        for k, (g, w) in enumerate(zip(got[1:], want[1:], strict=True), 1):
            assert np.array_equal(g[0], w[0]), f"step {k}: observations differ"
            assert np.array_equal(g[1], w[1]), f"step {k}: rewards differ"
            assert np.array_equal(g[2], w[2]) and np.array_equal(g[3], w[3]), f"step {k}"
            for key in ("is_success", "_is_success", "distance", "pose", "odom_pose"):
                assert np.array_equal(g[4][key], w[4][key]), f"step {k}: info[{key!r}]"
            if mode == "SameStep":
                for i in np.flatnonzero(w[4].get("_final_obs", [])):
                    assert np.array_equal(g[4]["final_obs"][i], w[4]["final_obs"][i])
            terminated += int(w[2].sum())
            truncated += int(w[3].sum())
        # early ends put cars out of step with each other's frame cycle; limits ended others
        assert terminated >= 2 and truncated >= 1, (terminated, truncated)
        assert len(set(batched.unwrapped.state.now_ns.tolist())) > 1
    finally:
        batched.close()
        single.close()


def test_mujoco_batch_follows_gymnasium_conventions():
    envs = make(3, max_episode_steps=4)
    try:
        assert envs.observation_space == gym.vector.utils.batch_space(
            envs.single_observation_space, 3)
        assert envs.action_space.shape == (3, 2)
        obs, _ = envs.reset(seed=5)
        other, _ = envs.reset(seed=6)
        assert np.array_equal(other[0, -2:], obs[1, -2:])  # car i is seeded 5 + i
        envs.reset(seed=5)
        done = np.zeros(3, dtype=bool)
        for k in range(5):
            obs, rewards, terminated, truncated, info = envs.step(np.full((3, 2), 0.3))
            assert obs in envs.observation_space
            assert np.all(rewards[done] == 0)  # next-step autoreset
            assert info["is_success"].dtype == bool and info["_is_success"].all()
            done = terminated | truncated
            assert done.all() == (k == 3)
    finally:
        envs.close()


def test_what_mujoco_cannot_batch_falls_back_to_the_loop():
    for kwargs in ({"randomize": "default"}, {"stop_speed": 0.01}):
        envs = make(2, **kwargs)
        assert isinstance(envs, SmartCarLoopVectorEnv), kwargs
        envs.close()
    pybullet = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(pybullet, SmartCarLoopVectorEnv)
    pybullet.close()


def test_the_kinematic_mode_on_mujoco_falls_back_to_the_loop_of_its_single_envs():
    """No batch runs ``controller_mode="sim"`` on MuJoCo: the fastest faithful vector env is
    the loop, whose cars are their single envs bit for bit."""
    envs = make(2, controller_mode="sim")
    single = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="sync", engine="mujoco",
                          controller_mode="sim")
    try:
        got, want = rollout(envs, 10, 2), rollout(single, 10, 2)
        assert np.array_equal(got[0][0], want[0][0])
        for k, (g, w) in enumerate(zip(got[1:], want[1:], strict=True), 1):
            assert np.array_equal(g[0], w[0]), f"step {k}: observations differ"
            assert np.array_equal(g[1], w[1]), f"step {k}: rewards differ"
            assert np.array_equal(g[2], w[2]) and np.array_equal(g[3], w[3]), f"step {k}"
        assert isinstance(envs, SmartCarLoopVectorEnv)
    finally:
        envs.close()
        single.close()


@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarGoal-v0", "SmartCarNav-v0"])
def test_a_differential_drive_robot_falls_back_to_the_loop(env_id):
    """The batches run skid-steer bases; the casterbot (two drive wheels and a caster) runs as
    its single envs in the loop, as the batches' docstrings say."""
    kwargs = {"model": CASTERBOT / "urdf/casterbot.urdf.xacro",
              "controller_config": CASTERBOT / "config/casterbot_arbotix.yaml",
              "engine": "mujoco"}
    if env_id == "SmartCarNav-v0":
        kwargs["laser_mount"] = (0.0, 0.0, 0.1, 0.0)
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    single = gym.make(env_id, **kwargs)
    try:
        assert isinstance(envs, SmartCarLoopVectorEnv)
        obs, _ = envs.reset(seed=3)
        want, _ = single.reset(seed=3)
        if isinstance(obs, dict):
            assert all(np.array_equal(obs[k][0], want[k]) for k in want)
        else:
            assert np.array_equal(obs[0], want)
        envs.step(np.full((2, 2), 0.5))
    finally:
        envs.close()
        single.close()
    with pytest.raises(ValueError, match=rf"^SmartCarBatchVectorEnv \({env_id} on mujoco\) runs "
                                         r"skid-steer bases; a differential-drive model"):
        SmartCarBatchVectorEnv(env_id, num_envs=2, **kwargs)


def test_bad_input_is_one_line():
    envs = make(3)
    envs.reset(seed=0)
    try:
        with pytest.raises(ValueError, match=r"shape \(3, 2\).*mixed batch"):
            envs.step([np.zeros(2), np.zeros(3), np.zeros(2)])
        with pytest.raises(ValueError, match=r"cars \[2\] have NaN"):
            envs.step(np.array([[0, 0], [0, 0], [np.nan, 0]]))
    finally:
        envs.close()
    with pytest.raises(MemoryError, match=r"^SmartCar-v0 \(mujoco\): num_envs=\d+ needs about"):
        make(10**12)
    with pytest.raises(ValueError, match="^num_threads must be an integer >= 1"):
        make(2, num_threads=0)


def test_batched_mujoco_training_reads_its_own_preset():
    """``--vectorization batched --engine mujoco`` reads ``<env>-batched-mujoco``, then
    ``<env>-batched``; without the engine, ``<env>-batched``."""
    from smartcar_gym.agents.hyperparams import load_hyperparams

    mujoco = load_hyperparams("ppo", "SmartCar-v0", variant=("batched-mujoco", "batched"))
    assert mujoco["n_envs"] == 16 and mujoco["n_steps"] == 128
    assert load_hyperparams("ppo", "SmartCar-v0", variant="batched")["n_envs"] == 8
    sim = load_hyperparams("ppo", "SmartCarSim-v0", variant=("batched-mujoco", "batched"))
    assert sim["n_envs"] == 64 and sim["n_timesteps"] == 81920


def test_sb3_adapter_on_the_mujoco_batch():
    from smartcar_gym.agents.vec_envs import make_batched_vec_env

    venv = make_batched_vec_env("SmartCar-v0", 4, seed=0, env_kwargs={"engine": "mujoco"})
    try:
        assert isinstance(venv.unwrapped.venv, SmartCarBatchVectorEnv)
        assert venv.unwrapped.venv.engine == "mujoco"
        obs = venv.reset()
        assert obs.shape == (4, 21)
        obs, rewards, dones, infos = venv.step(np.zeros((4, 2), dtype=np.float32))
        assert rewards.shape == (4,) and len(infos) == 4 and "is_success" in infos[0]
    finally:
        venv.close()
