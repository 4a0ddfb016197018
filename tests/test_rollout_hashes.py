"""Seeded rollouts of every id on every engine, single envs and batched, against recorded hashes.

The hashes in ``fixtures/rollout_hashes.json`` were recorded on main 094ff80, before the
engines became plug-ins and the batched envs one class (issue 41): a redesign must leave every
rollout bit for bit what it was. Each digest covers the reset observations, every observation,
reward, termination and truncation flag, and every number in ``info``. SmartCarBARN-v0's
(single on every engine, batched on MuJoCo and planar, ``localize`` off and on) were recorded
on main 49d6fad, before the tasks were written once (issue 53).

Recording them again is a deliberate act, for a change that means to alter behaviour:
``SMARTCAR_RECORD_HASHES=1 python -m pytest tests/test_rollout_hashes.py`` rewrites the file.
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.registration import ENV_IDS

#: the ids whose rollouts were recorded on 094ff80 (SmartCarBARN-v0's, recorded on 49d6fad, are
#: their own cases below)
RECORDED_IDS = ("SmartCar-v0", "SmartCarSim-v0", "SmartCarArrive-v0", "SmartCarNav-v0",
                "SmartCarGoal-v0")
HASHES = Path(__file__).parent / "fixtures" / "rollout_hashes.json"
RECORD = os.environ.get("SMARTCAR_RECORD_HASHES") == "1"
ENGINES = ("pybullet", "mujoco", "planar")
SEED = 11
STEPS = 24  # with max_episode_steps 10: every car truncates twice, so autoreset is crossed
LIMIT = 10
NUM_ENVS = 3


def _feed(digest: Any, value: Any) -> None:
    """Every number in ``value`` (dicts in key order, arrays with their dtype and shape)."""
    if isinstance(value, dict):
        for key in sorted(value, key=str):
            digest.update(str(key).encode())
            _feed(digest, value[key])
    elif isinstance(value, list | tuple):
        for item in value:
            _feed(digest, item)
    elif isinstance(value, np.ndarray) and value.dtype == object:
        for item in value.ravel():
            _feed(digest, item)
    elif isinstance(value, np.ndarray | np.generic | bool | int | float):
        arr = np.asarray(value)
        digest.update(f"{arr.dtype.str}{arr.shape}".encode())
        digest.update(np.ascontiguousarray(arr).tobytes())
    elif value is None or isinstance(value, str):
        digest.update(repr(value).encode())
    else:
        raise TypeError(f"cannot hash {type(value).__name__} in a rollout: {value!r}")


def _actions(shape: tuple[int, ...]) -> np.ndarray:
    return np.random.default_rng(5).uniform(-1.0, 1.0, size=(STEPS, *shape)).astype(np.float32)


def single_digest(env_id: str, engine: str) -> str:
    digest = hashlib.sha256()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # SmartCarSim-v0's "engine only holds the body"
        env = gym.make(env_id, engine=engine, max_episode_steps=LIMIT)
    try:
        _feed(digest, env.reset(seed=SEED))
        for action in _actions((2,)):
            step = env.step(action)
            _feed(digest, step)
            if step[2] or step[3]:
                _feed(digest, env.reset())
    finally:
        env.close()
    return digest.hexdigest()


def batched_digest(env_id: str, engine: str, mode: str) -> str:
    digest = hashlib.sha256()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        envs = gym.make_vec(env_id, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point",
                            engine=engine, max_episode_steps=LIMIT, autoreset_mode=mode)
    try:
        _feed(digest, envs.reset(seed=SEED))
        for actions in _actions((NUM_ENVS, 2)):
            _feed(digest, envs.step(actions))
    finally:
        envs.close()
    return digest.hexdigest()


BARN = "SmartCarBARN-v0"
BARN_WORLDS = [0, 6, 12]  # the first run's worlds (car i's, batched); the second's are drawn


def barn_single_digest(engine: str, localize: bool) -> str:
    """A run in world 0, then one in a world drawn from the training worlds (no time limit
    cuts a BARN run: the env ends it)."""
    digest = hashlib.sha256()
    env = gym.make(BARN, engine=engine, localize=localize)
    try:
        _feed(digest, env.reset(seed=SEED, options={"world": BARN_WORLDS[0]}))
        for k, action in enumerate(_actions((2,))):
            if k == STEPS // 2:
                _feed(digest, env.reset())
            _feed(digest, env.step(action))
    finally:
        env.close()
    return digest.hexdigest()


def barn_batched_digest(engine: str, mode: str, localize: bool) -> str:
    """Cars in worlds 0, 6 and 12, then cars 0 and 2 reset mid-way into drawn worlds (no run
    ends in these steps, so the autoreset mode changes nothing: NextStep only)."""
    digest = hashlib.sha256()
    envs = gym.make_vec(BARN, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point",
                        engine=engine, autoreset_mode=mode, localize=localize)
    try:
        _feed(digest, envs.reset(seed=SEED, options={"world": BARN_WORLDS}))
        for k, actions in enumerate(_actions((NUM_ENVS, 2))):
            if k == STEPS // 2:
                mask = np.array([True, False, True])
                _feed(digest, envs.reset(options={"reset_mask": mask}))
            _feed(digest, envs.step(actions))
    finally:
        envs.close()
    return digest.hexdigest()


CASES = [(env_id, engine, how) for env_id in RECORDED_IDS for engine in ENGINES
         for how in ("single", "NextStep", "SameStep")]
CASES += [(BARN + localize, engine, how) for localize in ("", "+localize")
          for engine, hows in (("pybullet", ("single",)),
                               ("mujoco", ("single", "NextStep")),
                               ("planar", ("single", "NextStep")))
          for how in hows]


def _key(env_id: str, engine: str, how: str) -> str:
    return f"{env_id}/{engine}/{how}"


def _digest(env_id: str, engine: str, how: str) -> str:
    if env_id.startswith(BARN):
        localize = env_id.endswith("+localize")
        if how == "single":
            return barn_single_digest(engine, localize)
        return barn_batched_digest(engine, how, localize)
    if how == "single":
        return single_digest(env_id, engine)
    return batched_digest(env_id, engine, how)


@pytest.fixture(scope="module")
def recorded() -> dict[str, str]:
    return json.loads(HASHES.read_text()) if HASHES.exists() else {}


@pytest.mark.slow
@pytest.mark.parametrize(("env_id", "engine", "how"), CASES, ids=[_key(*c) for c in CASES])
def test_rollout_is_bit_for_bit_the_recorded_one(env_id, engine, how, recorded):
    if engine == "mujoco":
        pytest.importorskip("mujoco")
    got = _digest(env_id, engine, how)
    key = _key(env_id, engine, how)
    if RECORD:
        recorded[key] = got
        HASHES.write_text(json.dumps(dict(sorted(recorded.items())), indent=1) + "\n")
        return
    assert key in recorded, f"no hash recorded for {key}: record with SMARTCAR_RECORD_HASHES=1"
    assert got == recorded[key], f"{key}: the rollout changed"


def test_every_case_has_a_recorded_hash(recorded):
    assert sorted(recorded) == sorted(_key(*c) for c in CASES)
    # SmartCarSim-v0 steps no physics: its numpy batch is the same on every engine
    # SmartCarSim-v0 steps no physics: its numpy batch is the same on every engine (6 keys,
    # one hash per autoreset mode)
    assert len(set(recorded.values())) == len(recorded) - 4, "two cases hashed the same rollout"


def test_the_recorded_ids_are_registered():
    assert set(RECORDED_IDS) <= set(ENV_IDS)


def test_the_digest_sees_one_changed_bit():
    a, b = hashlib.sha256(), hashlib.sha256()
    _feed(a, {"pose": np.array([0.1, 0.2]), "is_success": False})
    _feed(b, {"pose": np.array([0.1, np.nextafter(0.2, 1.0)]), "is_success": False})
    assert a.hexdigest() != b.hexdigest()
