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
    """``n`` float32 observations of seeded episodes of ``policy``'s env (episode i seeded
    ``i``), driven by ``policy``, through the episode runner on ``cars`` cars of a batching
    engine (the policy's own where it batches: ``sim.engines.batch_engine``): every running
    car's observation at each reset and step, in order, until there are ``n``."""
    from smartcar_gym.agents.episodes import act_batch
    from smartcar_gym.agents.runner import Hooks, Job, run_jobs
    from smartcar_gym.agents.vec_envs import make_batched_env
    from smartcar_gym.sim.engines import batch_engine

    engine = batch_engine(policy.env_kwargs.get("engine"))
    envs = make_batched_env(policy.env_id, cars, {**policy.env_kwargs, "engine": engine})
    rows: list[np.ndarray] = []

    class Observations(Hooks):
        count = 0  # the observations kept so far

        def keep(self, obs: Any, idx: np.ndarray) -> None:
            rows.append(np.array(obs[idx], dtype=np.float32))
            self.count += len(idx)

        def begin(self, envs: Any, idx: np.ndarray, jobs: Any, obs: Any, info: Any) -> None:
            self.keep(obs, idx)

        def step(self, idx: np.ndarray, actions: Any, obs: Any, *rest: Any) -> None:
            self.keep(obs, idx)

    def act(obs: Any, running: list, steps: np.ndarray) -> np.ndarray:
        return act_batch(policy, obs)

    jobs = [Job(i, i) for i in range(max(n, cars))]  # more than enough: each takes a step
    try:
        kept = Observations()
        run_jobs(envs, jobs, act, [kept], stop=lambda: kept.count >= n)
    finally:
        envs.close()
    return np.concatenate(rows)[:n]
