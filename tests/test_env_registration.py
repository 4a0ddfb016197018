"""SmartCar-v0 / SmartCarSim-v0 registration, spec and the TimeLimit."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import registry
from gymnasium.wrappers import TimeLimit

import smartcar_gym
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.tasks.registry import task_of
from smartcar_gym.registration import ENTRY_POINT


def test_import_registers_both_ids_with_time_limit_and_threshold():
    # the other ids (SmartCarNav-v0, SmartCarGoal-v0): tests/test_registry.py
    assert {"SmartCar-v0", "SmartCarSim-v0"} <= set(smartcar_gym.ENV_IDS)
    for env_id in ("SmartCar-v0", "SmartCarSim-v0"):
        spec, how = registry[env_id], task_of(env_id).ids[env_id]
        assert spec.entry_point == ENTRY_POINT
        assert spec.max_episode_steps == how.max_episode_steps == 200
        assert spec.reward_threshold == how.reward_threshold == 15.0
    assert registry["SmartCar-v0"].kwargs == {"task": "reach"}
    assert registry["SmartCarSim-v0"].kwargs == {"task": "reach", "controller_mode": "sim"}


def test_register_envs_is_idempotent_and_silent():
    before = {k: registry[k] for k in smartcar_gym.ENV_IDS}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        smartcar_gym.register_envs()
        smartcar_gym.register_envs()
    assert [str(w.message) for w in caught] == []
    for env_id, spec in before.items():
        assert registry[env_id] is spec  # not re-registered


def test_make_by_id_and_by_module_prefix():
    env = gym.make("smartcar_gym:SmartCar-v0")
    try:
        assert isinstance(env.unwrapped, SmartCarEnv)
        assert env.spec.id == "SmartCar-v0"
        assert env.spec.max_episode_steps == 200
        assert env.unwrapped.robot.mode == "hardware"
        # the TimeLimit wrapper is in the stack
        wrapper, found = env, False
        while isinstance(wrapper, gym.Wrapper):
            found |= isinstance(wrapper, TimeLimit) and wrapper._max_episode_steps == 200
            wrapper = wrapper.env
        assert found
    finally:
        env.close()
    sim_env = gym.make("SmartCarSim-v0")
    try:
        assert sim_env.unwrapped.robot.mode == "sim"
    finally:
        sim_env.close()


def test_module_prefix_registers_in_a_fresh_interpreter():
    """What a spawned worker does: it has not imported smartcar_gym, the id prefix does it."""
    script = (
        "import sys, gymnasium as gym\n"
        "assert 'smartcar_gym' not in sys.modules\n"
        "env = gym.make('smartcar_gym:SmartCar-v0')\n"
        "env.reset(seed=0)\n"
        "print(env.spec.id, env.spec.max_episode_steps, 'SmartCarSim-v0' in gym.registry)\n"
        "env.close()\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.split() == ["SmartCar-v0", "200", "True"]
    assert out.stderr == ""  # pybullet's banners are silenced


def test_time_limit_truncates_not_terminates():
    env = gym.make("SmartCar-v0", max_episode_steps=5)
    try:
        env.reset(seed=0)
        zero = np.zeros(2, dtype=np.float32)
        for i in range(1, 6):
            _, _, terminated, truncated, _ = env.step(zero)
            assert terminated is False
            assert truncated is (i == 5)
    finally:
        env.close()
