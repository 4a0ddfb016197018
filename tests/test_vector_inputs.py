"""The vector envs' arguments with one meaning and one check on every kind (numpy batch, MuJoCo
batches, the loop they fall back to): ``max_episode_steps`` as ``gym.make`` reads it, and bad
``num_threads``, seeds and actions each one line naming the argument and what it takes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401
from smartcar_gym.envs.vector import (  # noqa: E402
    SmartCarBatchVectorEnv,
    SmartCarLoopVectorEnv,
    SmartCarSimVectorEnv,
)

#: each kind of vector env: the numpy batch, a MuJoCo batch, and the loop on both engines
KINDS = {
    "numpy": ("SmartCarSim-v0", {}, SmartCarSimVectorEnv),
    "mujoco": ("SmartCar-v0", {"engine": "mujoco"}, SmartCarBatchVectorEnv),
    "goal-mujoco": ("SmartCarGoal-v0", {"engine": "mujoco"}, SmartCarBatchVectorEnv),
    "loop-mujoco": ("SmartCar-v0", {"engine": "mujoco", "randomize": "default"},
                    SmartCarLoopVectorEnv),
    "loop-numpy": ("SmartCarSim-v0", {"randomize": "default"}, SmartCarLoopVectorEnv),
}
#: near goals never reached by standing still, in an arena never left: only the limit ends
STILL = {"goal_range": (1.0, 1.2)}


def make(kind: str, num_envs: int = 2, **kwargs) -> gym.vector.VectorEnv:
    env_id, extra, cls = KINDS[kind]
    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                        **extra, **kwargs)
    assert type(envs) is cls
    if cls is SmartCarBatchVectorEnv:
        assert (envs.env_id, envs.engine) == (env_id, extra["engine"])
    return envs


def episode_length(envs: gym.vector.VectorEnv, most: int) -> int | None:
    """Steps standing still until the first truncation (None: none within ``most``)."""
    envs.reset(seed=0)
    for k in range(1, most + 1):
        *_, truncated, _ = envs.step(np.zeros((envs.num_envs, 2)))
        if truncated.any():
            return k
    return None


@pytest.mark.parametrize("kind", KINDS)
def test_max_episode_steps_means_what_it_means_to_gym_make(kind):
    limit = 100 if kind == "goal-mujoco" else 200  # the id's registered limit
    for value, want in ((None, limit), (7, 7), (-1, None)):
        envs = make(kind, max_episode_steps=value, **STILL)
        try:
            assert envs.unwrapped.max_episode_steps == want, value
            if value == 7:
                assert episode_length(envs, 8) == 7
            if value == -1:
                assert episode_length(envs, limit + 1) is None  # past the id's limit
        finally:
            envs.close()


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("value", [0, -5, 2.5, "x"])
def test_a_bad_max_episode_steps_is_refused_as_gym_make_refuses_it(kind, value):
    with pytest.raises(ValueError, match=r"^max_episode_steps must be a positive integer, None "
                                         r"\(SmartCar\w*-v0's limit, \d+ steps\) or -1 \(no "
                                         r"limit\), got "):
        make(kind, max_episode_steps=value)


@pytest.mark.parametrize("kind", ["numpy", "mujoco", "goal-mujoco", "loop-mujoco"])
@pytest.mark.parametrize("value", [2.5, "x", 0, True])
def test_a_bad_num_threads_is_one_line(kind, value):
    with pytest.raises(ValueError, match=r"^num_threads must be an integer >= 1 \(worker threads "
                                         r"stepping the physics\) or None \(one per CPU\), got "):
        make(kind, num_threads=value)


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_takes_num_threads(kind):
    """The numpy batch has no worker threads, but takes the argument every kind takes (a
    batched training passes its thread count whatever the id)."""
    make(kind, num_threads=2).close()


@pytest.fixture(scope="module", params=list(KINDS))
def envs(request):
    made = make(request.param)
    made.reset(seed=0)
    yield made
    made.close()


@pytest.mark.parametrize("seed", [1.5, "x", -1, [1, 2.5], [1, "x"]])
def test_a_bad_seed_is_one_line(envs, seed):
    with pytest.raises(ValueError, match=r"^reset\(seed=\.\.\.\) must be an integer >= 0, None "
                                         r"or a list of 2 \(an integer or None per car\), got "):
        envs.reset(seed=seed)


def test_a_seed_list_of_the_wrong_length_is_one_line(envs):
    with pytest.raises(ValueError, match=r"^reset\(seed=\[\.\.\.\]\) needs 2 seeds \(one per "
                                         r"car\), got 3$"):
        envs.reset(seed=[1, 2, 3])


def test_complex_actions_are_refused_not_truncated(envs):
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"^actions must be real numbers \(linear, angular per "
                                         r"car\), got complex values"):
        envs.step(np.array([[0.5 + 0.5j, 0.0], [0.0, 0.0]]))
    assert envs.reset(seed=np.int64(3))[0] is not None  # numpy integers are integers


@pytest.mark.parametrize(("env_id", "kwargs"), [
    *((env_id, extra) for env_id, extra, _ in KINDS.values()),
    ("SmartCar-v0", {"engine": "planar"}), ("SmartCar-v0", {}),
    ("SmartCarNav-v0", {"engine": "planar"})])
def test_loop_reason_says_which_ids_the_entry_point_runs_as_a_loop(env_id, kwargs):
    from smartcar_gym.envs.vector.make import loop_reason

    envs = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", **kwargs)
    try:
        why = loop_reason(env_id, kwargs)
        assert (why is not None) == isinstance(envs, SmartCarLoopVectorEnv), why
    finally:
        envs.close()
    if (env_id, kwargs) == ("SmartCar-v0", {}):  # the default engine, pybullet
        assert why == "engine='pybullet': it has no car batch (Engine.car_batch)"
