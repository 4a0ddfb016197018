"""What the policy node needs of the env a policy was trained in, without making the env.

The env's keyword arguments (its registration's, then the run's ``env_kwargs``) give the robot
model (for the wheel joints, in the env's order), the task (the reaching task: arena,
tolerance), the action scale and the controller's rate; defaults are read from the env's and
the task's own signatures, so there is no second copy of them. ``task`` is the env's own
task, bound to the car, for one car: the node builds its observation with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym

from smartcar_gym import checks
from smartcar_gym.controller import ArbotixConfig, load_controller_config
from smartcar_gym.envs.observation import Observation
from smartcar_gym.envs.settings import own_keywords
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.tasks.base import CarSettings
from smartcar_gym.envs.tasks.reach import ReachTask
from smartcar_gym.envs.tasks.registry import ENTRY_POINT
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.sim.engines import engine_kwargs

#: the task the node drives: reaching a goal on the plane
TASK = "reach"


@dataclass(frozen=True)
class PolicySettings:
    """The env settings a policy acts under: its observation and how actions become twists."""

    env_id: str
    wheel_joints: tuple[str, ...]
    task: ReachTask
    max_linear: float
    max_angular: float
    rate_hz: float
    #: the controller configuration the policy was trained with (its odometry)
    controller_config: ArbotixConfig | None = None

    @property
    def observation(self) -> Observation:
        return self.task.observation()


def _defaults() -> dict[str, Any]:
    """The env's and the reaching task's keywords, with their defaults."""
    return {**own_keywords(SmartCarEnv.__init__), **own_keywords(ReachTask.__init__)}


def env_kwargs_of(env_id: str, env_kwargs: dict[str, Any] | None = None) -> dict[str, Any]:
    """All keyword arguments ``gym.make(env_id, **env_kwargs)`` gives ``SmartCarEnv``."""
    try:
        spec = gym.spec(env_id)
    except gym.error.Error as err:
        raise ValueError(f"unknown env {env_id!r}: {err}") from None
    if spec.entry_point != ENTRY_POINT or (spec.kwargs or {}).get("task") != TASK:
        raise ValueError(f"{env_id} is not a goal-reaching SmartCarEnv (entry point "
                         f"{spec.entry_point!r}, task {(spec.kwargs or {}).get('task')!r}); the "
                         f"ROS policy node drives the {TASK!r} task's policies")
    return {**_defaults(), **(spec.kwargs or {}), **(env_kwargs or {})}


def policy_settings(env_id: str, env_kwargs: dict[str, Any] | None = None) -> PolicySettings:
    """The settings of ``env_id`` made with ``env_kwargs`` (checked as the env checks them)."""
    kw = env_kwargs_of(env_id, env_kwargs)
    checks.check_keywords(env_id, [k for k in kw if k != "task"],
                          [*_defaults(), *engine_kwargs()], ValueError)
    model = kw.get("model")
    if not isinstance(model, RobotModel):
        model = load_model(checks.source("model", model, RobotModel),
                           mappings=kw.get("model_args") or None,
                           package_path=kw.get("package_path"), wheels=kw.get("wheels"))
    config = kw.get("controller_config")
    if not isinstance(config, ArbotixConfig):
        config = load_controller_config(checks.source("controller_config", config,
                                                      ArbotixConfig))
    task = ReachTask(goal_range=kw["goal_range"], goal_tolerance=kw["goal_tolerance"],
                     arena_size=kw["arena_size"], stop_speed=kw["stop_speed"])
    max_linear = checks.positive_number("max_linear", kw["max_linear"])
    max_angular = checks.positive_number("max_angular", kw["max_angular"])
    car = CarSettings(model, config, kw.get("controller_mode") or "hardware", max_linear,
                      max_angular, kw["wheel_contact"], kw.get("engine") or "pybullet")
    task.bind(car)
    task.attach(1)
    return PolicySettings(env_id=env_id, wheel_joints=tuple(car.wheel_joints), task=task,
                          max_linear=max_linear, max_angular=max_angular,
                          rate_hz=config.rate_hz, controller_config=config)
