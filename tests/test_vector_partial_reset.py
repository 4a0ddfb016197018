"""Partial resets of the vector_entry_point envs (``reset(options={"reset_mask": mask})``, what
``smartcar-eval --vectorization batched`` runs on): the same as Gymnasium's SyncVectorEnv of
single envs, bit for bit."""

from __future__ import annotations

import importlib.util

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401

N = 3
MUJOCO = importlib.util.find_spec("mujoco") is not None
CASES = [
    ("SmartCarSim-v0", {}),
    ("SmartCar-v0", {}),  # pybullet: the loop of single envs
    pytest.param("SmartCar-v0", {"engine": "mujoco"}, marks=pytest.mark.skipif(
        not MUJOCO, reason="engine='mujoco' needs the mujoco extra")),
    pytest.param("SmartCarGoal-v0", {"engine": "mujoco"}, marks=pytest.mark.skipif(
        not MUJOCO, reason="engine='mujoco' needs the mujoco extra")),
    pytest.param("SmartCarNav-v0", {"engine": "mujoco"}, marks=pytest.mark.skipif(
        not MUJOCO, reason="engine='mujoco' needs the mujoco extra")),
    ("SmartCar-v0", {"engine": "planar"}),
    ("SmartCarGoal-v0", {"engine": "planar"}),
    ("SmartCarNav-v0", {"engine": "planar"}),
]
#: (steps, then the cars reset and their seeds); car 1's second reset keeps its generator
SCRIPT = [(4, [True, False, True], [20, None, 21]), (3, [False, True, False], [None, None, 9]),
          (3, None, None)]


def _run(envs: gym.vector.VectorEnv) -> list[tuple]:
    rng = np.random.default_rng(0)
    out = [envs.reset(seed=3)]
    for steps, mask, seeds in SCRIPT:
        for _ in range(steps):
            out.append(envs.step(rng.uniform(-1, 1, (N, 2)).astype(np.float32)))
        if mask is not None:
            out.append(envs.reset(seed=seeds, options={"reset_mask": np.array(mask)}))
    return out


def _equal(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    return np.array_equal(a, b)


@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
def test_partial_reset_equals_sync_single_envs(env_id, kwargs):
    kwargs = {"max_episode_steps": 50, **kwargs}
    numpy_yaw = env_id == "SmartCarSim-v0"
    batched = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)
    single = gym.make_vec(env_id, num_envs=N, vectorization_mode="sync", **kwargs)
    try:
        got, want = _run(batched), _run(single)
        for k, (g, w) in enumerate(zip(got, want, strict=True)):
            obs_g, obs_w = g[0], w[0]
            assert _equal(obs_g, obs_w), f"call {k}: observations differ"
            info_g, info_w = g[-1], w[-1]
            for key in ("is_success", "_is_success", "distance", "_pose"):
                assert np.array_equal(info_g[key], info_w[key]), f"call {k}: info[{key!r}]"
            for key in ("pose", "odom_pose"):
                if numpy_yaw:  # the numpy batch's yaws: docs/vector.md
                    np.testing.assert_allclose(info_g[key], info_w[key], atol=1e-6)
                else:
                    assert np.array_equal(info_g[key], info_w[key]), f"call {k}: info[{key!r}]"
            if len(g) == 5:
                for a, b in zip(g[1:4], w[1:4], strict=True):
                    assert np.array_equal(a, b), f"call {k}: rewards or ends differ"
        # a partial reset's info holds the reset cars only
        assert got[5][-1]["_pose"].tolist() == [True, False, True]
    finally:
        batched.close()
        single.close()


def test_partial_reset_input_is_checked():
    envs = gym.make_vec("SmartCarSim-v0", num_envs=N, vectorization_mode="vector_entry_point")
    try:
        with pytest.raises(gym.error.ResetNeeded, match="first reset"):
            envs.reset(options={"reset_mask": np.array([True, False, False])})
        envs.reset(seed=0)
        for bad in ([True, False, False], np.array([1, 0, 0]), np.zeros(N, dtype=bool),
                    np.ones(N + 1, dtype=bool)):
            with pytest.raises(ValueError, match=r"reset_mask.*bool array of shape \(3,\)"):
                envs.reset(options={"reset_mask": bad})
        # the mask may come with a goal
        obs, _ = envs.reset(options={"reset_mask": np.array([False, True, False]),
                                     "goal": (0.5, 0.5)})
        assert obs[1, -2:].tolist() == [0.5, 0.5] and obs[0, -2:].tolist() != [0.5, 0.5]
    finally:
        envs.close()


PARKED = [c for c in CASES if "engine" in (c.values[1] if hasattr(c, "values") else c[1])]


