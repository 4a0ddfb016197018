"""Uniform random actions as a policy: the baseline of the evaluations and the README's GIF."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

__all__ = ["RandomPolicy"]


class RandomPolicy:
    """Uniform random actions in [-1, 1]^2, seeded: a baseline (and the README's GIF).

    In the episodes run here each episode's actions are drawn from a generator seeded with
    ``(seed, episode)`` (``act_episodes``), as its reset is seeded with ``seed + episode``: the
    records do not depend on ``n_envs``, on batching or on which car ran an episode.
    ``predict`` (SB3's interface, for other callers) draws from one generator seeded with
    ``seed``."""

    observation_space = None

    def __init__(self, seed: int = 0) -> None:
        self.seed = seed
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.action_space.seed(seed)
        self._episodes: dict[int, np.random.Generator] = {}

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        """One sampled action per observation in the batch (a dict of batches for a Dict)."""
        first = np.asarray(next(iter(obs.values())) if isinstance(obs, dict) else obs)
        batch = first.reshape(-1, first.shape[-1])
        return np.stack([self.action_space.sample() for _ in batch]), None

    def act_episodes(self, episodes: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """Each car's action (float32, ``(N, 2)``) at step ``steps[car]`` of the episode
        ``episodes[car]`` it runs (-1: none, a zero action); step 0 seeds the episode's
        generator anew."""
        actions = np.zeros((len(episodes), 2), dtype=np.float32)
        for car, (episode, step) in enumerate(zip(episodes.tolist(), steps.tolist(),
                                                  strict=True)):
            if episode < 0:
                continue
            if step == 0 or episode not in self._episodes:
                self._episodes[episode] = np.random.default_rng([self.seed, episode])
            actions[car] = self._episodes[episode].uniform(-1.0, 1.0, 2)
        running = set(episodes.tolist())
        self._episodes = {e: g for e, g in self._episodes.items() if e in running}
        return actions
