"""Every step of an evaluation's episodes, read from its vector env.

The evaluation loops (``agents.episodes``: one observation at a time, or
on a batch) call an ``EpisodeSteps`` when cars begin episodes (``begin``: the reset's
observations and infos) and after each step (``step``: the actions sent, the observations,
rewards, terminations, truncations and infos that came back). Reading only what the loop
already has, it changes nothing in the episodes. An ended episode is kept as an
``EpisodeSteps.Episode`` under its number; ``episodes()`` lists them in episode order.

Infos: an entry is kept when it is a number or a numeric array in every info of the episode,
reset included, with the same shape (``pose``, ``distance``, ``is_success``, ...); entries
that are dicts or objects (a recorder's capture) are left out.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["EpisodeSteps"]


@dataclass
class _Buffer:
    episode: int
    seed: int
    observations: list[Any] = field(default_factory=list)
    actions: list[np.ndarray] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    terminations: list[bool] = field(default_factory=list)
    truncations: list[bool] = field(default_factory=list)
    infos: list[dict[str, np.ndarray]] = field(default_factory=list)


class EpisodeSteps:
    """The evaluation's steps (see the module docstring); episode ``i`` has seed
    ``seed + i``."""

    @dataclass
    class Episode:
        """One ended episode: ``T`` steps, ``T + 1`` observations and infos."""

        episode: int
        seed: int
        observations: np.ndarray | dict[str, np.ndarray]
        actions: np.ndarray
        rewards: np.ndarray
        terminations: np.ndarray
        truncations: np.ndarray
        infos: dict[str, np.ndarray]

    def __init__(self, seed: int = 0) -> None:
        self.seed = seed
        self._open: dict[int, _Buffer] = {}
        self._done: dict[int, EpisodeSteps.Episode] = {}

    def begin(self, slots: Iterable[int], episodes: Sequence[int] | np.ndarray, obs: Any,
              info: Mapping[str, Any]) -> None:
        """Cars ``slots`` begin episodes ``episodes`` (one each, in order) with the reset's
        batched ``obs`` and ``info``."""
        for slot, episode in zip(slots, episodes, strict=True):
            slot, episode = int(slot), int(episode)
            buffer = _Buffer(episode, self.seed + episode)
            buffer.observations.append(_row(obs, slot))
            buffer.infos.append(_array_infos(info, slot))
            self._open[slot] = buffer

    def step(self, slots: Iterable[int], actions: np.ndarray, obs: Any, reward: np.ndarray,
             terminated: np.ndarray, truncated: np.ndarray, info: Mapping[str, Any]) -> None:
        """The cars ``slots`` (those with an episode) took ``actions`` (the batch sent)."""
        for slot in slots:
            slot = int(slot)
            buffer = self._open[slot]
            buffer.actions.append(np.array(actions[slot], dtype=np.float32))
            buffer.observations.append(_row(obs, slot))
            buffer.rewards.append(float(reward[slot]))
            buffer.terminations.append(bool(terminated[slot]))
            buffer.truncations.append(bool(truncated[slot]))
            buffer.infos.append(_array_infos(info, slot))
            if terminated[slot] or truncated[slot]:
                self._done[buffer.episode] = _finish(self._open.pop(slot))

    def episodes(self) -> list[EpisodeSteps.Episode]:
        """The ended episodes, in episode order."""
        return [self._done[key] for key in sorted(self._done)]


def _row(obs: Any, slot: int) -> Any:
    if isinstance(obs, Mapping):
        return {key: np.array(value[slot]) for key, value in obs.items()}
    return np.array(obs[slot])


def _array_infos(info: Mapping[str, Any], slot: int) -> dict[str, np.ndarray]:
    """The entries of car ``slot`` in a vector env's ``info`` that are numeric arrays."""
    kept = {}
    for key, values in info.items():
        if key.startswith("_"):
            continue
        mask = info.get(f"_{key}")
        if mask is not None and not np.asarray(mask)[slot]:
            continue
        try:
            value = np.asarray(values[slot])
        except (IndexError, KeyError, TypeError):
            continue
        if value.dtype.kind in "biuf":
            kept[key] = value
    return kept


def _stack(rows: list[Any]) -> Any:
    if isinstance(rows[0], Mapping):
        return {key: np.stack([row[key] for row in rows]) for key in rows[0]}
    return np.stack(rows)


def _finish(buffer: _Buffer) -> EpisodeSteps.Episode:
    infos: dict[str, np.ndarray] = {}
    for key, first in buffer.infos[0].items():
        values = [info.get(key) for info in buffer.infos]
        if all(v is not None and v.shape == first.shape for v in values):
            infos[key] = np.stack(values).astype(np.result_type(*values))
    return EpisodeSteps.Episode(
        episode=buffer.episode, seed=buffer.seed,
        observations=_stack(buffer.observations), actions=np.stack(buffer.actions),
        rewards=np.array(buffer.rewards, dtype=np.float64),
        terminations=np.array(buffer.terminations), truncations=np.array(buffer.truncations),
        infos=infos)
