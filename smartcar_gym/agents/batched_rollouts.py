"""Seeded evaluation episodes in one vector env: ``smartcar-eval --vectorization batched``.

``evaluate_batched_episodes`` makes ``n_envs`` cars of the id's ``vector_entry_point``
(``gym.make_vec(env_id, vectorization_mode="vector_entry_point")``: the MuJoCo batches, the
numpy SmartCarSim-v0 batch, N single envs in a loop for the ids and options that are not
batched; any engine whose vector env follows docs/vector.md's conventions plugs in). It runs
the episodes of ``rollouts.evaluate_policy_episodes``: episode ``i`` is seeded ``seed + i``,
and a car whose episode ends is reset at once with the next episode's seed (Gymnasium's
partial reset, ``reset(seed=[...], options={"reset_mask": mask})``), so the records do not
depend on ``n_envs`` or on which car ran an episode.

Actions come from one ``predict`` call on all cars' observations per step (normalised with
the policy's frozen statistics, as ``Policy.act`` does one at a time). Where the vector env is
bit for bit its single envs (the MuJoCo and numpy batches, the loop), the records equal the
sequential evaluation's exactly for a policy whose actions do not depend on batching (a plain
function of one observation: ``testing.FunctionModel`` calls it per observation). A torch
network's batched matrix products round differently from a batch of one: its actions differ
by about 1e-7. In the hardware mode (SmartCar-v0's default) the controller turns them into
integer encoder ticks, almost always the same ones, so the paths stayed equal to the last bit
(the tests allow ``RECORD_TOLERANCE``; the returns' action cost differs by about 1e-8); in
the kinematic mode (SmartCarSim-v0) the car follows the commanded twist, so the difference
grows along an episode and an episode may end otherwise (1 of 1,000 with the shipped policy:
docs/performance.md). The same command (same ``n_envs``) gives the same records.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from collections.abc import Iterator, Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.agents.env_factory import EnvSetupError
from smartcar_gym.agents.rollouts import EpisodeRecord, _check_spaces
from smartcar_gym.policy import DEFAULT_ENV_ID, Policy, as_policy

__all__ = ["DEFAULT_BATCH", "RECORD_TOLERANCE", "act_batch", "evaluate_batched_episodes",
           "make_batched_env"]

#: cars in the batch when ``n_envs`` is not given: more cars spread the batch's numpy cost
#: further, and the cars left without an episode at the end are parked where the batch can
#: (``park``: MuJoCo's and the planar engine's), so that the tail costs no physics. Measured
#: (1,000 episodes on MuJoCo, 2 cores, interleaved): 128 cars took 13-17 % less wall time than
#: 64 in each of 4 rounds; 256 were no faster than 128
DEFAULT_BATCH = 128
#: bound on |batched - sequential| of an SB3 model's returns, final distances and paths (m) in
#: the hardware mode, as the tests check it (measured: 0 m for paths, about 5e-8 for returns)
RECORD_TOLERANCE = 1e-4


def make_batched_env(env_id: str, num_envs: int,
                     env_kwargs: dict[str, Any] | None = None) -> gym.vector.VectorEnv:
    """``num_envs`` cars of ``env_id`` through its ``vector_entry_point`` (Gymnasium's
    ``"NextStep"`` autoreset); ``EnvSetupError`` (one line) if it cannot be made."""
    kwargs = dict(env_kwargs or {})
    try:
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                            **kwargs)
    except (gym.error.Error, TypeError, ValueError, MemoryError) as err:
        given = ", ".join(f"{k}={v!r}" for k, v in kwargs.items()) or "no env kwargs"
        raise EnvSetupError(f"cannot make {num_envs} batched {env_id} with {given}: "
                            f"{err}") from err


def act_batch(policy: Policy, obs: np.ndarray | Mapping[str, np.ndarray],
              deterministic: bool = True) -> np.ndarray:
    """Every car's action (float32, ``(N, 2)``) from one ``predict`` call: ``Policy.act``'s
    float32 observations and normaliser, on the whole batch (a dict of batches for a Dict
    space)."""
    if isinstance(obs, Mapping):
        batch: Any = {key: np.asarray(value, dtype=np.float32) for key, value in obs.items()}
        n = len(next(iter(batch.values())))
    else:
        batch = np.asarray(obs, dtype=np.float32)
        n = len(batch)
    if policy.normalizer is not None:
        batch = policy.normalizer(batch)
    action, _ = policy.model.predict(batch, deterministic=deterministic)
    return np.asarray(action, dtype=np.float32).reshape(n, -1)


def evaluate_batched_episodes(
    model: Policy | Any,
    env_id: str = DEFAULT_ENV_ID,
    n_episodes: int = 100,
    n_envs: int = DEFAULT_BATCH,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    deterministic: bool = True,
    vecnormalize_path: str | os.PathLike | None = None,
    progress: bool = False,
    steps: Any = None,
) -> list[EpisodeRecord]:
    """Run ``n_episodes`` episodes (episode i seeded ``seed + i``) on ``min(n_envs,
    n_episodes)`` cars of ``env_id``'s vector env in this process; records in episode order.

    ``model`` and ``vecnormalize_path``: as for ``rollouts.evaluate_policy_episodes``. Sampled
    actions (``deterministic=False``) are reproducible for the same ``seed`` and ``n_envs``.
    ``steps`` (a ``datasets.steps.EpisodeSteps``) gets every step of the episodes.
    """
    if n_episodes < 1 or n_envs < 1:
        raise ValueError(f"n_episodes and n_envs must be >= 1, got {n_episodes}, {n_envs}")
    policy = as_policy(model, vecnormalize_path)
    if not deterministic and hasattr(policy.model, "set_random_seed"):
        policy.model.set_random_seed(seed)
    n = min(n_envs, n_episodes)
    envs = make_batched_env(env_id, n, env_kwargs)
    bar = None
    try:
        _check_spaces(policy, envs.single_observation_space, env_id)
        step_s = 1.0 / float(envs.metadata.get("render_fps") or 10)
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=n_episodes, unit="episode", desc="evaluating (batched)",
                       dynamic_ncols=True)
        with _one_torch_thread():
            return _run(envs, policy, env_id, n_episodes, seed, deterministic, step_s, bar,
                        steps)
    finally:
        if bar is not None:
            bar.close()
        envs.close()


def _run(envs: gym.vector.VectorEnv, policy: Policy, env_id: str, n_episodes: int, seed: int,
         deterministic: bool, step_s: float, bar: Any, steps: Any = None,
         ) -> list[EpisodeRecord]:
    n = envs.num_envs
    episode_of = np.arange(n)  # each car's episode, -1 once it has none left
    obs, info = envs.reset(seed=[seed + i for i in range(n)])
    tracks = _Tracks(n)
    tracks.start(np.ones(n, dtype=bool), episode_of, seed, info, _goals(envs))
    if steps is not None:
        steps.begin(range(n), episode_of, obs, info)
    next_episode = n
    records: list[EpisodeRecord] = []
    park = getattr(envs.unwrapped, "park", None)
    while (episode_of >= 0).any():
        active = episode_of >= 0
        actions = act_batch(policy, obs, deterministic)
        actions[~active] = 0.0  # a car with no episode left stands still ...
        if park is not None:  # ... or, where the batch can, is not simulated at all
            park(~active)
        obs, reward, terminated, truncated, info = envs.step(actions)
        tracks.add(active, reward, info)
        if steps is not None:
            steps.step(np.flatnonzero(active), actions, obs, reward, terminated, truncated, info)
        done = active & (terminated | truncated)
        if not done.any():
            continue
        for car in np.flatnonzero(done):
            records.append(tracks.record(car, info, step_s))
        if bar is not None:
            bar.update(int(done.sum()))
        refill = np.flatnonzero(done)[:max(0, n_episodes - next_episode)]
        episode_of[done] = -1
        if refill.size == 0:
            continue  # the cars left without an episode autoreset themselves, unread
        episode_of[refill] = np.arange(next_episode, next_episode + refill.size)
        next_episode += refill.size
        mask = np.zeros(n, dtype=bool)
        mask[refill] = True
        seeds = [seed + int(e) if m else None for e, m in zip(episode_of, mask, strict=True)]
        new_obs, new_info = _partial_reset(envs, env_id, seeds, mask)
        for array, new in _arrays(obs, new_obs):
            array[mask] = new[mask]
        tracks.start(mask, episode_of, seed, new_info, _goals(envs))
        if steps is not None:
            steps.begin(refill, episode_of[refill], new_obs, new_info)
    return sorted(records, key=lambda r: r.episode)


@contextlib.contextmanager
def _one_torch_thread() -> Iterator[None]:
    """torch on one thread while the batch runs: its intra-op threads, idle-spinning beside
    the physics' worker threads, made predict on 16 cars take 10 ms instead of 0.2 ms."""
    torch = sys.modules.get("torch")
    if torch is None:
        yield
        return
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def _partial_reset(envs: gym.vector.VectorEnv, env_id: str, seeds: list[int | None],
                   mask: np.ndarray) -> tuple[Any, dict[str, Any]]:
    """Reset the masked cars with their seeds; one line if the vector env cannot."""
    what = (f"{env_id}'s vector env ({type(envs.unwrapped).__name__}) cannot reset single cars "
            "(reset(options={'reset_mask': mask}), Gymnasium's partial reset), which "
            "--vectorization batched needs")
    try:
        obs, info = envs.reset(seed=seeds, options={"reset_mask": mask})
    except (ValueError, TypeError, KeyError, AssertionError) as err:
        raise EnvSetupError(f"{what}: {err}") from err
    reset = info.get("_pose")
    if reset is None or not np.array_equal(reset, mask):
        raise EnvSetupError(f"{what}: it reset cars {np.flatnonzero(reset).tolist()}, "
                            f"not {np.flatnonzero(mask).tolist()}")
    return obs, info


