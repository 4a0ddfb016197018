"""The smartcar vector conventions over arrays of cars, whatever steps them.

``CarsVectorEnv`` is what the numpy kinematic env (``SmartCarSimVectorEnv``) and the batched
physics env (``SmartCarBatchVectorEnv``) share: Gymnasium's vector API with the smartcar
conventions (docs/vector.md): autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
``s + i``, partial resets by ``reset_mask``, the ``goal`` reset option, ``info`` per car with
its ``_key`` masks, ``(N, 2)`` actions checked in one line, top-down ``render()`` tiles, a
closed env reopened by ``reset()``, and copies. A subclass says how its cars are reset
(``_reset_cars``), stepped (``_advance``) and observed (``_observe``, ``_info_values``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from smartcar_gym.envs.observation import Observation
from smartcar_gym.envs.vector.common import check_actions, check_seeds, vector_info
from smartcar_gym.envs.vector.render import top_down_tiles


class CarsVectorEnv(gym.vector.VectorEnv):
    """N smartcars as arrays, under Gymnasium's vector API (see the module)."""

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}
    #: attributes taken from ``settings`` (lambdas inside): a copy takes them again
    from_settings: tuple[str, ...] = ("observation",)
    # set by the subclass's __init__ before the first reset
    num_envs: int
    autoreset_mode: AutoresetMode
    max_episode_steps: int | None
    #: what the env calls itself in its error lines
    label: str

    def _take_settings(self, s: Any) -> None:
        """The task, observation, spaces and metadata of the single env (or its settings)
        ``s`` that every car shares."""
        self.settings = s
        self.task, self.observation = s.task, s.observation
        self.observation_names = s.observation_names
        self.render_mode = s.render_mode
        self.metadata = {**self.metadata, "render_fps": s.controller_config.rate_hz,
                         "autoreset_mode": self.autoreset_mode}
        self.single_observation_space = s.observation_space
        self.single_action_space = s.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    def _allocate_episodes(self, n: int) -> None:
        """Per car: its generator, steps, goal, distance, last action and episode flags."""
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._steps = np.zeros(n, dtype=np.int64)
        self.goal = np.zeros((n, 2))
        self._distance = np.zeros(n)
        self._prev_action = np.zeros((n, 2), dtype=np.float32)
        self._autoreset = np.zeros(n, dtype=bool)
        #: cars not simulated until a reset names them (``park`` where the subclass has it)
        self._parked = np.zeros(n, dtype=bool)
        self._needs_reset = True

    # -- copies --------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """Everything but what is taken from ``settings`` (the single env's own copy keeps
        its settings and declares its observation again)."""
        state = self.__dict__.copy()
        for key in self.from_settings:
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        for key in self.from_settings:
            setattr(self, key, getattr(self.settings, key))

    # -- gymnasium API -------------------------------------------------------------------------
    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """Each car's generator (created from entropy if it had none)."""
        return tuple(self._rng(i) for i in range(self.num_envs))

    def _rng(self, i: int) -> np.random.Generator:
        if self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random(None)
        return self._rngs[i]

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
        goals = self._check_options(options)
        self._reset_cars(mask, goals)
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
        restart = self._autoreset & ~self._parked \
            if self.autoreset_mode == AutoresetMode.NEXT_STEP \
            else np.zeros(self.num_envs, dtype=bool)
        reward, success, failure = self._advance(a)
        terminated = success | failure
        truncated = self._cut_short() | (
            self._steps >= self.max_episode_steps if self.max_episode_steps is not None
            else np.zeros(self.num_envs, dtype=bool))
        # a parked car has no episode: it never ends, so it is never autoreset
        terminated &= ~self._parked
        truncated &= ~self._parked
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            if restart.any():
                self._reset_cars(restart, None)
                reward[restart] = 0.0
                terminated[restart] = truncated[restart] = success[restart] = False
            obs = self._observe()
            info = self._info(np.ones(self.num_envs, dtype=bool), success)
        else:
            done = terminated | truncated
            obs = self._observe()
            info = self._info(np.ones(self.num_envs, dtype=bool), success)
            if done.any():
                final_obs = np.full(self.num_envs, None, dtype=object)
                for i in np.flatnonzero(done):
                    final_obs[i] = self._car_obs(obs, i)
                final_info = self._info(done, success)
                self._reset_cars(done, None)
                obs = self._observe()
                info = self._info(np.ones(self.num_envs, dtype=bool), success & ~done)
                info["final_obs"], info["_final_obs"] = final_obs, done.copy()
                info["final_info"], info["_final_info"] = final_info, done.copy()
        self._autoreset = terminated | truncated
        return obs, reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode='rgb_array'")
            return None
        s = self.settings
        return top_down_tiles(self._pose[:16, :2], self._pose[:16, 2], self.goal[:16],
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
        mask = options.pop("reset_mask")
        if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_
                and mask.shape == (self.num_envs,) and mask.any()):
            raise ValueError(f"options['reset_mask'] must be a bool array of shape "
                             f"({self.num_envs},) with a car to reset, got {mask!r}")
        if self._needs_reset and not mask.all():
            raise gym.error.ResetNeeded(f"{self.label}: the first reset() resets every car (no "
                                        "reset_mask)")
        return options or None, mask.copy()

    def _check_options(self, options: Any) -> np.ndarray | None:
        """The ``goal`` option as one goal per car ((N, 2); None: each car draws its own)."""
        if options is None:
            return None
        if not isinstance(options, dict) or set(options) - {"goal"}:
            raise ValueError(f"reset options must be {{'goal': (x, y) or an ({self.num_envs}, 2) "
                             f"array}}, got {options!r}")
        if "goal" not in options:
            return None
        goal = np.asarray(options["goal"], dtype=float)
        rows = goal.reshape(-1, 2) if goal.shape in ((2,), (self.num_envs, 2)) else None
        if rows is None:
            raise ValueError(f"options['goal'] must be (x, y) or an ({self.num_envs}, 2) array, "
                             f"got shape {goal.shape}")
        checked = np.array([self.task.check_goal(g) for g in rows])
        return np.broadcast_to(checked, (self.num_envs, 2))

    def _draw_goals(self, idx: np.ndarray, goals: np.ndarray | None) -> None:
        """Each listed car's goal: given, or drawn from its generator as its single env
        draws it."""
        origin = np.zeros(2)
        for i in idx:
            self.goal[i] = (goals[i] if goals is not None
                            else self.task.sample_goal(self._rng(i), origin))

    def _reset_cars(self, mask: np.ndarray, goals: np.ndarray | None) -> None:
        """The masked cars afresh, each with a new goal (``goals``, or drawn)."""
        raise NotImplementedError

    # -- steps ---------------------------------------------------------------------------------
    def _advance(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One controller period for every car: reward, success and failure."""
        raise NotImplementedError

    def _cut_short(self) -> np.ndarray:
        """Which cars the env itself truncates this step (none here: only the time limit)."""
        return np.zeros(self.num_envs, dtype=bool)

    # -- observations and infos ----------------------------------------------------------------
    def _observe(self) -> Any:
        """Every car's observation: ``Observation.build``'s values, in its order and rounding."""
        return self._build(self.observation, self._columns())

    def _car_obs(self, obs: Any, i: int) -> Any:
        """Car ``i``'s observation, copied out of the batch (``final_obs``)."""
        return obs[i].copy()

    def _columns(self) -> dict[str, Any]:
        """Each observation entry's values as columns over cars (by the entry's key)."""
        raise NotImplementedError

    def _build(self, observation: Observation, columns: dict[str, Any]) -> np.ndarray:
        """``observation.build`` for every car from the entries' ``columns``."""
        obs = np.empty((self.num_envs, len(observation.names)), dtype=np.float32)
        k = 0
        for entry in observation.entries:
            for col in columns[entry.key]:
                obs[:, k] = col  # each float64 value rounded once to float32
                k += 1
        return np.minimum(np.maximum(obs, observation.low, out=obs), observation.high, out=obs)

    def _info_values(self, success: np.ndarray) -> dict[str, np.ndarray]:
        """Every car's ``info`` values (as the single env's ``_info``) by key."""
        raise NotImplementedError

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
