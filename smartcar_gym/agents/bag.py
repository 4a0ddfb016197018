"""A policy's episodes as a ROS 1 bag or an MCAP file: ``smartcar-eval --bag``.

The episodes are run by the episode runner as the evaluation runs them (episode ``i`` reset
with seed ``seed + i``: the same episodes, step for step) in one env of this process;
``bags.ros1.BagRecorder``, a hook of the runner, writes what the bringup node would publish.
"""

from __future__ import annotations

import os
from typing import Any

from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.policies import Policy
from smartcar_gym.bags.ros1 import BagRecorder, episode_writer

__all__ = ["write_bag"]


def write_bag(
    model: Policy | Any,
    out_path: str | os.PathLike,
    env_id: str,
    n_episodes: int,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    deterministic: bool = True,
    vecnormalize_path: str | os.PathLike | None = None,
) -> int:
    """Run episodes 0..n-1 (seeds ``seed + i``) and write them to ``out_path`` (``.bag`` or
    ``.mcap``; the file appears only once complete); returns the number of messages written.
    ``model``: a ``smartcar_gym.policy.Policy``, or an SB3-like model with the statistics at
    ``vecnormalize_path`` (as for ``evaluate_policy_episodes``)."""
    with episode_writer(out_path) as writer:
        evaluate_policy_episodes(model, env_id, n_episodes, 1, seed, env_kwargs, deterministic,
                                 vecnormalize_path, hooks=[BagRecorder(writer)])
        return writer.count
