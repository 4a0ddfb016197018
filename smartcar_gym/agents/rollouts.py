"""Seeded evaluation episodes of a policy: per-episode records, their summary, a video.

``evaluate_policy_episodes`` is the reusable part (tests, ``smartcar-eval`` and the CI
regression gate call it). Episode ``i`` is reset with seed ``seed + i`` in whichever worker
runs it, and actions are computed one observation at a time, so the per-episode results do
not depend on ``n_envs``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.agents.env_factory import make_env
from smartcar_gym.policy import DEFAULT_ENV_ID, Policy, as_policy

__all__ = ["DEFAULT_ENV_ID", "EpisodeRecord", "ObservationShapeError", "RandomPolicy",
           "evaluate_policy_episodes", "record_video", "summarize"]


@dataclass
class EpisodeRecord:
    """One evaluation episode. Positions are ground-truth (``path``) or odometry, in metres."""

    episode: int
    seed: int
    success: bool
    episode_return: float
    length: int
    time_to_goal_s: float | None
    final_distance_m: float
    final_odom_error_m: float
    goal: tuple[float, float]
    path: np.ndarray = field(repr=False)
    odom_path: np.ndarray = field(repr=False)

    def to_dict(self, include_paths: bool = False) -> dict[str, Any]:
        """JSON-ready fields (paths as lists of [x, y] only if ``include_paths``)."""
        data = asdict(self)
        data["goal"] = [float(g) for g in self.goal]
        data["final_pose"] = np.asarray(self.path)[-1].tolist()
        data["final_odom_pose"] = np.asarray(self.odom_path)[-1].tolist()
        for key in ("path", "odom_path"):
            data[key] = np.asarray(data[key]).tolist() if include_paths else None
            if not include_paths:
                del data[key]
        return data


def summarize(records: Sequence[EpisodeRecord]) -> dict[str, float | int | None]:
    """Success rate, mean return, mean time to goal (s, successes only), distances (m)."""
    if not records:
        raise ValueError("no episodes to summarize")
    times = [r.time_to_goal_s for r in records if r.success]
    returns = np.array([r.episode_return for r in records])
    return {
        "episodes": len(records),
        "success_rate": float(np.mean([r.success for r in records])),
        "mean_return": float(returns.mean()),
        "std_return": float(returns.std()),
        "mean_time_to_goal_s": float(np.mean(times)) if times else None,
        "mean_final_distance_m": float(np.mean([r.final_distance_m for r in records])),
        "mean_final_odom_error_m": float(np.mean([r.final_odom_error_m for r in records])),
        "mean_length": float(np.mean([r.length for r in records])),
    }


def _vector_env(env_id: str, n_envs: int, env_kwargs: dict[str, Any],
                capture: bool = False) -> gym.vector.VectorEnv:
    fns = [_EnvFn(env_id, env_kwargs, capture) for _ in range(n_envs)]
    mode = gym.vector.AutoresetMode.DISABLED
    if n_envs == 1:
        return gym.vector.SyncVectorEnv(fns, autoreset_mode=mode)
    return gym.vector.AsyncVectorEnv(fns, autoreset_mode=mode, context="forkserver")


@dataclass
class _EnvFn:
    """A picklable env constructor for AsyncVectorEnv workers."""

    env_id: str
    env_kwargs: dict[str, Any]
    capture: bool = False  # add info["capture"] for recorders (smartcar_gym.viewers.capture)

    def __call__(self) -> gym.Env:
        env = make_env(self.env_id, self.env_kwargs)
        if self.capture:
            from smartcar_gym.viewers.capture import CaptureWrapper

            env = CaptureWrapper(env)
        return env


class RandomPolicy:
    """Uniform random actions in [-1, 1]^2, seeded: a baseline (and the README's GIF)."""

    observation_space = None

    def __init__(self, seed: int = 0) -> None:
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.action_space.seed(seed)

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        """One sampled action per observation in the batch (a dict of batches for a Dict)."""
        first = np.asarray(next(iter(obs.values())) if isinstance(obs, dict) else obs)
        batch = first.reshape(-1, first.shape[-1])
        return np.stack([self.action_space.sample() for _ in batch]), None


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
    ``steps`` (a ``datasets.steps.EpisodeSteps``) gets every step, read from the vector env.
    """
    if n_episodes < 1 or n_envs < 1:
        raise ValueError(f"n_episodes and n_envs must be >= 1, got {n_episodes}, {n_envs}")
    policy = as_policy(model, vecnormalize_path)
    if not deterministic and hasattr(policy.model, "set_random_seed"):
        policy.model.set_random_seed(seed)
    n_slots = min(n_envs, n_episodes)
    envs = _vector_env(env_id, n_slots, dict(env_kwargs or {}), capture=bool(recorders))
    collector = None
    if recorders:
        from smartcar_gym.viewers.capture import CAPTURE_KEY, EpisodeCollector

        collector = EpisodeCollector(list(recorders))
    try:
        _check_spaces(policy, envs.single_observation_space, env_id)
    except ObservationShapeError:
        envs.close()
        raise
    step_s = 1.0 / float(envs.metadata.get("render_fps") or 10)
    records: list[EpisodeRecord] = []
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_episodes, unit="episode", desc="evaluating", dynamic_ncols=True)
    try:
        episode_of = list(range(n_slots))
        obs, info = envs.reset(seed=[seed + i for i in range(n_slots)])
        goals = _goals(envs, range(n_slots))
        tracks = [_Track(i, seed + i, goals[i], info, i) for i in range(n_slots)]
        if steps is not None:
            steps.begin(range(n_slots), range(n_slots), obs, info)
        if collector is not None:
            for slot in range(n_slots):
                collector.begin(slot, slot, seed + slot, info[CAPTURE_KEY][slot])
        next_episode = n_slots
        while any(e is not None for e in episode_of):
            actions = np.zeros((n_slots, *envs.single_action_space.shape), dtype=np.float32)
            for slot, episode in enumerate(episode_of):
                if episode is not None:
                    actions[slot] = policy.act(_slot(obs, slot), deterministic)
            obs, reward, terminated, truncated, info = envs.step(actions)
            if steps is not None:
                steps.step([s for s, e in enumerate(episode_of) if e is not None], actions, obs,
                           reward, terminated, truncated, info)
            reset_mask = np.zeros(n_slots, dtype=bool)
            for slot, episode in enumerate(episode_of):
                if episode is None:
                    continue
                track = tracks[slot]
                track.add(float(reward[slot]), info, slot)
                if collector is not None:
                    collector.add(slot, info[CAPTURE_KEY][slot])
                if terminated[slot] or truncated[slot]:
                    records.append(track.record(step_s))
                    if bar is not None:
                        bar.update(1)
                    if next_episode < n_episodes:
                        episode_of[slot] = next_episode
                        next_episode += 1
                        reset_mask[slot] = True
                    else:
                        episode_of[slot] = None
            if reset_mask.any():
                seeds = [seed + episode_of[s] if m else None for s, m in enumerate(reset_mask)]
                new_obs, new_info = envs.reset(seed=seeds, options={"reset_mask": reset_mask})
                slots = np.flatnonzero(reset_mask)
                goals = _goals(envs, slots)
                if steps is not None:
                    steps.begin(slots, [episode_of[s] for s in slots], new_obs, new_info)
                for slot in slots:
                    for array, new in _arrays(obs, new_obs):
                        array[slot] = new[slot]
                    tracks[slot] = _Track(
                        episode_of[slot], seed + episode_of[slot], goals[slot], new_info, slot
                    )
                    if collector is not None:
                        collector.begin(slot, episode_of[slot], seed + episode_of[slot],
                                        new_info[CAPTURE_KEY][slot])
    finally:
        if bar is not None:
            bar.close()
        envs.close()
    return sorted(records, key=lambda r: r.episode)


def _slot(obs: np.ndarray | dict[str, np.ndarray], slot: int) -> Any:
    """Sub-env ``slot``'s observation of a batch (a dict of batches for a Dict space)."""
    return {k: v[slot] for k, v in obs.items()} if isinstance(obs, dict) else obs[slot]


def _arrays(obs: Any, new_obs: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """Pairs of (batch held, batch of the new observations), one per Dict key."""
    if isinstance(obs, dict):
        return [(obs[k], new_obs[k]) for k in obs]
    return [(obs, new_obs)]


class ObservationShapeError(ValueError):
    """The model was trained on observations of another shape than the env's."""


def _check_spaces(policy: Policy, space: gym.spaces.Space, env_id: str) -> None:
    """A clear error when the model was trained on observations of another shape."""
    expected = getattr(policy.observation_space, "shape", None)
    if expected is not None and tuple(expected) != tuple(space.shape):
        raise ObservationShapeError(
            f"the model expects observations of shape {tuple(expected)} but {env_id} gives "
            f"{tuple(space.shape)}: the env changed since the model was trained; retrain it "
            "(see the README, 'Training')"
        )


def _goals(envs: gym.vector.VectorEnv, slots: Any) -> dict[int, tuple[float, float]]:
    """The goal (x, y) of the given sub-envs (NaN if the env does not expose ``goal``)."""
    try:
        goals = envs.get_attr("goal")
    except AttributeError:
        return {int(s): (math.nan, math.nan) for s in slots}
    return {int(s): tuple(float(v) for v in np.asarray(goals[int(s)])[:2]) for s in slots}


class _Track:
    """Accumulates one episode of one sub-env."""

    def __init__(self, episode: int, seed: int, goal: tuple[float, float],
                 reset_info: dict[str, Any], slot: int) -> None:
        self.episode, self.seed, self.goal = episode, seed, goal
        self.ret, self.length = 0.0, 0
        self.path = [np.asarray(reset_info["pose"][slot][:2], dtype=float)]
        self.odom = [np.asarray(reset_info["odom_pose"][slot][:2], dtype=float)]
        self.last: dict[str, Any] = {}

    def add(self, reward: float, info: dict[str, Any], slot: int) -> None:
        self.ret += reward
        self.length += 1
        self.path.append(np.asarray(info["pose"][slot][:2], dtype=float))
        self.odom.append(np.asarray(info["odom_pose"][slot][:2], dtype=float))
        self.last = {k: info[k][slot] for k in ("is_success", "distance", "odom_error")}

    def record(self, step_s: float) -> EpisodeRecord:
        success = bool(self.last["is_success"])
        return EpisodeRecord(
            episode=self.episode, seed=self.seed, success=success,
            episode_return=self.ret, length=self.length,
            time_to_goal_s=self.length * step_s if success else None,
            final_distance_m=float(self.last["distance"]),
            final_odom_error_m=float(self.last["odom_error"]),
            goal=self.goal, path=np.array(self.path), odom_path=np.array(self.odom),
        )


def record_video(
    model: Policy | Any,
    out_path: str | os.PathLike,
    env_id: str = DEFAULT_ENV_ID,
    n_episodes: int = 3,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    deterministic: bool = True,
    vecnormalize_path: str | os.PathLike | None = None,
) -> int:
    """Render episodes 0..n-1 (seeds seed+i, as in the evaluation) to a .gif or .mp4.

    ``model`` and ``vecnormalize_path``: as for ``evaluate_policy_episodes``. Returns the
    number of frames written (mp4 through ``imageio-ffmpeg``, a dependency).
    """
    import imageio.v3 as iio

    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"video file must end in .gif or .mp4, got {out_path.name!r}")
    policy = as_policy(model, vecnormalize_path)
    env = make_env(env_id, {**(env_kwargs or {}), "render_mode": "rgb_array"})
    fps = float(env.metadata.get("render_fps") or 10)
    frames = []
    try:
        for i in range(n_episodes):
            obs, _ = env.reset(seed=seed + i)
            frames.append(env.render())
            done = False
            while not done:
                action = policy.act(obs, deterministic)
                obs, _, terminated, truncated, _ = env.step(action)
                frames.append(env.render())
                done = terminated or truncated
            frames.extend([frames[-1]] * int(fps // 2))  # a short pause between episodes
    finally:
        env.close()
    # even sizes for yuv420p video
    frames = [np.ascontiguousarray(f[: f.shape[0] // 2 * 2, : f.shape[1] // 2 * 2, :3])
              for f in frames]
    out_path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".gif":
        iio.imwrite(out_path, np.stack(frames), plugin="pillow", duration=1000.0 / fps, loop=0)
    else:
        import imageio.v2 as iio2

        iio2.mimsave(out_path, frames, format="FFMPEG", fps=fps, macro_block_size=2)
    return len(frames)
