"""A task is a plug-in: examples/task_plugin.py adds parking through the public API only, and
the task registry refuses what would make two tasks one."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.tasks import registry
from smartcar_gym.envs.tasks.reach import ReachTask
from smartcar_gym.envs.tasks.registry import (
    EnvId,
    TaskEntry,
    get_task,
    register_task,
    task_names,
    task_of,
)
from smartcar_gym.registration import ENV_IDS

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "task_plugin.py"


@pytest.mark.slow
def test_the_task_plugin_example_prints_ok():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get(
        "PYTHONPATH", "")])}
    result = subprocess.run([sys.executable, str(EXAMPLE)], capture_output=True, text=True,
                            timeout=600, cwd=ROOT, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip().splitlines()[-1] == "ok"


@pytest.fixture
def plugin():
    """The example's ``park`` task and its id registered, for this test only."""
    sys.path.insert(0, str(EXAMPLE.parent))
    try:
        import task_plugin
    finally:
        sys.path.remove(str(EXAMPLE.parent))
    task_plugin.register()
    yield task_plugin
    registry._REGISTRY.pop("park")
    gym.registry.pop(task_plugin.ENV_ID)


def test_a_plugged_task_batched_is_its_single_env_bit_for_bit(plugin):
    seeds, steps = [3, 4], 30
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, 2, 2)).astype(np.float32)
    envs = gym.make_vec(plugin.ENV_ID, num_envs=2, vectorization_mode="vector_entry_point",
                        engine="planar", max_episode_steps=-1)
    try:
        batched = [envs.reset(seed=seeds)[0]]
        for a in actions:
            obs, reward, *_ = envs.step(a)
            batched.append((obs, reward))
    finally:
        envs.close()
    for car, seed in enumerate(seeds):
        env = gym.make(plugin.ENV_ID, engine="planar")
        try:
            obs, _ = env.reset(seed=seed)
            assert np.array_equal(obs, batched[0][car])
            for k, a in enumerate(actions):
                obs, reward, terminated, truncated, info = env.step(a[car])
                assert np.array_equal(obs, batched[k + 1][0][car])
                assert reward == batched[k + 1][1][car]
                assert "in_box" in info and isinstance(info["in_box"], bool)
        finally:
            env.close()


def test_the_registry_makes_the_built_in_ids_and_refuses_a_second_owner():
    assert set(task_names()) >= {"reach", "nav", "goal", "barn"}
    assert task_of("SmartCarNav-v0").name == "nav"
    assert task_of("NoSuch-v0") is None
    assert gym.spec("SmartCarBARN-v0").kwargs["task"] == "barn"
    assert all(task_of(env_id) is not None for env_id in ENV_IDS)
    with pytest.raises(ValueError, match="task 'reach' is registered already"):
        register_task("reach", ReachTask, {"Other-v0": EnvId(10)})
    with pytest.raises(ValueError, match="id 'SmartCar-v0' belongs to task 'reach' already"):
        register_task("reach2", ReachTask, {"SmartCar-v0": EnvId(10)})
    with pytest.raises(ValueError, match="task must be one of .*'reach'.*got 'nope'"):
        get_task("nope")
    with pytest.raises(ValueError, match="a task's name must be an identifier"):
        TaskEntry("no good", ReachTask, {"X-v0": EnvId(1)})
    with pytest.raises(ValueError, match="needs at least one id"):
        TaskEntry("empty", ReachTask, {})
    assert "reach2" not in task_names()


def test_an_unknown_task_keyword_names_the_closest_of_every_keyword():
    with pytest.raises(TypeError, match=r"'goal_rnage' \(did you mean 'goal_range'\?\)"):
        gym.make("SmartCar-v0", goal_rnage=(0.5, 1.0))
    with pytest.raises(TypeError, match="SmartCarBARN-v0 takes no goal_range: the BARN "
                                        "protocol sets"):
        gym.make("SmartCarBARN-v0", goal_range=(0.5, 1.0))
