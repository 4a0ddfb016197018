"""The envs on MuJoCo (engine="mujoco"): Gymnasium's checks, determinism, close(), defaults."""

from __future__ import annotations

import contextlib
import ctypes
import gc
import os
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401
from smartcar_gym.envs.smartcar_env import SmartCarEnv  # noqa: E402

ROLLOUT = """
import hashlib, sys, numpy as np, gymnasium as gym, smartcar_gym
env = gym.make(sys.argv[1], engine="mujoco", randomize=sys.argv[2] or None)
digest = hashlib.sha256()
obs, _ = env.reset(seed=7)
rng = np.random.default_rng(1)
for _ in range(40):
    obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
    digest.update(np.asarray(obs, dtype=np.float64).tobytes())
    digest.update(np.float64(reward).tobytes())
    if terminated or truncated:
        env.reset()
env.close()
print(digest.hexdigest())
"""


@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarNav-v0", "SmartCarGoal-v0"])
def test_check_env_passes_on_mujoco(env_id):
    env = gym.make(env_id, engine="mujoco")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # check_env's warnings are failures here
        check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped.sim.engine == "mujoco"
    env.close()


def test_pybullet_stays_the_default():
    env = gym.make("SmartCar-v0")
    assert env.unwrapped.engine == "pybullet" and env.unwrapped.sim.engine == "pybullet"
    env.close()


def test_an_unknown_engine_is_one_line_listing_the_engines():
    with pytest.raises(ValueError, match=r"^engine must be one of 'pybullet', 'mujoco', 'planar', "
                                         r"got 'bullet3'$"):
        gym.make("SmartCar-v0", engine="bullet3")


def test_smartcar_sim_says_in_one_line_that_it_steps_no_physics():
    poses = []
    for engine in ("mujoco", "pybullet"):
        with pytest.warns(UserWarning, match=r"^.*steps no physics: engine='\w+' only holds"):
            env = gym.make("SmartCarSim-v0", engine=engine)
        env.reset(seed=0)
        for _ in range(5):
            _, _, _, _, info = env.step(np.array([1.0, 0.5], dtype=np.float32))
        poses.append(info["pose"])
        env.close()
    assert poses[0] == pytest.approx(poses[1], abs=1e-6)  # kinematic: the same on both


@pytest.mark.parametrize("env_id,randomize", [("SmartCarNav-v0", "default")])
def test_rollouts_are_bit_identical_across_processes(env_id, randomize):
    digests = {
        subprocess.run([sys.executable, "-c", ROLLOUT, env_id, randomize], check=True,
                       capture_output=True, text=True).stdout.strip()
        for _ in range(2)
    }
    assert len(digests) == 1
    # and in this process, after another env ran in between
    env = gym.make("SmartCar-v0", engine="mujoco")
    env.reset(seed=3)
    env.close()
    namespace = {"__name__": "rollout"}
    old_argv = sys.argv
    sys.argv = ["x", env_id, randomize]
    try:
        with open(os.devnull, "w") as devnull, contextlib.redirect_stdout(devnull):
            exec(ROLLOUT, namespace)  # noqa: S102
    finally:
        sys.argv = old_argv
    assert namespace["digest"].hexdigest() in digests


def test_mujoco_and_pybullet_rollouts_differ_but_both_reach_similar_poses():
    poses = {}
    for engine in ("pybullet", "mujoco"):
        env = gym.make("SmartCar-v0", engine=engine)
        env.reset(seed=0)
        for _ in range(20):
            _, _, _, _, info = env.step(np.array([0.6, 0.0], dtype=np.float32))
        poses[engine] = np.array(info["pose"])
        env.close()
    assert not np.array_equal(poses["pybullet"], poses["mujoco"])
    assert poses["mujoco"] == pytest.approx(poses["pybullet"], abs=0.02)


def _rss_mb() -> float:
    gc.collect()
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).malloc_trim(0)
    with open("/proc/self/statm") as stream:
        return int(stream.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


@pytest.mark.slow
def test_200_make_reset_close_cycles_do_not_grow(shipped_model, shipped_config):
    def cycle():
        env = SmartCarEnv(model=shipped_model, controller_config=shipped_config, engine="mujoco")
        env.reset(seed=0)
        env.step(np.zeros(2, dtype=np.float32))
        env.close()
        assert env.sim is None

    for _ in range(10):
        cycle()
    before = _rss_mb()
    for _ in range(200):
        cycle()
    growth = _rss_mb() - before
    assert growth < 10.0, f"{growth:.1f} MB more after 200 cycles"


def test_a_closed_env_resets_into_a_new_world():
    env = gym.make("SmartCar-v0", engine="mujoco")
    first, _ = env.reset(seed=5)
    env.close()
    again, _ = env.reset(seed=5)
    assert np.array_equal(first, again)
    env.close()



def test_a_copy_of_a_mujoco_env_gets_a_world_of_its_own():
    import copy

    env = gym.make("SmartCar-v0", engine="mujoco")
    first, _ = env.reset(seed=4)
    twin = copy.deepcopy(env)
    again, _ = twin.reset(seed=4)
    assert np.array_equal(first, again)
    assert twin.unwrapped.sim is not env.unwrapped.sim
    assert twin.unwrapped.sim.engine == "mujoco"
    twin.close()
    env.step(np.zeros(2, dtype=np.float32))  # the original still runs
    env.close()
