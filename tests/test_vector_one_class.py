"""One batched vector env for every engine with a car batch (``SmartCarBatchVectorEnv``): the
registry picks the engine's batch, and one task object runs over its cars."""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import inspect
import pkgutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
import smartcar_gym.envs.vector as vector
from smartcar_gym.envs.vector import SmartCarBatchVectorEnv, SmartCarLoopVectorEnv
from smartcar_gym.sim import engines
from smartcar_gym.sim.batch import CarBatch

MUJOCO = importlib.util.find_spec("mujoco") is not None
IDS = ("SmartCar-v0", "SmartCarNav-v0", "SmartCarGoal-v0")
CASTERBOT = Path(__file__).resolve().parent / "fixtures/casterbot_description"
#: a differential-drive robot: two drive wheels and a caster
DIFFERENTIAL = {"model": CASTERBOT / "urdf/casterbot.urdf.xacro",
                "controller_config": CASTERBOT / "config/casterbot_arbotix.yaml"}


def rollout(env_id: str, engine: str, steps: int = 12) -> list:
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                        engine=engine, max_episode_steps=5)
    try:
        assert isinstance(envs, SmartCarBatchVectorEnv) and envs.engine == engine
        out = [envs.reset(seed=4)[0]]
        rng = np.random.default_rng(1)
        for _ in range(steps):
            out.append(envs.step(rng.uniform(-1, 1, (2, 2)))[:4])
        return out
    finally:
        envs.close()


def flat(value) -> list[np.ndarray]:
    if isinstance(value, dict):
        return [a for k in sorted(value) for a in flat(value[k])]
    if isinstance(value, list | tuple):
        return [a for v in value for a in flat(v)]
    return [np.asarray(value)]


@pytest.mark.parametrize("env_id", IDS)
def test_an_engine_registered_under_another_name_is_batched_by_its_description(env_id,
                                                                                monkeypatch):
    """The planar engine again, as ``flatland`` (the registry only): its ids are batched by
    the description's ``car_batch``, and give the planar batch's numbers."""
    flatland = dataclasses.replace(engines.get_engine("planar"), name="flatland")
    monkeypatch.setitem(engines._REGISTRY, "flatland", flatland)
    a, b = flat(rollout(env_id, "flatland")), flat(rollout(env_id, "planar"))
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_an_engine_without_a_car_batch_runs_the_loop_and_says_why(monkeypatch):
    bare = dataclasses.replace(engines.get_engine("planar"), name="bare", car_batch=None)
    monkeypatch.setitem(engines._REGISTRY, "bare", bare)
    envs = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        engine="bare")
    assert isinstance(envs, SmartCarLoopVectorEnv)
    envs.close()
    with pytest.raises(ValueError, match=r"^SmartCarBatchVectorEnv \(SmartCar-v0 on bare\) "
                                         r"cannot run engine='bare': it has no car batch"):
        SmartCarBatchVectorEnv("SmartCar-v0", 2, engine="bare")


def test_a_differential_drive_model_falls_back_where_the_batch_takes_none(monkeypatch):
    """``batches_differential=False``: a two-wheel robot is the loop's (``CannotBatch``)."""
    skid_only = dataclasses.replace(engines.get_engine("planar"), name="skid_only",
                                    batches_differential=False)
    monkeypatch.setitem(engines._REGISTRY, "skid_only", skid_only)
    envs = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        engine="skid_only", **DIFFERENTIAL)
    assert isinstance(envs, SmartCarLoopVectorEnv)
    envs.close()
    envs = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        engine="planar", **DIFFERENTIAL)
    assert isinstance(envs, SmartCarBatchVectorEnv)  # the planar batch takes it
    envs.close()


def test_each_engine_batch_meets_the_protocol():
    envs = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        engine="planar")
    assert isinstance(envs.cars, CarBatch) and envs.cars.take_unstable() == ()
    envs.close()
    if MUJOCO:
        envs = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                            engine="mujoco")
        assert isinstance(envs.cars, CarBatch)
        envs.close()


def test_no_vector_class_is_named_after_an_engine_or_has_two_batched_parents():
    names = [m.name for m in pkgutil.iter_modules(vector.__path__)]
    classes = [c for m in names
               for _, c in inspect.getmembers(importlib.import_module(f"{vector.__name__}.{m}"),
                                              inspect.isclass)
               if c.__module__.startswith("smartcar_gym.envs.vector")]
    assert SmartCarBatchVectorEnv in classes
    for cls in classes:
        assert not any(e in cls.__name__.lower() for e in ("mujoco", "planar", "bullet")), cls
        batched = [b for b in cls.__bases__ if issubclass(b, SmartCarBatchVectorEnv)]
        assert len(batched) <= 1, cls


def test_the_old_alias_names_are_gone():
    for name in ("SmartCarPlanarVectorEnv", "SmartCarNavPlanarVectorEnv",
                 "SmartCarGoalPlanarVectorEnv", "SmartCarMujocoVectorEnv"):
        assert not hasattr(vector, name), name


@pytest.mark.parametrize(("env_id", "engine"), [
    ("SmartCar-v0", "planar"),
    ("SmartCarNav-v0", "planar"),
    ("SmartCarGoal-v0", "planar"),
    pytest.param("SmartCar-v0", "mujoco",
                 marks=pytest.mark.skipif(not MUJOCO, reason="needs the mujoco extra")),
])
def test_the_one_class_runs_each_id_on_each_engine_and_names_both(env_id, engine):
    label = rf"SmartCarBatchVectorEnv \({env_id} on {engine}\)"
    envs = SmartCarBatchVectorEnv(env_id, num_envs=2, engine=engine, max_episode_steps=3,
                                  autoreset_mode="SameStep", num_threads=1)
    try:
        assert type(envs) is SmartCarBatchVectorEnv
        assert (envs.env_id, envs.engine, envs.max_episode_steps) == (env_id, engine, 3)
        assert envs.metadata["autoreset_mode"].value == "SameStep"
        envs.close()
        with pytest.raises(RuntimeError, match=rf"^{label} is closed"):
            envs.step(np.zeros((2, 2)))
    finally:
        envs.close()
    if env_id != "SmartCarNav-v0":  # Nav's batch varies each car as its builder draws it
        with pytest.raises(ValueError, match=rf"^{label} cannot run randomize"):
            SmartCarBatchVectorEnv(env_id, num_envs=2, engine=engine, randomize="default")
