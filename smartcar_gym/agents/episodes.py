"""Seeded episodes of a policy, run in one place: one record type, one summary.

* ``evaluate_policy_episodes``: single envs (worker processes when ``n_envs > 1``), actions
  one observation at a time (``Policy.act``): ``smartcar-eval``, the CI gate,
  ``testing.evaluate(batched=False)``.
* ``evaluate_batched_episodes``: ``n_envs`` cars of the id's ``vector_entry_point`` in this
  process (the MuJoCo and planar batches, the numpy SmartCarSim-v0 batch, N single envs in a
  loop elsewhere), every car's action from one ``predict`` call per step (``act_batch``):
  ``smartcar-eval --vectorization batched``, ``testing.evaluate``.
* ``run_sb3_episodes``: SB3's ``evaluate_policy`` on an SB3 VecEnv: the evaluations during
  training, in the training process or in the evaluation worker (``eval_worker``).

Each gives ``records.EpisodeRecord``s; ``records.summarize`` turns them into the figures every
caller shows. ``random_policy.RandomPolicy`` is the baseline.
In the first two, episode ``i`` is reset with seed ``seed + i`` whichever car or worker runs
it, and a car whose episode ends is reset at once with the next episode's seed (Gymnasium's
partial reset, ``reset(seed=[...], options={"reset_mask": mask})``), so the records do not
depend on ``n_envs``.

Where the vector env is bit for bit its single envs, the batched records equal the sequential
ones exactly for a policy whose actions do not depend on batching (a plain function of one
observation: ``testing.FunctionModel`` calls it per observation). A torch network's batched
matrix products round differently from a batch of one: its actions differ by about 1e-7. In
the hardware mode (SmartCar-v0's default) the controller turns them into integer encoder
ticks, almost always the same ones, so the paths stayed equal to the last bit (the tests allow
``RECORD_TOLERANCE``; the returns' action cost differs by about 1e-8); in the kinematic mode
(SmartCarSim-v0) the car follows the commanded twist, so the difference grows along an
episode and an episode may end otherwise (1 of 1,000 with the shipped policy:
docs/performance.md). The same command (same ``n_envs``) gives the same records.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.agents.env_factory import EnvSetupError
from smartcar_gym.agents.policies import DEFAULT_ENV_ID, Policy, as_policy
from smartcar_gym.agents.records import CaptureHook, EpisodeRecord, RecordHook, StepsHook
from smartcar_gym.agents.runner import Hooks, Job, ResetError, one_torch_thread, run_jobs
from smartcar_gym.agents.vec_envs import make_batched_env, make_single_env_vector

__all__ = ["DEFAULT_BATCH", "RECORD_TOLERANCE", "ObservationShapeError", "act_batch",
           "evaluate_batched_episodes", "evaluate_policy_episodes", "run_sb3_episodes"]

#: cars in the batch when ``n_envs`` is not given: more cars spread the batch's numpy cost
#: further, and the cars left without an episode at the end are parked where the batch can
#: (``park``: MuJoCo's and the planar engine's), so that the tail costs no physics. Measured
#: (1,000 episodes on MuJoCo, 2 cores, interleaved): 128 cars took 13-17 % less wall time than
#: 64 in each of 4 rounds; 256 were no faster than 128
DEFAULT_BATCH = 128
#: bound on |batched - sequential| of an SB3 model's returns, final distances and paths (m) in
#: the hardware mode, as the tests check it (measured: 0 m for paths, about 5e-8 for returns)
RECORD_TOLERANCE = 1e-4


class ObservationShapeError(ValueError):
    """The model was trained on observations of another shape than the env's."""


def _check_spaces(policy: Policy, space: gym.spaces.Space, env_id: str) -> None:
    """A clear error when the model was trained on observations of another shape (or kind: a
    Box against a Dict)."""
    expected = policy.observation_space
    if expected is None or _same_shapes(expected, space):
        return
    shape = "shape " if getattr(expected, "shape", None) is not None else ""
    raise ObservationShapeError(
        f"the model expects observations of {shape}{_shapes(expected)} but {env_id} gives "
        f"{_shapes(space)}: the env changed since the model was trained; retrain it "
        "(see the README, 'Training')"
    )


