"""What the policy node needs of the env a policy was trained in, without making the env.

The env's keyword arguments (its registration's, then the run's ``env_kwargs``) give the robot
model (for the wheel joints, in the env's order), the task (arena, tolerance), the action scale
and the controller's rate; defaults are read from ``SmartCarEnv``'s own signature, so there is
no second copy of them. ``observation`` is the env's own declaration (``declare_observation``).
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any

import gymnasium as gym

from smartcar_gym import checks
from smartcar_gym.controller import ArbotixConfig, load_controller_config
from smartcar_gym.envs.observation import Observation
from smartcar_gym.envs.smartcar_env import SmartCarEnv, declare_observation, observed_wheels
from smartcar_gym.envs.tasks.reach import GoalReachingTask
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.registration import ENTRY_POINT


@dataclass(frozen=True)
class PolicySettings:
    """The env settings a policy acts under: its observation and how actions become twists."""

    env_id: str
    wheel_joints: tuple[str, ...]
    task: GoalReachingTask
    max_linear: float
    max_angular: float
    rate_hz: float
    #: the controller configuration the policy was trained with (its odometry)
    controller_config: ArbotixConfig | None = None

    @property
    def observation(self) -> Observation:
        return declare_observation(self.wheel_joints, self.task)


def _defaults() -> dict[str, Any]:
    return {name: p.default for name, p in inspect.signature(SmartCarEnv).parameters.items()
            if p.default is not inspect.Parameter.empty}


def env_kwargs_of(env_id: str, env_kwargs: dict[str, Any] | None = None) -> dict[str, Any]:
    """All keyword arguments ``gym.make(env_id, **env_kwargs)`` gives ``SmartCarEnv``."""
    try:
        spec = gym.spec(env_id)
    except gym.error.Error as err:
        raise ValueError(f"unknown env {env_id!r}: {err}") from None
    if spec.entry_point != ENTRY_POINT:
        raise ValueError(f"{env_id} is not a SmartCarEnv (entry point {spec.entry_point!r}); "
                         "the ROS policy node drives SmartCarEnv policies")
    return {**_defaults(), **(spec.kwargs or {}), **(env_kwargs or {})}


def policy_settings(env_id: str, env_kwargs: dict[str, Any] | None = None) -> PolicySettings:
    """The settings of ``env_id`` made with ``env_kwargs`` (checked as the env checks them)."""
    kw = env_kwargs_of(env_id, env_kwargs)
    checks.check_keywords(env_id, kw, list(_defaults()), ValueError)
    model = kw.get("model")
    if not isinstance(model, RobotModel):
        model = load_model(checks.source("model", model, RobotModel),
                           package_path=kw.get("package_path"), wheels=kw.get("wheels"))
    config = kw.get("controller_config")
    if not isinstance(config, ArbotixConfig):
        config = load_controller_config(checks.source("controller_config", config,
                                                      ArbotixConfig))
    task = GoalReachingTask(
        goal_range_m=checks.number_pair("goal_range", kw["goal_range"]),
        goal_tolerance_m=checks.positive_number("goal_tolerance", kw["goal_tolerance"]),
        arena_half_size_m=checks.positive_number("arena_size", kw["arena_size"]) / 2.0,
        stop_speed_m_s=(None if kw["stop_speed"] is None
                        else checks.positive_number("stop_speed", kw["stop_speed"])),
    )
    return PolicySettings(
        env_id=env_id,
        wheel_joints=tuple(observed_wheels(model)),
        task=task,
        max_linear=checks.positive_number("max_linear", kw["max_linear"]),
        max_angular=checks.positive_number("max_angular", kw["max_angular"]),
        rate_hz=config.rate_hz,
        controller_config=config,
    )
