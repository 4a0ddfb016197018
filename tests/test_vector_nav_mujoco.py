"""SmartCarNav-v0 on MuJoCo batched in C (``SmartCarBatchVectorEnv``): per-car equality
with N single MuJoCo Nav envs (scan, collisions, autoresets), no single env stepped, reset
options, Gymnasium's vector conventions and the fallbacks."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401
from smartcar_gym.envs.smartcar_env import SmartCarEnv  # noqa: E402
from smartcar_gym.envs.vector import (  # noqa: E402
    SmartCarBatchVectorEnv,
    SmartCarLoopVectorEnv,
)
from tests.test_vector_batched import rollout  # noqa: E402

#: 8 cars on 2 threads: the worker threads take 4 cars or more each
N = 8
EPISODE = 25
#: near goals among 6 obstacles in a small arena: with seed 1 and ``rollout``'s policy, cars
#: reach goals, hit obstacles and leave the arena before the time limit ends the others
SHORT = {"goal_range": (0.4, 0.9), "obstacles": 6, "arena_size": 2.0, "proximity_penalty": 1.0}
INFO_KEYS = ("is_success", "_is_success", "distance", "pose", "odom_pose", "collision",
             "_collision", "clearance")


def make(num_envs: int = N, **kwargs) -> gym.vector.VectorEnv:
    return gym.make_vec("SmartCarNav-v0", num_envs=num_envs,
                        vectorization_mode="vector_entry_point", engine="mujoco", **kwargs)


def single_envs(num_envs: int = N, mode: str = "NextStep", **kwargs) -> gym.vector.VectorEnv:
    return gym.make_vec("SmartCarNav-v0", num_envs=num_envs, vectorization_mode="sync",
                        engine="mujoco", vector_kwargs={"autoreset_mode": AutoresetMode(mode)},
                        **kwargs)


@pytest.mark.parametrize(("mode", "laser"), [
    ("NextStep", {}),
    # noise from each car's generator; 13 Hz scans split the controller's intervals
    ("SameStep", {"noise_std_m": 0.01, "rate_hz": 13.0}),
])
def test_nav_batch_equals_n_single_envs_bit_for_bit(mode, laser):
    """Each car's observations (scan sectors included), rewards (collision and proximity
    terms), ends and info are its own single env's, across autoresets that rebuild its
    obstacles, with the physics, scans and clearances split between two worker threads."""
    kwargs = {**SHORT, "max_episode_steps": EPISODE, "laser": laser}
    batched = make(autoreset_mode=mode, num_threads=2, **kwargs)
    single = single_envs(mode=mode, **kwargs)
    assert isinstance(batched, SmartCarBatchVectorEnv)
    assert (batched.env_id, batched.engine) == ("SmartCarNav-v0", "mujoco")
    try:
        got, want = rollout(batched, 50, 1), rollout(single, 50, 1)
        assert np.array_equal(got[0][0], want[0][0])
        for key in ("collision", "clearance", "distance"):
            assert np.array_equal(got[0][1][key], want[0][1][key]), key
        ends = {"terminated": 0, "truncated": 0, "collision": 0, "success": 0}
        for k, (g, w) in enumerate(zip(got[1:], want[1:], strict=True), 1):
            assert np.array_equal(g[0], w[0]), f"step {k}: observations differ"
            assert np.array_equal(g[1], w[1]), f"step {k}: rewards differ"
            assert np.array_equal(g[2], w[2]) and np.array_equal(g[3], w[3]), f"step {k}"
            for key in INFO_KEYS:
                assert np.array_equal(g[4][key], w[4][key]), f"step {k}: info[{key!r}]"
            if mode == "SameStep":
                assert np.array_equal(g[4].get("_final_obs", np.zeros(N, bool)),
                                      w[4].get("_final_obs", np.zeros(N, bool)))
                for i in np.flatnonzero(w[4].get("_final_obs", [])):
                    assert np.array_equal(g[4]["final_obs"][i], w[4]["final_obs"][i])
                    for key in ("is_success", "collision", "clearance"):
                        assert g[4]["final_info"][key][i] == w[4]["final_info"][key][i]
            ends["terminated"] += int(w[2].sum())
            ends["truncated"] += int(w[3].sum())
            ends["collision"] += int(_at_end(w[4], "collision").sum())
            ends["success"] += int(_at_end(w[4], "is_success").sum())
        # successes, collisions and one more failure; time limits end the rest
        assert ends["terminated"] >= 3 and ends["truncated"] >= 4, ends
        assert ends["collision"] >= 1 and ends["success"] >= 1, ends
        u = batched.unwrapped
        for i, env in enumerate(single.envs):
            assert np.array_equal(u.state.readings["scan"][i], env.unwrapped.laser.latest.ranges)
            assert u.obstacles[i] == env.unwrapped.obstacles
        assert len(set(u.state.now_ns.tolist())) > 1  # cars out of step with each other
    finally:
        batched.close()
        single.close()


def _at_end(info: dict, key: str) -> np.ndarray:
    """``info[key]`` of the step, or of the episode's last step where SameStep reset a car."""
    if "final_info" not in info:
        return info[key]
    return np.where(info["_final_info"], info["final_info"][key], info[key])