@pytest.mark.parametrize(("env_id", "kwargs"), PARKED)
def test_parked_cars_stand_still_and_the_others_step_as_before(env_id, kwargs):
    """``park``: the parked car is not simulated (its clock and pose stand still) until its
    next reset; the other cars step bit for bit as without it."""

    def run(park: bool) -> tuple[list, np.ndarray, np.ndarray]:
        envs = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point",
                            **kwargs)
        rng = np.random.default_rng(0)
        envs.reset(seed=3)
        out, poses = [], []
        for k in range(8):
            if park and k >= 2:
                envs.unwrapped.park(np.array([False, True, False]))
            obs, *_, info = envs.step(rng.uniform(-1, 1, (N, 2)).astype(np.float32))
            out.append({key: np.delete(v, 1, axis=0) for key, v in obs.items()}
                       if isinstance(obs, dict) else np.delete(obs, 1, axis=0))
            poses.append(info["pose"][1].copy())
        clock = envs.unwrapped.state.now_ns.copy()
        envs.reset(options={"reset_mask": np.array([False, True, False])})
        envs.step(np.ones((N, 2), dtype=np.float32))
        after = envs.unwrapped.state.now_ns.copy()
        envs.close()
        return out, np.array(poses), np.stack([clock, after])

    free, free_poses, _ = run(park=False)
    parked, poses, clocks = run(park=True)
    assert all(_equal(a, b) for a, b in zip(free, parked, strict=True))
    assert np.array_equal(poses[1], poses[-1]) and not np.array_equal(free_poses[1],
                                                                      free_poses[-1])
    assert clocks[0, 1] < clocks[0, 0] and clocks[1, 1] > 0  # stood still, then stepped
    envs = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)
    with pytest.raises(ValueError, match="park: expected a bool mask of shape"):
        envs.unwrapped.park(np.ones(N + 1, dtype=bool))
    envs.close()


@pytest.mark.parametrize("mask", [np.array([0.0, 1.0, 0.0]), np.array([0, 1, 0]),
                                  [False, True, False], np.array([[False, True, False]])])
def test_park_takes_only_a_bool_array_of_one_flag_per_car(mask):
    """Only a numpy bool array of shape (N,) parks cars: a float or int array (which a cast
    would read as "nonzero", 0.5 parking its car), a list or another shape is one line, and no
    car is parked."""
    envs = gym.make_vec("SmartCar-v0", num_envs=N, vectorization_mode="vector_entry_point",
                        engine="planar")
    try:
        envs.reset(seed=0)
        with pytest.raises(ValueError, match=r"^park: expected a bool mask of shape \(3,\) \(a "
                                             r"numpy array of dtype bool\), got a "):
            envs.unwrapped.park(mask)
        assert not envs.unwrapped.state.parked.any()
        envs.unwrapped.park(np.array([False, True, False]))
        assert envs.unwrapped.state.parked.tolist() == [False, True, False]
    finally:
        envs.close()


@pytest.mark.parametrize("engine", ["planar", pytest.param("mujoco", marks=pytest.mark.skipif(
    not MUJOCO, reason="engine='mujoco' needs the mujoco extra"))])
@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_a_parked_car_is_never_autoreset(engine, mode):
    """Every car's episode ends at its third step (``max_episode_steps``). Car 1, parked
    before the step that would reset it, is not reset (its clock stands, no new world is
    built) and never ends again; the others are autoreset as usual, and a ``reset`` that names
    car 1 unparks it."""
    envs = gym.make_vec("SmartCarNav-v0", num_envs=N, vectorization_mode="vector_entry_point",
                        engine=engine, max_episode_steps=3, autoreset_mode=mode)
    u = envs.unwrapped
    builder = u.builder
    builds = []
    reset = builder.reset
    builder.reset = lambda **kw: builds.append(1) or reset(**kw)
    parked = np.array([False, True, False])
    at = 3 if mode == "NextStep" else 2  # NextStep: after its end; SameStep: before it
    try:
        envs.reset(seed=0)
        action = np.full((N, 2), 0.5, dtype=np.float32)
        ends, final = [], []
        for k in range(5):
            if k == at:
                u.park(parked)
                clock = u.state.now_ns[1]
                builds.clear()
            _, _, terminated, truncated, info = envs.step(action)
            ends.append((terminated | truncated).tolist())
            final.append(info.get("_final_obs", np.zeros(N, dtype=bool)).tolist())
        assert ends[2] == [True, at == 3, True]  # the first episodes' end
        assert u.state.parked.tolist() == [False, True, False] and u.state.now_ns[1] == clock
        assert not any(end[1] for end in ends[at:]) and not any(f[1] for f in final)
        assert len(builds) == 2  # cars 0 and 2 autoreset once each, car 1 never
        envs.reset(seed=[None, 5, None], options={"reset_mask": parked})
        assert not u.state.parked.any() and u.state.now_ns[1] == 0 and len(builds) == 3
    finally:
        envs.close()


@pytest.mark.parametrize("engine", ["planar", pytest.param("mujoco", marks=pytest.mark.skipif(
    not MUJOCO, reason="engine='mujoco' needs the mujoco extra"))])
def test_the_engines_measure_the_listed_cars_clearances_alone(engine):
    """``CarBatch.clearances(pose, d, idx)``: each listed car's value is the one it has among
    every car's, bit for bit, in the listed order (the batch measures the running cars)."""
    envs = gym.make_vec("SmartCarNav-v0", num_envs=4, vectorization_mode="vector_entry_point",
                        engine=engine, obstacles=6, arena_size=2.0, goal_range=(0.4, 0.9))
    try:
        envs.reset(seed=1)
        u = envs.unwrapped
        every = u.cars.clearances(u.state.pose, 0.5, np.arange(4))
        assert (every < 0.5).sum() >= 2  # obstacles within reach of some cars
        idx = np.array([3, 0, 2])
        assert u.cars.clearances(u.state.pose, 0.5, idx).tolist() == every[idx].tolist()
        assert u.cars.clearances(u.state.pose, 0.5, np.zeros(0, dtype=np.int64)).shape == (0,)
    finally:
        envs.close()
