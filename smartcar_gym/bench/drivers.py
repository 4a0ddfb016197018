"""What drives the cars in a benchmark: a trained policy, or a classical driver by name.

A driver has ``reset(cars, indices)`` (the episodes of the cars ``indices`` have just
started) and ``act(cars, obs, indices)`` (the actions (K, 2) of those K cars from their
observations (K, ...)), where ``cars`` is a ``envs.vector.view.CarView``: the cars' public
state and task. ``DRIVERS`` names the classical ones; ``PolicyDriver`` wraps a
``smartcar_gym.policy.Policy``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from smartcar_gym.bench.dwa import DWADriver

#: the classical drivers, by ``--driver`` name
DRIVERS = {"dwa": DWADriver}


class DriverError(ValueError):
    """A driver that cannot drive these envs (unknown name, another observation space)."""


def make_driver(name: str, **options: Any) -> Any:
    """The classical driver called ``name``, given ``options`` (DriverError listing them for
    another name)."""
    if name not in DRIVERS:
        raise DriverError(f"--driver: unknown driver {name!r}; the drivers are "
                          f"{', '.join(sorted(DRIVERS))}")
    return DRIVERS[name](**options)


class PolicyDriver:
    """A trained policy: every car's action from one ``predict`` call (``act_batch``: the
    policy's normaliser on the batch, as ``Policy.act`` on each)."""

    def __init__(self, policy: Any, name: str, deterministic: bool = True) -> None:
        self.policy = policy
        self.name = name
        self.deterministic = deterministic

    def check(self, env_id: str, space: Any) -> None:
        """DriverError (one line, both shapes) if the policy was trained on observations of
        another shape than the env's."""
        expected = getattr(self.policy.observation_space, "shape", None)
        if expected is not None and tuple(expected) != tuple(space.shape):
            trained = getattr(self.policy, "env_id", None) or "another env"
            raise DriverError(f"{self.name} takes observations of shape {tuple(expected)} (it "
                              f"was trained on {trained}) but {env_id} gives "
                              f"{tuple(space.shape)}: train a policy on {env_id}")

    def reset(self, cars: Any, indices: Sequence[int] | None = None) -> None:
        """Nothing to prepare: a policy sees only its observations."""

    def act(self, cars: Any, obs: np.ndarray,
            indices: Sequence[int] | None = None) -> np.ndarray:
        """One action per observation (``(K, 2)`` for ``obs`` ``(K, ...)``)."""
        from smartcar_gym.agents.episodes import act_batch

        return act_batch(self.policy, obs, deterministic=self.deterministic)