def test_nav_batch_steps_no_single_env(monkeypatch):
    """Only resets go through the builder; a step never calls SmartCarEnv.step."""
    envs = make(2, max_episode_steps=3, **SHORT)
    try:
        envs.reset(seed=0)

        def refuse(*args, **kwargs):
            raise AssertionError("a single env was stepped")

        monkeypatch.setattr(SmartCarEnv, "step", refuse)
        for _ in range(4):  # across the autoreset
            envs.step(np.full((2, 2), 0.2))
    finally:
        envs.close()


def test_reset_options_give_every_car_the_layout():
    layout = [{"shape": "box", "position": [0.5, 0.0], "size": [0.2, 0.6], "yaw": 0.0},
              {"shape": "cylinder", "position": [0.0, 0.6], "size": [0.3], "yaw": 0.0}]
    options = {"obstacles": layout, "goal": (0.9, 0.1)}
    batched, single = make(3, max_episode_steps=6), single_envs(3, max_episode_steps=6)
    try:
        obs, info = batched.reset(seed=4, options=options)
        want, want_info = single.reset(seed=4, options=options)
        assert np.array_equal(obs, want)
        assert np.array_equal(info["clearance"], want_info["clearance"])
        assert all(len(o) == 2 and o[0].shape == "box" for o in batched.unwrapped.obstacles)
        for _ in range(3):
            step, step_want = batched.step(np.full((3, 2), 0.6)), single.step(np.full((3, 2), 0.6))
            for g, w in zip(step[:4], step_want[:4], strict=True):
                assert np.array_equal(g, w)
        # the layout was this episode's: the next reset draws each car's own again
        batched.reset(seed=4)
        drawn = batched.unwrapped.obstacles
        assert len(drawn[0]) == 8 and drawn[0] != drawn[1]
        with pytest.raises(ValueError, match=r"options\['obstacles'\]\[0\].*overlaps the car"):
            batched.reset(options={"obstacles": [{"shape": "cylinder", "position": [0.0, 0.0],
                                                  "size": [0.2]}]})
    finally:
        batched.close()
        single.close()


def test_nav_batch_follows_gymnasium_conventions():
    envs = make(3, max_episode_steps=4)
    try:
        assert envs.observation_space == gym.vector.utils.batch_space(
            envs.single_observation_space, 3)
        assert envs.observation_space.shape == (3, 57) and envs.action_space.shape == (3, 2)
        assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        obs, _ = envs.reset(seed=5)
        other, _ = envs.reset(seed=6)
        assert np.array_equal(other[0, 19:21], obs[1, 19:21])  # car i is seeded 5 + i
        assert np.array_equal(other[0, 21:], obs[1, 21:])  # its scan, among its obstacles
        envs.reset(seed=5)
        envs.action_space.seed(0)
        done = np.zeros(3, dtype=bool)
        for k in range(5):
            obs, rewards, terminated, truncated, info = envs.step(envs.action_space.sample())
            assert obs in envs.observation_space
            assert rewards.shape == (3,) and rewards.dtype == np.float64
            assert np.all(rewards[done] == 0)  # next-step autoreset
            assert info["collision"].dtype == bool and info["_collision"].all()
            done = terminated | truncated
            assert done.all() == (k == 3)
    finally:
        envs.close()


def test_what_the_nav_batch_cannot_run_falls_back_to_the_loop():
    for kwargs in ({"controller_mode": "sim"}, {"render_mode": "rgb_array"}):
        envs = make(2, **kwargs)
        assert isinstance(envs, SmartCarLoopVectorEnv), kwargs
        envs.close()
    pybullet = gym.make_vec("SmartCarNav-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(pybullet, SmartCarLoopVectorEnv)
    pybullet.close()
    with pytest.raises(ValueError, match=r"^SmartCarBatchVectorEnv \(SmartCarNav-v0 on mujoco\) "
                                         r"cannot run render_mode"):
        SmartCarBatchVectorEnv("SmartCarNav-v0", 2, engine="mujoco", render_mode="rgb_array")
    with pytest.raises(MemoryError, match=r"^SmartCarNav-v0 \(mujoco\): num_envs=\d+ needs"):
        make(10**12)
