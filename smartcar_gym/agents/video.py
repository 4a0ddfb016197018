"""A policy's episodes rendered to a .gif or .mp4: ``smartcar-eval --video``.

The episodes are run by the episode runner as the evaluation runs them (episode ``i`` reset
with seed ``seed + i``: the video shows the episodes whose records the evaluation reports); a
runner hook renders a frame at every reset and step.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.policies import DEFAULT_ENV_ID, Policy
from smartcar_gym.agents.runner import Hooks, Job

__all__ = ["record_video"]


class _Frames(Hooks):
    """The env's frame after every reset and step, and a short pause after each episode."""

    def __init__(self) -> None:
        self.frames: list[np.ndarray] = []
        self.fps = 10.0
        self._envs: Any = None

    def _render(self) -> None:
        self.frames.append(self._envs.render()[0])

    def begin(self, envs: gym.vector.VectorEnv, cars: np.ndarray, jobs: list[Job], obs: Any,
              info: dict[str, Any]) -> None:
        self._envs = envs
        self.fps = float(envs.metadata.get("render_fps") or 10)
        self._render()

    def step(self, cars: np.ndarray, actions: np.ndarray, obs: Any, reward: np.ndarray,
             terminated: np.ndarray, truncated: np.ndarray, info: dict[str, Any]) -> None:
        self._render()

    def end(self, car: int, job: Job, info: dict[str, Any]) -> None:
        self.frames.extend([self.frames[-1]] * int(self.fps // 2))  # a pause between episodes


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
    frames = _Frames()
    evaluate_policy_episodes(model, env_id, n_episodes, 1, seed,
                             {**(env_kwargs or {}), "render_mode": "rgb_array"}, deterministic,
                             vecnormalize_path, hooks=[frames])
    # even sizes for yuv420p video
    images = [np.ascontiguousarray(f[: f.shape[0] // 2 * 2, : f.shape[1] // 2 * 2, :3])
              for f in frames.frames]
    out_path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".gif":
        iio.imwrite(out_path, np.stack(images), plugin="pillow", duration=1000.0 / frames.fps,
                    loop=0)
    else:
        import imageio.v2 as iio2

        iio2.mimsave(out_path, images, format="FFMPEG", fps=frames.fps, macro_block_size=2)
    return len(images)