def _same_shapes(a: gym.spaces.Space, b: gym.spaces.Space) -> bool:
    """Whether two spaces have the same shape: Boxes (arrays), or Dicts with the same keys."""
    if isinstance(a, gym.spaces.Dict) or isinstance(b, gym.spaces.Dict):
        return (isinstance(a, gym.spaces.Dict) and isinstance(b, gym.spaces.Dict)
                and list(a.spaces) == list(b.spaces)
                and all(_same_shapes(a[k], b[k]) for k in a.spaces))
    shape_a, shape_b = getattr(a, "shape", None), getattr(b, "shape", None)
    return shape_a is None or shape_b is None or tuple(shape_a) == tuple(shape_b)


def _shapes(space: gym.spaces.Space) -> str:
    """``(12,)``, or ``a Dict of observation (10,), achieved_goal (2,), desired_goal (2,)``."""
    if isinstance(space, gym.spaces.Dict):
        return "a Dict of " + ", ".join(f"{k} {_shapes(v)}" for k, v in space.spaces.items())
    shape = getattr(space, "shape", None)
    return str(tuple(shape)) if shape is not None else type(space).__name__


# -- the episodes -------------------------------------------------------------------------------
def evaluate_policy_episodes(
    model: Policy | Any,
    env_id: str = DEFAULT_ENV_ID,
    n_episodes: int = 100,
    n_envs: int = 1,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    deterministic: bool = True,
    vecnormalize_path: str | os.PathLike | None = None,
    progress: bool = False,
    recorders: Sequence[Callable[[Any], None]] = (),
    steps: Any = None,
    hooks: Sequence[Hooks] = (),
) -> list[EpisodeRecord]:
    """Run ``n_episodes`` complete episodes over ``n_envs`` envs; episode i uses seed seed+i.

    ``model`` is a ``smartcar_gym.policy.Policy`` (its normaliser applies), or anything with
    SB3's ``predict(obs, deterministic=...)``, whose observations are normalised with the
    ``VecNormalize`` statistics at ``vecnormalize_path`` if given. Envs
    run in worker processes when ``n_envs > 1`` (so call it under ``if __name__ ==
    "__main__":`` in a script). Records are returned in episode order. Sampled actions
    (``deterministic=False``) are reproducible for the same ``seed`` and ``n_envs``.

    ``recorders`` (a Rerun recording, a ROS 2 bag: ``smartcar_gym.viewers``) are called with
    each finished ``Episode`` (scene and per-step frames, read in the workers), in episode
    order; recording only reads the simulator, so the episodes are the same with or without.
    ``steps`` (a ``datasets.steps.EpisodeSteps``) gets every step, read from the vector env;
    ``hooks`` (``runner.Hooks``) see every start, step and end in this process (a video's
    frames, a bag's messages: with ``n_envs=1`` the env is in this process too).
    """
    policy = _policy(model, vecnormalize_path, n_episodes, n_envs, deterministic, seed)
    envs = make_single_env_vector(env_id, min(n_envs, n_episodes), env_kwargs,
                                  capture=bool(recorders))
    collector = None
    if recorders:
        from smartcar_gym.viewers.capture import EpisodeCollector

        collector = EpisodeCollector(list(recorders))

    def act(obs: Any, episode_of: np.ndarray, steps: np.ndarray) -> np.ndarray:
        if hasattr(policy.model, "act_episodes"):
            return policy.model.act_episodes(episode_of, steps)
        actions = np.zeros((len(episode_of), *envs.single_action_space.shape), dtype=np.float32)
        for car in np.flatnonzero(episode_of >= 0):
            actions[car] = policy.act(_car(obs, car), deterministic)
        return actions

    return _episodes(envs, policy, env_id, n_episodes, seed, act, progress, "evaluating",
                     collector, steps=steps, hooks=hooks)


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

    ``model`` and ``vecnormalize_path``: as for ``evaluate_policy_episodes``. Sampled
    actions (``deterministic=False``) are reproducible for the same ``seed`` and ``n_envs``.
    ``steps`` (a ``datasets.steps.EpisodeSteps``) gets every step of the episodes.
    """
    policy = _policy(model, vecnormalize_path, n_episodes, n_envs, deterministic, seed)
    envs = make_batched_env(env_id, min(n_envs, n_episodes), env_kwargs)

    def act(obs: Any, episode_of: np.ndarray, steps: np.ndarray) -> np.ndarray:
        if hasattr(policy.model, "act_episodes"):
            return policy.model.act_episodes(episode_of, steps)
        actions = act_batch(policy, obs, deterministic)
        actions[episode_of < 0] = 0.0  # a car with no episode left stands still (or is parked)
        return actions

    with one_torch_thread():
        return _episodes(envs, policy, env_id, n_episodes, seed, act, progress,
                         "evaluating (batched)", None, check_resets=True, steps=steps)


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


def run_sb3_episodes(model: Any, venv: Any, n_episodes: int, seed: int,
                     deterministic: bool = True) -> list[EpisodeRecord]:
    """Play ``n_episodes`` episodes of the SB3 VecEnv ``venv`` (seeded with ``seed``: the same
    goals at every evaluation) with ``model`` (anything with SB3's ``predict``), by SB3's
    ``evaluate_policy``; records in the order the episodes ended."""
    from stable_baselines3.common.evaluation import evaluate_policy

    ends: list[tuple[bool, float, float]] = []

    def collect(locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        if locals_["done"]:
            info = locals_["info"]
            ends.append((bool(info.get("is_success", False)),
                         float(info.get("distance", np.nan)),
                         float(info.get("odom_error", np.nan))))

    venv.seed(seed)
    returns, lengths = evaluate_policy(model, venv, n_eval_episodes=n_episodes,
                                       deterministic=deterministic, return_episode_rewards=True,
                                       callback=collect, warn=False)
    step_s = _step_s(venv.get_attr("metadata", [0])[0])
    return [EpisodeRecord(episode=i, seed=None, success=success, episode_return=ret,
                          length=length, time_to_goal_s=length * step_s if success else None,
                          final_distance_m=distance, final_odom_error_m=odom_error,
                          goal=(math.nan, math.nan))
            for i, ((success, distance, odom_error), ret, length)
            # an episode that a wrapper outside the Monitor ended is not among the returns
            in enumerate(zip(ends, returns, lengths, strict=False))]


def _policy(model: Any, vecnormalize_path: str | os.PathLike | None, n_episodes: int,
            n_envs: int, deterministic: bool, seed: int) -> Policy:
    """The checked arguments' ``Policy`` (seeded when it samples)."""
    if n_episodes < 1 or n_envs < 1:
        raise ValueError(f"n_episodes and n_envs must be >= 1, got {n_episodes}, {n_envs}")
    policy = as_policy(model, vecnormalize_path)
    if not deterministic and hasattr(policy.model, "set_random_seed"):
        policy.model.set_random_seed(seed)
    return policy


def _episodes(envs: gym.vector.VectorEnv, policy: Policy, env_id: str, n_episodes: int,
              seed: int, act: Callable[..., np.ndarray], progress: bool,
              desc: str, collector: Any, check_resets: bool = False,
              steps: Any = None, hooks: Sequence[Hooks] = ()) -> list[EpisodeRecord]:
    """Episodes 0..n_episodes-1 (episode i seeded ``seed + i``) through the runner
    (``runner.run_jobs``) on ``envs`` (closed at the end), after checking the spaces; the
    records in episode order. ``act(obs, episode_of, steps)``: the cars' actions
    (``episode_of``: each car's episode, -1 for none; ``steps``: the steps each car's episode
    has run); ``steps`` (or None) is told of every reset and step, ``collector`` (or None)
    gets every captured frame."""
    bar = None
    try:
        _check_spaces(policy, envs.single_observation_space, env_id)
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=n_episodes, unit="episode", desc=desc, dynamic_ncols=True)
        tracks = RecordHook(envs.num_envs, _step_s(envs.metadata), bar)
        every: list[Hooks] = [tracks, *hooks]
        if steps is not None:
            every.append(StepsHook(steps))
        if collector is not None:
            every.append(CaptureHook(collector))

        def by_episode(obs: Any, running: list[Job | None], steps: np.ndarray) -> np.ndarray:
            episode_of = np.array([-1 if job is None else job.episode for job in running])
            return act(obs, episode_of, steps)

        jobs = [Job(i, seed + i) for i in range(n_episodes)]
        try:
            run_jobs(envs, jobs, by_episode, every, check_resets)
        except ResetError as err:
            raise EnvSetupError(f"{env_id}'s {err}, which --vectorization batched needs"
                                ) from err
        return sorted(tracks.records, key=lambda r: r.episode)
    finally:
        if bar is not None:
            bar.close()
        envs.close()


def _step_s(metadata: Mapping[str, Any]) -> float:
    """Seconds per env step: 1 / the env's ``render_fps`` (10 if it names none)."""
    return 1.0 / float(metadata.get("render_fps") or 10)


def _car(obs: np.ndarray | dict[str, np.ndarray], car: int) -> Any:
    """Car ``car``'s observation of a batch (a dict of batches for a Dict space)."""
    return {k: v[car] for k, v in obs.items()} if isinstance(obs, dict) else obs[car]
