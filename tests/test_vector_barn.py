"""SmartCarBARN-v0 batched (``SmartCarBatchVectorEnv`` with the ``Barn`` part): per car its
single env bit for bit on planar and MuJoCo, the ``world`` reset option per car, and the
loop where no batch runs it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.tasks.barn import BarnProtocol
from smartcar_gym.envs.vector import SmartCarBatchVectorEnv, SmartCarLoopVectorEnv
from smartcar_gym.worlds.barn import BarnWorldError
from tests.test_vector_batched import rollout

N = 3
ENGINES = ["planar", pytest.param("mujoco", marks=pytest.mark.skipif(
    not __import__("importlib").util.find_spec("mujoco"), reason="needs the mujoco extra"))]
INFO_KEYS = ("is_success", "distance", "pose", "odom_pose", "collision", "clearance", "world",
             "outcome", "run_time_s", "optimal_time_s", "score", "score_025")


def make(engine: str, mode: str, mode_kind: str, **kwargs) -> gym.vector.VectorEnv:
    if mode_kind == "batch":
        return gym.make_vec("SmartCarBARN-v0", num_envs=N,
                            vectorization_mode="vector_entry_point", engine=engine,
                            autoreset_mode=mode, **kwargs)
    return gym.make_vec("SmartCarBARN-v0", num_envs=N, vectorization_mode="sync",
                        engine=engine, vector_kwargs={"autoreset_mode": AutoresetMode(mode)},
                        **kwargs)


def _at_end(info: dict, key: str) -> np.ndarray:
    if "final_info" not in info:
        return info[key]
    return np.where(info["_final_info"], info["final_info"][key], info[key])


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize(("mode", "timeout", "progress", "map_mode"), [
    ("NextStep", 25, "goal", "known"), ("SameStep", None, "goal", "known"),
    ("SameStep", None, "path", "known"), ("SameStep", None, "goal", "laser")])
def test_barn_batch_equals_n_single_envs_bit_for_bit(engine, mode, timeout, progress, map_mode,
                                                     monkeypatch):
    """Each car's observations (waypoint row included), rewards (with either progress
    reward), ends and infos (world, outcome, AT, OT, scores) are its single env's over 60
    steps, across autoresets that draw new worlds: ended by the time limit (SameStep) or the
    protocol's timeout, made short (NextStep), and by collisions; with the known map or each
    car's laser costmap (its global path replanned as it fills), the latter as the benchmark
    runs it: the laser's noise (the batch casts each car's first scan, which its builder
    leaves to it, with the noise the builder's would have had) and scans matched."""
    if timeout is not None:
        monkeypatch.setattr(BarnProtocol, "timeout_steps", lambda self, period_s: timeout)
    extra = ({"laser": {"noise_std_m": 0.01}, "localize": True} if map_mode == "laser"
             else {})
    batched = make(engine, mode, "batch", max_episode_steps=24 if timeout is None else 60,
                   progress=progress, map_mode=map_mode, **extra)
    single = make(engine, mode, "sync", max_episode_steps=24 if timeout is None else 60,
                  progress=progress, map_mode=map_mode, **extra)
    assert isinstance(batched, SmartCarBatchVectorEnv)
    builder = batched.unwrapped.builder.task

    def begun(*args):  # the batch's task begins each car; its builder's never does
        raise AssertionError("the builder's task began a car")

    monkeypatch.setattr(builder, "begin", begun)
    try:
        got, want = rollout(batched, 60, 3), rollout(single, 60, 3)
        assert np.array_equal(got[0][0], want[0][0])
        for key in INFO_KEYS:
            assert np.array_equal(got[0][1][key], want[0][1][key]), key
        outcomes, truncated = set(), 0
        for k, (g, w) in enumerate(zip(got[1:], want[1:], strict=True), 1):
            named = zip(("observations", "rewards", "terminated", "truncated"), g[:4], w[:4],
                        strict=True)
            for what, mine, theirs in [*named, *((f"info[{key!r}]", g[4][key], w[4][key])
                                                 for key in INFO_KEYS)]:
                assert np.array_equal(mine, theirs), f"step {k}: {what} differ"
            if mode == "SameStep":
                done = w[4].get("_final_obs", np.zeros(N, bool))
                assert np.array_equal(g[4].get("_final_obs", np.zeros(N, bool)), done)
                for i in np.flatnonzero(done):
                    assert np.array_equal(g[4]["final_obs"][i], w[4]["final_obs"][i])
                    for key in INFO_KEYS:
                        assert np.array_equal(g[4]["final_info"][key][i],
                                              w[4]["final_info"][key][i]), key
            ends = w[2] | w[3]
            outcomes |= set(_at_end(w[4], "outcome")[ends].tolist())
            truncated += int(w[3].sum())
        assert truncated >= 2 and len(set(np.concatenate(
            [s[4]["world"] for s in want[1:]]).tolist())) > N, outcomes
        if timeout is not None:
            assert "timeout" in outcomes, outcomes
        assert "collision" in outcomes, outcomes
        u = batched.unwrapped
        for i, env in enumerate(single.envs):
            assert np.array_equal(u.global_paths[i], env.unwrapped.global_path)
            if map_mode == "laser":  # the costmaps too, and the path came from them
                assert np.array_equal(u.costmaps.costs(i), env.unwrapped.costmaps.costs(0))
                assert env.unwrapped.costmaps.lethal(0).any()
        # the batch's builder only builds: its task keeps no laser map of its own
        assert u.builder.task.costmaps is None and u.builder.task.builds_only
    finally:
        batched.close()
        single.close()


@pytest.mark.parametrize("engine", ENGINES)
def test_world_option_per_car_and_for_all(engine):
    envs = make(engine, "NextStep", "batch", max_episode_steps=5)
    try:
        _, info = envs.reset(seed=0, options={"world": 6})
        assert info["world"].tolist() == [6] * N
        _, info = envs.reset(seed=0, options={"world": [0, 12, 294]})
        assert info["world"].tolist() == [0, 12, 294]
        single = gym.make("SmartCarBARN-v0", engine=engine)
        obs, one = single.reset(seed=1, options={"world": 12})
        assert np.array_equal(envs.reset(seed=0, options={"world": [0, 12, 294]})[0][1], obs)
        assert one["optimal_time_s"] == info["optimal_time_s"][1]
        single.close()
        mask = np.array([False, True, False])
        _, info = envs.reset(options={"world": [0, 30, 0], "reset_mask": mask})
        assert info["world"][1] == 30
        with pytest.raises(BarnWorldError, match="BARN world 300 is out of range"):
            envs.reset(options={"world": 300})
        with pytest.raises(ValueError, match="3 of them"):
            envs.reset(options={"world": [1, 2]})
        with pytest.raises(ValueError, match="SmartCarBARN-v0 takes 'world'"):
            envs.reset(options={"goal": (1.0, 0.0)})
    finally:
        envs.close()


@pytest.mark.parametrize("kwargs", [{"engine": "pybullet"},
                                    {"engine": "planar", "render_mode": "rgb_array"}])
def test_pybullet_and_render_fall_back_to_the_loop(kwargs):
    envs = gym.make_vec("SmartCarBARN-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        **kwargs)
    kind = type(envs)
    envs.close()
    assert kind is SmartCarLoopVectorEnv
