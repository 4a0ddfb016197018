"""The vector env of the pybullet ids: N single envs stepped one after the other."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from smartcar_gym.envs.vector.common import (
    check_actions,
    check_autoreset_mode,
    check_max_episode_steps,
    check_num_envs,
    check_num_threads,
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
    with ``s + i``, vector ``info`` with ``is_success`` and its ``_is_success`` mask, and
    ``render()`` the first car's frame. ``max_episode_steps`` means what it means to the
    batches (None: the id's limit, -1: none) and ``num_threads`` is checked as theirs (and
    unused). Every other kwarg goes to each single env (so an ``engine`` kwarg reaches the
    engine choice of the single envs).
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

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """``SyncVectorEnv.reset``, after a one-line error for seeds that are not an integer,
        None or one per car."""
        return super().reset(seed=check_seeds(seed, self.num_envs), options=options)

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        """``SyncVectorEnv.step``, after a one-line error for a batch not of shape (N, 2)."""
        check_actions(actions, self.num_envs)
        return super().step(actions)

    def render(self) -> Any:
        """The first car's frame (``render_mode="rgb_array"``: an image; None otherwise)."""
        return self.envs[0].render()