def _arrays(obs: Any, new_obs: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """Pairs of (batch held, batch after the reset), one per Dict key."""
    if isinstance(obs, Mapping):
        return [(obs[k], new_obs[k]) for k in obs]
    return [(obs, new_obs)]


def _goals(envs: gym.vector.VectorEnv) -> np.ndarray:
    """Every car's goal (x, y) now: the sub-envs' ``goal`` (a loop of single envs) or the
    batch's ``(N, 2)`` ``goal``; NaN where the env exposes none."""
    get_attr = getattr(envs, "get_attr", None)
    try:
        goals = get_attr("goal") if get_attr is not None else envs.unwrapped.goal
    except AttributeError:
        return np.full((envs.num_envs, 2), math.nan)
    return np.array([np.asarray(g, dtype=float)[:2] for g in goals])


class _Tracks:
    """Every car's episode so far: ``rollouts._Track``'s arithmetic, in its order."""

    def __init__(self, n: int) -> None:
        self.episode = np.zeros(n, dtype=np.int64)
        self.seed = np.zeros(n, dtype=np.int64)
        self.goal = np.zeros((n, 2))
        self.ret = np.zeros(n)
        self.length = np.zeros(n, dtype=np.int64)
        self.path: list[list[np.ndarray]] = [[] for _ in range(n)]
        self.odom: list[list[np.ndarray]] = [[] for _ in range(n)]

    def start(self, mask: np.ndarray, episode_of: np.ndarray, seed: int,
              info: dict[str, Any], goals: np.ndarray) -> None:
        """The masked cars begin their episodes (``info``: their reset's)."""
        pose, odom = _xy(info, "pose"), _xy(info, "odom_pose")
        for car in np.flatnonzero(mask):
            self.path[car], self.odom[car] = [pose[car]], [odom[car]]
        self.episode[mask] = episode_of[mask]
        self.seed[mask] = seed + episode_of[mask]
        self.goal[mask] = goals[mask]
        self.ret[mask] = 0.0
        self.length[mask] = 0

    def add(self, active: np.ndarray, reward: np.ndarray, info: dict[str, Any]) -> None:
        """One step of the active cars."""
        self.ret[active] += np.asarray(reward, dtype=np.float64)[active]
        self.length[active] += 1
        pose, odom = _xy(info, "pose"), _xy(info, "odom_pose")
        for car in np.flatnonzero(active):
            self.path[car].append(pose[car])
            self.odom[car].append(odom[car])

    def record(self, car: int, info: dict[str, Any], step_s: float) -> EpisodeRecord:
        """Car ``car``'s episode, ended at this step (``info``: the step's)."""
        success = bool(info["is_success"][car])
        length = int(self.length[car])
        return EpisodeRecord(
            episode=int(self.episode[car]), seed=int(self.seed[car]), success=success,
            episode_return=float(self.ret[car]), length=length,
            time_to_goal_s=length * step_s if success else None,
            final_distance_m=float(info["distance"][car]),
            final_odom_error_m=float(info["odom_error"][car]),
            goal=(float(self.goal[car, 0]), float(self.goal[car, 1])),
            path=np.array(self.path[car]), odom_path=np.array(self.odom[car]),
        )


def _xy(info: dict[str, Any], key: str) -> np.ndarray:
    """Every car's x, y of ``info[key]`` as a float64 ``(N, 2)`` copy."""
    return np.array(np.asarray(info[key])[:, :2], dtype=float)
