"""Comparing an exported policy with its SB3 model: ``smartcar-export``'s check before it
writes, and the observations of seeded episodes that the tests and the benchmark compare on."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["check_actions", "episode_observations"]


def check_actions(policy: Any, path: str | Path, n: int, seed: int = 0) -> float | None:
    """The largest difference between the SB3 policy's deterministic actions and the exported
    file's (numpy evaluator) on ``n`` observations drawn in the observation space (None if
    ``n`` is 0)."""
    if n == 0:
        return None
    from smartcar_gym.runtime.onnx_policy import load_onnx

    space = policy.model.observation_space
    low = np.maximum(space.low, -10.0)
    high = np.minimum(space.high, 10.0)
    obs = np.random.default_rng(seed).uniform(low, high, (n, *space.shape)).astype(np.float32)
    exported, _ = load_onnx(path, runtime="numpy").predict(obs)
    batch = obs if policy.normalizer is None else policy.normalizer(obs)
    expected, _ = policy.model.predict(batch, deterministic=True)
    return float(np.max(np.abs(exported - expected)))


def episode_observations(policy: Any, n: int, cars: int = 64) -> np.ndarray:
    """``n`` float32 observations of seeded episodes (seeds ``0..cars-1`` and the next ones
    the batch starts) of ``policy``'s env on the planar batch, driven by ``policy``."""
    from smartcar_gym.agents.episodes import act_batch, make_batched_env

    envs = make_batched_env(policy.env_id, cars, {**policy.env_kwargs, "engine": "planar"})
    rows = []
    try:
        obs, _ = envs.reset(seed=list(range(cars)))
        while sum(len(r) for r in rows) < n:
            rows.append(np.array(obs, dtype=np.float32))
            obs, *_ = envs.step(act_batch(policy, obs))
    finally:
        envs.close()
    return np.concatenate(rows)[:n]
