"""The vector env of the pybullet ids: N single envs stepped one after the other."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.vector.utils import concatenate

from smartcar_gym.envs.vector.common import (
    check_actions,
    check_autoreset_mode,
    check_max_episode_steps,
    check_num_envs,
    check_num_threads,
    check_park_mask,
    check_reset_mask,
    check_seeds,
)

#: measured: each SmartCar-v0 env adds about 30 MiB (benchmarks/batched_speed.py)
BYTES_PER_CAR = 32 * 2**20


class SmartCarLoopVectorEnv(SyncVectorEnv):
    """N single smartcar envs (``gym.make(env_id, **kwargs)``) stepped in a loop.

    The pybullet ids are not batched: an earlier measurement of N cars in one pybullet world
    gained nothing over N worlds, so this is ``SyncVectorEnv`` with the smartcar vector
    conventions: Gymnasium 1.x autoreset (``"NextStep"`` by default, ``autoreset_mode=
    "SameStep"`` puts ``final_obs``/``final_info`` in ``info``), ``reset(seed=s)`` seeds car i
    with ``s + i``, the task's reset options as the batches read them (one value for every
    reset car, or one per car where the task takes that: ``world``, ``goal``), vector ``info``
    with ``is_success`` and its ``_is_success`` mask, ``park`` (a parked env is not stepped
    until a reset names it), and ``render()`` the first car's frame. ``max_episode_steps``
    means what it means to the batches (None: the id's limit, -1: none) and ``num_threads`` is
    checked as theirs (and unused). Every other kwarg goes to each single env (so an
    ``engine`` kwarg reaches the engine choice of the single envs).
    """

    def __init__(self, env_id: str, num_envs: int = 1, max_episode_steps: int | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 num_threads: int | None = None, **kwargs: Any) -> None:
        num_envs = check_num_envs(num_envs, env_id, BYTES_PER_CAR)
        mode = check_autoreset_mode(autoreset_mode)
        check_num_threads(num_threads)  # the batches' argument: one env at a time here
        limit = check_max_episode_steps(max_episode_steps, env_id)
        #: steps before a car's episode is truncated (None: no limit), as the batches say it
        self.max_episode_steps = limit
        kwargs["max_episode_steps"] = -1 if limit is None else limit  # gym.make's "no limit"
        self.env_id = env_id

        def make() -> gym.Env:
            return gym.make(env_id, **kwargs)

        super().__init__([make] * num_envs, autoreset_mode=mode)
        #: the envs not stepped until a reset names them (``park``)
        self.parked = np.zeros(self.num_envs, dtype=bool)
        task = getattr(self.envs[0].unwrapped, "task", None)
        self._options = None if task is None else task.for_cars(self.num_envs)

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """``SyncVectorEnv.reset``, after a one-line error for seeds that are not an integer,
        None or one per car, with each car's own options."""
        seeds = check_seeds(seed, self.num_envs)
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        mask = (np.ones(self.num_envs, dtype=bool) if mask is None
                else check_reset_mask(mask, self.num_envs))
        cars = (self._options.check_options(options or None, vector=True)
                if self._options is not None and options else [options or None] * self.num_envs)
        self.parked[mask] = False
        self._terminations[mask] = self._truncations[mask] = False
        self._autoreset_envs[mask] = False
        infos: dict[str, Any] = {}
        for i in np.flatnonzero(mask).tolist():
            self._env_obs[i], info = self.envs[i].reset(seed=seeds[i], options=cars[i] or None)
            infos = self._add_info(infos, info, i)
        self._observations = concatenate(self.single_observation_space, self._env_obs,
                                         self._observations)
        return self._copy(self._observations), infos

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        """``SyncVectorEnv.step``, after a one-line error for a batch not of shape (N, 2); a
        parked env is not stepped (its observation stays, reward 0, never ending)."""
        check_actions(actions, self.num_envs)
        if not self.parked.any():
            return super().step(actions)
        infos: dict[str, Any] = {}
        for i, action in enumerate(np.asarray(actions)):
            if self.parked[i]:
                self._rewards[i] = 0.0
                self._terminations[i] = self._truncations[i] = False
                continue
            infos = self._add_info(infos, self._step_one(i, action, infos), i)
        self._observations = concatenate(self.single_observation_space, self._env_obs,
                                         self._observations)
        self._autoreset_envs = np.logical_or(self._terminations, self._truncations)
        return (self._copy(self._observations), np.copy(self._rewards),
                np.copy(self._terminations), np.copy(self._truncations), infos)

    def _step_one(self, i: int, action: Any, infos: dict[str, Any]) -> dict[str, Any]:
        """Env ``i``'s step (or its autoreset), as ``SyncVectorEnv.step`` takes it; its info."""
        env = self.envs[i]
        if self.autoreset_mode == AutoresetMode.NEXT_STEP and self._autoreset_envs[i]:
            self._env_obs[i], info = env.reset()
            self._rewards[i] = 0.0
            self._terminations[i] = self._truncations[i] = False
            return info
        (self._env_obs[i], self._rewards[i], self._terminations[i], self._truncations[i],
         info) = env.step(action)
        if self.autoreset_mode == AutoresetMode.SAME_STEP and (
                self._terminations[i] or self._truncations[i]):
            infos.update(self._add_info(infos, {"final_obs": self._env_obs[i],
                                                "final_info": info}, i))
            self._env_obs[i], info = env.reset()
        return info

    def park(self, mask: np.ndarray) -> None:
        """Stop stepping the masked envs until a ``reset`` names each one (as the batches'
        ``park``)."""
        self.parked |= check_park_mask(mask, self.num_envs)

    def _copy(self, obs: Any) -> Any:
        from copy import deepcopy

        return deepcopy(obs) if self.copy else obs

    def render(self) -> Any:
        """The first car's frame (``render_mode="rgb_array"``: an image; None otherwise)."""
        return self.envs[0].render()
