"""Policy checks for your own test suite: seeded episodes, their metrics, a success assertion.

::

    from smartcar_gym.policy import Policy
    from smartcar_gym.testing import assert_success, evaluate

    def test_my_policy_reaches_its_goals():
        policy = Policy.load("runs/ppo_SmartCar-v0_s0")      # or an SB3 model, or obs -> action
        assert_success(policy, episodes=50, engine="mujoco", at_least=0.95)

    def test_my_controller():
        metrics = evaluate(my_controller, "SmartCarSim-v0", episodes=20)
        assert metrics.mean_final_distance_m < 0.1, metrics.summary_line()

``policy`` is a ``smartcar_gym.policy.Policy`` (its normaliser applies; its env id and env
kwargs are the defaults), a Stable-Baselines3 model (anything with ``predict(obs,
deterministic=...)``; pass ``normalizer=`` for its VecNormalize statistics, a pickle: only a
file you trust), or a plain callable ``obs -> action`` of one observation (called once per
observation, batched or not). Episode ``i`` is seeded ``seed + i``, as ``smartcar-eval``.

``batched=True`` (the default) runs the episodes as ``smartcar-eval --vectorization batched``:
``n_envs`` cars (default 64) of the id's ``vector_entry_point`` in this process, so no test needs
``if __name__ == "__main__"``; ``batched=False`` steps one single env in this process. Both give
the same records for a callable; an SB3 model's batched actions round differently from a batch
of one (``agents.episodes``: the records agree within ``RECORD_TOLERANCE``).

``assert_success`` raises ``AssertionError`` with one line: the env, the success rate against
the mark, the failed seeds. ``RandomPolicy`` (uniform random actions) is a failing baseline.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smartcar_gym.agents.episodes import (
    DEFAULT_BATCH,
    evaluate_batched_episodes,
    evaluate_policy_episodes,
)
from smartcar_gym.agents.policies import DEFAULT_ENV_ID, Policy, as_policy
from smartcar_gym.agents.random_policy import RandomPolicy
from smartcar_gym.agents.records import EpisodeRecord, summarize
from smartcar_gym.checks import distinct_figure

__all__ = ["FunctionModel", "Metrics", "RandomPolicy", "assert_success", "evaluate"]


class FunctionModel:
    """A plain function of one observation seen as an SB3-like model: ``predict`` calls it
    once per observation of a batch (a dict of batches gives it one dict per car). Each
    action must hold ``action_shape``'s numbers (the smartcar envs': ``(2,)``, linear and
    angular); another shape is a ``ValueError`` in one line, batched or not."""

    observation_space = None

    def __init__(self, fn: Callable[[Any], Any], action_shape: tuple[int, ...] = (2,)) -> None:
        self.fn = fn
        self.action_shape = tuple(action_shape)

    def predict(self, obs: np.ndarray | Mapping[str, np.ndarray],
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        if isinstance(obs, Mapping):
            n = len(next(iter(obs.values())))
            rows: Sequence[Any] = [{k: v[i] for k, v in obs.items()} for i in range(n)]
        else:
            rows = obs
        return np.stack([self._action(row) for row in rows]), None

    def _action(self, row: Any) -> np.ndarray:
        """The callable's action for one observation, checked and shaped ``action_shape``."""
        action = np.asarray(self.fn(row), dtype=np.float32)
        if action.size != math.prod(self.action_shape):
            raise ValueError(f"policy: the callable returned an action of shape {action.shape}; "
                             f"expected shape {self.action_shape} (linear, angular in [-1, 1])")
        return action.reshape(self.action_shape)


@dataclass(frozen=True)
class Metrics:
    """What ``evaluate`` measured: ``smartcar-eval``'s summary, with the episodes' records."""

    env_id: str
    env_kwargs: dict[str, Any]
    batched: bool
    seed: int
    episodes: int
    success_rate: float
    mean_return: float
    std_return: float
    mean_time_to_goal_s: float | None
    mean_final_distance_m: float
    mean_final_odom_error_m: float
    mean_length: float
    records: tuple[EpisodeRecord, ...] = field(repr=False)

    @property
    def failed_seeds(self) -> list[int]:
        """The seeds of the episodes that did not reach the goal."""
        return [r.seed for r in self.records if not r.success]

    def summary_line(self) -> str:
        """One line: env, success rate, episodes and seeds, mean final distance."""
        kwargs = ", ".join(f"{k}={v!r}" for k, v in self.env_kwargs.items())
        how = f"{kwargs}, batched" if self.batched and kwargs else (
            "batched" if self.batched else kwargs or "single env")
        return (f"{self.env_id} ({how}): {self.success_rate:.1%} success over {self.episodes} "
                f"episodes (seeds {self.seed}..{self.seed + self.episodes - 1}), mean final "
                f"distance {self.mean_final_distance_m:.3f} m")


