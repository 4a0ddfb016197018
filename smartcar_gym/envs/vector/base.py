"""The smartcar vector conventions over arrays of cars, whatever steps them.

``CarsVectorEnv`` is what the numpy kinematic env (``SmartCarSimVectorEnv``) and the batched
physics env (``SmartCarBatchVectorEnv``) share: Gymnasium's vector API with the smartcar
conventions (docs/vector.md): autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
``s + i``, partial resets by ``reset_mask``, the task's reset options, ``info`` per car with
its ``_key`` masks, ``(N, 2)`` actions checked in one line, top-down ``render()`` tiles, a
closed env reopened by ``reset()``, and copies. Both run one task object over all their cars
(``envs.tasks.base.Task``) on their public state (``state``); a subclass says how its cars
are reset (``_reset_cars``) and how a period runs (``_run``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.envs.state import CarState
from smartcar_gym.envs.tasks.base import Task, no_options
from smartcar_gym.envs.vector.common import (
    check_actions,
    check_reset_mask,
    check_seeds,
    vector_info,
)
from smartcar_gym.envs.vector.render import top_down_tiles


class CarsVectorEnv(gym.vector.VectorEnv):
    """N smartcars as arrays, under Gymnasium's vector API (see the module)."""

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}
    # set by the subclass's __init__ before the first reset
    num_envs: int
    autoreset_mode: AutoresetMode
    max_episode_steps: int | None
    #: what the env calls itself in its error lines
    label: str
    #: the worker threads a task may split per-car work over
    threads = 1
    #: every car's public state (one row a car): what the task reads and writes
    state: CarState
    #: the task, run over every car
    task: Task
    #: every car's ArbotiX controller (and boards), in arrays
    base: BatchedArbotix

    def _take_settings(self, s: Any) -> None:
        """The task, spaces and metadata of the single env ``s`` that every car is."""
        self.settings = s
        self.task = s.task.for_cars(self.num_envs)
        self.observation_names = s.observation_names
        self.render_mode = s.render_mode
        self.max_linear, self.max_angular = s.max_linear, s.max_angular
        self.metadata = {**self.metadata, "render_fps": s.controller_config.rate_hz,
                         "autoreset_mode": self.autoreset_mode}
        self.single_observation_space = s.observation_space
        self.single_action_space = s.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    def _allocate_episodes(self, n: int, wheels: int, sensors: dict[str, Any]) -> None:
        """Per car: its generator, its state and its episode flags."""
        self._rngs: list[np.random.Generator | None] = [None] * n
        self.state = CarState.zeros(n, wheels, sensors)
        self._autoreset = np.zeros(n, dtype=bool)
        self._needs_reset = True

    def __getattr__(self, name: str) -> Any:
        """What the task exports (``obstacles``, ``compute_reward``, ...), read here."""
        task = self.__dict__.get("task")
        if task is not None and name in task.exports:
            return getattr(task, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def goal(self) -> np.ndarray:
        """Every car's goal (N, 2), odom frame."""
        return self.state.goal

    # -- what the task sees (``tasks.base.Cars``) ------------------------------------------------
    @staticmethod
    def values(array: np.ndarray) -> np.ndarray:
        """Every car's values: the array itself."""
        return array

    def rng(self, car: int) -> np.random.Generator:
        """Car ``car``'s generator (created from entropy if it had none)."""
        if self._rngs[car] is None:
            self._rngs[car], _ = seeding.np_random(None)
        return self._rngs[car]

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """Each car's generator (created from entropy if it had none)."""
        return tuple(self.rng(i) for i in range(self.num_envs))

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        n = self.num_envs
        seeds = check_seeds(seed, n)
        if self.closed:  # as the single envs: reset() reopens
            self._reopen()
            self.closed = False
        options, mask = self._reset_mask(options)
        for i, s in enumerate(seeds):
            if mask[i] and (s is not None or self._rngs[i] is None):
                self._rngs[i], _ = seeding.np_random(s)
        checked = self.task.check_options(options, vector=True)
        self._reset_cars(mask, checked)
        self._autoreset[mask] = False
        self._needs_reset = False
        return self._observe(), self._info(mask, np.zeros(n, dtype=bool))

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray,
                                          dict[str, Any]]:
        if self.closed:
            raise RuntimeError(f"{self.label} is closed: call reset() to reopen it before "
                               "step()")
        if self._needs_reset:
            raise gym.error.ResetNeeded(f"{self.label}: call reset() before step()")
        a = check_actions(actions, self.num_envs)
        state, task = self.state, self.task
        parked = state.parked
        restart = self._autoreset & ~parked \
            if self.autoreset_mode == AutoresetMode.NEXT_STEP \
            else np.zeros(self.num_envs, dtype=bool)
        self._run(a[:, 0] * self.max_linear, a[:, 1] * self.max_angular)
        state.steps += 1
        reward, success, failure = task.score(self, a)
        state.previous_action[:] = a
        terminated = success | failure
        truncated = task.truncated(self) | (
            state.steps >= self.max_episode_steps if self.max_episode_steps is not None
            else np.zeros(self.num_envs, dtype=bool))
        # a parked car has no episode: it never ends, so it is never autoreset
        terminated &= ~parked
        truncated &= ~parked
        if restart.any():  # NextStep: the cars that ended at the last step start afresh
            self._reset_cars(restart, no_options(self.num_envs))
            reward[restart] = 0.0
            terminated[restart] = truncated[restart] = success[restart] = False
        everyone = np.ones(self.num_envs, dtype=bool)
        obs = self._observe()
        info = self._info(everyone, success)
        if self.autoreset_mode == AutoresetMode.SAME_STEP:
            done = terminated | truncated
            if done.any():
                final_obs = np.full(self.num_envs, None, dtype=object)
                for i in np.flatnonzero(done):
                    final_obs[i] = task.car_obs(obs, i)
                final_info = self._info(done, success)
                self._reset_cars(done, no_options(self.num_envs))
                obs = self._observe()
                info = self._info(everyone, success & ~done)
                info["final_obs"], info["_final_obs"] = final_obs, done.copy()
                info["final_info"], info["_final_info"] = final_info, done.copy()
        self._autoreset = terminated | truncated
        return obs, reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode='rgb_array'")
            return None
        s, pose = self.settings, self.state.pose
        return top_down_tiles(pose[:16, :2], pose[:16, 2], self.state.goal[:16],
                              s.task.goal_tolerance_m, s.task.arena_half_size_m,
                              s.render_width, s.render_height)

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release: no engine, no files."""

    def _reopen(self) -> None:
        """What ``close_extras`` released, back before ``reset`` starts the cars again (nothing
        here)."""

    # -- resets --------------------------------------------------------------------------------
    def _reset_mask(self, options: Any) -> tuple[Any, np.ndarray]:
        """``options`` without ``"reset_mask"``, and the cars to reset (all without one)."""
        everyone = np.ones(self.num_envs, dtype=bool)
        if not isinstance(options, dict) or "reset_mask" not in options:
            return options, everyone
        options = dict(options)
        mask = check_reset_mask(options.pop("reset_mask"), self.num_envs)
        if self._needs_reset and not mask.all():
            raise gym.error.ResetNeeded(f"{self.label}: the first reset() resets every car (no "
                                        "reset_mask)")
        return options or None, mask

    def _reset_cars(self, mask: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """The masked cars afresh, each with its episode's ``options`` (one a car of the
        batch, ``Task.check_options``'s or ``no_options``)."""
        raise NotImplementedError

    def _run(self, linear_x: np.ndarray, angular_z: np.ndarray) -> None:
        """Every car's ``cmd_vel`` now, one controller period, and the state read after it."""
        raise NotImplementedError

    def _read_odometry(self) -> None:
        """Every car's odometry in the state, from the batched controllers (``base``)."""
        odometry, b = self.state.odometry, self.base
        odometry[:, 0], odometry[:, 1], odometry[:, 2] = b.x, b.y, b.theta
        odometry[:, 3], odometry[:, 4] = b.odom_v, b.odom_w

    # -- observations and infos ----------------------------------------------------------------
    def _observe(self) -> Any:
        """Every car's observation, the task's."""
        return self.task.observe(self)

    def _info_values(self, success: np.ndarray) -> dict[str, Any]:
        """Every car's ``info`` values (the task's) by key."""
        return self.task.info(self, success)

    def _info(self, mask: np.ndarray, success: np.ndarray) -> dict[str, Any]:
        values = self._info_values(success)
        if not mask.all():
            values = _masked(values, mask)
        return vector_info(values, mask)


def _masked(values: dict[str, Any], mask: np.ndarray) -> dict[str, Any]:
    """``values`` (arrays over cars, or dicts of them) with the unmasked cars' zeroed."""
    return {k: _masked(v, mask) if isinstance(v, dict)
            else np.where(mask.reshape(-1, *([1] * (v.ndim - 1))), v, np.zeros_like(v))
            for k, v in values.items()}
