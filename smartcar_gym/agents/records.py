"""What the evaluations record: one ``EpisodeRecord`` an episode, ``summarize`` over them,
and the episode runner's hooks that record (``RecordHook``: the records; ``StepsHook``: a
dataset's steps; ``CaptureHook``: recorders' frames)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.agents.runner import Hooks, Job

__all__ = ["CaptureHook", "EpisodeRecord", "RecordHook", "StepsHook", "summarize"]


def _no_path() -> np.ndarray:
    return np.zeros((0, 2))


@dataclass
class EpisodeRecord:
    """One episode. Positions are ground-truth (``path``) or odometry, in metres.

    ``seed`` is None and the paths are empty (the goal NaN) for the episodes of
    ``run_sb3_episodes``: SB3's VecEnvs reset a finished env unseeded, and keep no path."""

    episode: int
    seed: int | None
    success: bool
    episode_return: float
    length: int
    time_to_goal_s: float | None
    final_distance_m: float
    final_odom_error_m: float
    goal: tuple[float, float]
    path: np.ndarray = field(repr=False, default_factory=_no_path)
    odom_path: np.ndarray = field(repr=False, default_factory=_no_path)

    def to_dict(self, include_paths: bool = False) -> dict[str, Any]:
        """JSON-ready fields (paths as lists of [x, y] only if ``include_paths``)."""
        data = asdict(self)
        data["goal"] = [float(g) for g in self.goal]
        for key, name in (("final_pose", "path"), ("final_odom_pose", "odom_path")):
            points = np.asarray(getattr(self, name))
            data[key] = points[-1].tolist() if len(points) else None
        for key in ("path", "odom_path"):
            data[key] = np.asarray(data[key]).tolist() if include_paths else None
            if not include_paths:
                del data[key]
        return data


def summarize(records: Sequence[EpisodeRecord]) -> dict[str, float | int | None]:
    """Success rate, mean return, mean time to goal (s, successes only), distances (m; the
    mean of the episodes that know theirs)."""
    if not records:
        raise ValueError("no episodes to summarize")
    times = [r.time_to_goal_s for r in records if r.success and r.time_to_goal_s is not None]
    returns = np.array([r.episode_return for r in records])
    return {
        "episodes": len(records),
        "success_rate": float(np.mean([r.success for r in records])),
        "mean_return": float(returns.mean()),
        "std_return": float(returns.std()),
        "mean_time_to_goal_s": float(np.mean(times)) if times else None,
        "mean_final_distance_m": _nanmean([r.final_distance_m for r in records]),
        "mean_final_odom_error_m": _nanmean([r.final_odom_error_m for r in records]),
        "mean_length": float(np.mean([r.length for r in records])),
    }


def _nanmean(values: list[float]) -> float:
    """The mean of the values that are not NaN; NaN (without a warning) if none is."""
    array = np.asarray(values, dtype=float)
    return float(np.nanmean(array)) if not np.isnan(array).all() else math.nan


def _goals(envs: gym.vector.VectorEnv) -> np.ndarray:
    """Every car's goal (x, y) now: the sub-envs' ``goal`` (single envs) or the batch's
    ``(N, 2)`` ``goal``; NaN where the env exposes none."""
    get_attr = getattr(envs, "get_attr", None)
    try:
        goals = get_attr("goal") if get_attr is not None else envs.unwrapped.goal
    except AttributeError:
        return np.full((envs.num_envs, 2), math.nan)
    return np.array([np.asarray(g, dtype=float)[:2] for g in goals])


class RecordHook(Hooks):
    """Every car's episode so far, and the records of those that ended."""

    def __init__(self, n: int, step_s: float, bar: Any) -> None:
        self.step_s, self.bar = step_s, bar
        self.records: list[EpisodeRecord] = []
        self.goal = np.zeros((n, 2))
        self.ret = np.zeros(n)
        self.path: list[list[np.ndarray]] = [[] for _ in range(n)]
        self.odom: list[list[np.ndarray]] = [[] for _ in range(n)]

    def begin(self, envs: gym.vector.VectorEnv, cars: np.ndarray, jobs: list[Job], obs: Any,
              info: dict[str, Any]) -> None:
        """The listed cars begin their jobs (``info``: their reset's)."""
        pose, odom, goals = _xy(info, "pose"), _xy(info, "odom_pose"), _goals(envs)
        for car in cars.tolist():
            self.path[car], self.odom[car] = [pose[car]], [odom[car]]
            self.goal[car] = goals[car]
            self.ret[car] = 0.0

    def step(self, cars: np.ndarray, actions: np.ndarray, obs: Any, reward: np.ndarray,
             terminated: np.ndarray, truncated: np.ndarray, info: dict[str, Any]) -> None:
        """One step of the running cars."""
        self.ret[cars] += np.asarray(reward, dtype=np.float64)[cars]
        pose, odom = _xy(info, "pose"), _xy(info, "odom_pose")
        for car in cars.tolist():
            self.path[car].append(pose[car])
            self.odom[car].append(odom[car])

    def end(self, car: int, job: Job, info: dict[str, Any]) -> None:
        """Car ``car``'s episode, ended at this step (``info``: the step's)."""
        success = bool(info["is_success"][car])
        length = len(self.path[car]) - 1  # the steps after the reset's pose
        self.records.append(EpisodeRecord(
            episode=int(job.episode), seed=int(job.seed), success=success,
            episode_return=float(self.ret[car]), length=length,
            time_to_goal_s=length * self.step_s if success else None,
            final_distance_m=float(info["distance"][car]),
            final_odom_error_m=float(info["odom_error"][car]),
            goal=(float(self.goal[car, 0]), float(self.goal[car, 1])),
            path=np.array(self.path[car]), odom_path=np.array(self.odom[car])))
        if self.bar is not None:
            self.bar.update(1)


class StepsHook(Hooks):
    """Every reset and step told to a ``datasets.steps.EpisodeSteps``."""

    def __init__(self, steps: Any) -> None:
        self.steps = steps

    def begin(self, envs: gym.vector.VectorEnv, cars: np.ndarray, jobs: list[Job], obs: Any,
              info: dict[str, Any]) -> None:
        self.steps.begin(cars, [job.episode for job in jobs], obs, info)

    def step(self, cars: np.ndarray, actions: np.ndarray, obs: Any, reward: np.ndarray,
             terminated: np.ndarray, truncated: np.ndarray, info: dict[str, Any]) -> None:
        self.steps.step(cars, actions, obs, reward, terminated, truncated, info)


class CaptureHook(Hooks):
    """The frames every sub-env captured (``viewers.capture``) to an ``EpisodeCollector``."""

    def __init__(self, collector: Any) -> None:
        from smartcar_gym.viewers.capture import CAPTURE_KEY

        self.collector, self.key = collector, CAPTURE_KEY

    def begin(self, envs: gym.vector.VectorEnv, cars: np.ndarray, jobs: list[Job], obs: Any,
              info: dict[str, Any]) -> None:
        for car, job in zip(cars.tolist(), jobs, strict=True):
            self.collector.begin(car, job.episode, job.seed, info[self.key][car])

    def step(self, cars: np.ndarray, actions: np.ndarray, obs: Any, reward: np.ndarray,
             terminated: np.ndarray, truncated: np.ndarray, info: dict[str, Any]) -> None:
        for car in cars.tolist():
            self.collector.add(car, info[self.key][car])


def _xy(info: dict[str, Any], key: str) -> np.ndarray:
    """Every car's x, y of ``info[key]`` as a float64 ``(N, 2)`` copy."""
    return np.array(np.asarray(info[key])[:, :2], dtype=float)
