"""A policy's episodes rendered to a .gif or .mp4: ``smartcar-eval --video``.

Episode ``i`` is reset with seed ``seed + i``, as in the evaluation (``episodes``), so the video
shows the episodes whose records the evaluation reports.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.agents.env_factory import make_env
from smartcar_gym.policy import DEFAULT_ENV_ID, Policy, as_policy

__all__ = ["record_video"]


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
            done, step = False, 0
            while not done:
                if hasattr(policy.model, "act_episodes"):  # the episode's own random actions
                    action = policy.model.act_episodes(np.array([i]), np.array([step]))[0]
                    step += 1
                else:
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