def evaluate(policy: Policy | Any, env_id: str | None = None, *, episodes: int = 20,
             engine: str | None = None, batched: bool = True, seed: int = 0,
             n_envs: int | None = None, env_kwargs: Mapping[str, Any] | None = None,
             deterministic: bool = True,
             normalizer: str | os.PathLike | None = None) -> Metrics:
    """Run ``episodes`` seeded episodes (``seed + i``) of ``policy`` on ``env_id`` and return
    their ``Metrics``.

    ``env_id`` and ``env_kwargs`` default to a ``Policy``'s own (else ``SmartCar-v0``, no
    kwargs; given ``env_kwargs`` are added to the policy's); ``engine`` (``"pybullet"``,
    ``"mujoco"``) is the env kwarg of that name. ``n_envs``: cars of the batch (default 64),
    or single envs (default 1; worker processes when > 1) with ``batched=False``. Bad
    arguments raise ``ValueError`` or ``TypeError`` with one line naming the argument.
    """
    episodes = _whole("episodes", episodes, 1)
    n_envs = None if n_envs is None else _whole("n_envs", n_envs, 1)
    seed = _whole("seed", seed, 0)
    if env_kwargs is not None and (not isinstance(env_kwargs, Mapping)
                                   or not all(isinstance(k, str) for k in env_kwargs)):
        raise TypeError(f"env_kwargs: expected a mapping of gym.make keyword names to values, "
                        f"got {env_kwargs!r}")
    resolved = _as_policy(policy, normalizer)
    env_id = env_id or (resolved.env_id if isinstance(policy, Policy) else DEFAULT_ENV_ID)
    kwargs = {**(resolved.env_kwargs if isinstance(policy, Policy) else {}),
              **dict(env_kwargs or {})}
    if engine is not None:
        kwargs["engine"] = engine
    common = dict(env_id=env_id, n_episodes=episodes, seed=seed, env_kwargs=kwargs,
                  deterministic=deterministic)
    if batched:
        records = evaluate_batched_episodes(resolved, n_envs=n_envs or DEFAULT_BATCH, **common)
    else:
        records = evaluate_policy_episodes(resolved, n_envs=n_envs or 1, **common)
    summary = summarize(records)
    return Metrics(env_id=env_id, env_kwargs=kwargs, batched=batched, seed=seed,
                   episodes=summary["episodes"], success_rate=summary["success_rate"],
                   mean_return=summary["mean_return"], std_return=summary["std_return"],
                   mean_time_to_goal_s=summary["mean_time_to_goal_s"],
                   mean_final_distance_m=summary["mean_final_distance_m"],
                   mean_final_odom_error_m=summary["mean_final_odom_error_m"],
                   mean_length=summary["mean_length"], records=tuple(records))


def assert_success(policy: Policy | Any, env_id: str | None = None, *, at_least: float = 0.95,
                   max_final_distance: float | None = None, **kwargs: Any) -> Metrics:
    """``evaluate(policy, env_id, **kwargs)``, then ``AssertionError`` with one line when the
    success rate is under ``at_least`` (a fraction: 0.95 for 95 %) or the mean final distance
    (m) is over ``max_final_distance``; the ``Metrics`` otherwise."""
    at_least = _plain(at_least)
    if not _is_real(at_least) or not 0.0 <= at_least <= 1.0:
        hint = f" (for {at_least}% pass {at_least / 100:g})" if _is_real(
            at_least) and 1.0 < at_least <= 100.0 else ""
        raise ValueError(f"at_least: expected a fraction from 0 to 1, got {at_least!r}{hint}")
    max_final_distance = _plain(max_final_distance)
    if max_final_distance is not None and not (
            _is_real(max_final_distance) and 0.0 < max_final_distance < math.inf):
        raise ValueError(f"max_final_distance: expected metres > 0, got {max_final_distance!r}")
    metrics = evaluate(policy, env_id, **kwargs)
    problems = []
    if metrics.success_rate + 1e-12 < at_least:
        failed = metrics.failed_seeds
        shown = ", ".join(map(str, failed[:10])) + (", ..." if len(failed) > 10 else "")
        rate = distinct_figure(100.0 * metrics.success_rate, 100.0 * at_least, 1)
        problems.append(f"success {rate}% is under {at_least:.1%} (failed seeds: {shown})")
    if max_final_distance is not None and metrics.mean_final_distance_m > max_final_distance:
        mean = distinct_figure(metrics.mean_final_distance_m, max_final_distance, 3)
        problems.append(f"mean final distance {mean} m is over {max_final_distance:g} m")
    if problems:
        raise AssertionError(f"{metrics.summary_line()}: {'; '.join(problems)}")
    return metrics


def _plain(value: Any) -> Any:
    """A numpy scalar as the Python number it holds (anything else as it is)."""
    return value.item() if isinstance(value, np.generic) else value


def _is_real(value: Any) -> bool:
    """A real number, not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _whole(name: str, value: Any, low: int) -> int:
    """``value`` as an int >= ``low`` (numpy integers too); one line naming ``name`` else."""
    value = _plain(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
    return value


def _as_policy(policy: Any, normalizer: str | os.PathLike | None) -> Policy:
    """A ``Policy`` of what ``evaluate`` was given (one line naming the argument otherwise)."""
    if isinstance(policy, Policy):
        if normalizer is not None:
            raise ValueError("normalizer: a Policy brings its own; pass normalizer only with "
                             "an SB3 model")
        return policy
    if hasattr(policy, "predict"):
        return as_policy(policy, normalizer)
    if callable(policy):
        if normalizer is not None:
            raise ValueError("normalizer: only for an SB3 model; a callable gets the env's "
                             "raw observations")
        return Policy(FunctionModel(policy), algo="function")
    raise TypeError(f"policy: expected a smartcar_gym.policy.Policy, an SB3 model (with "
                    f"predict) or a callable obs -> action, got {type(policy).__name__}")
