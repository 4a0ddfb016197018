"""SmartCarGoal-v0: SmartCar-v0 as a goal-conditioned env (``Dict`` observation, for HER)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from gymnasium import spaces

from smartcar_gym import checks
from smartcar_gym.envs.observation import Entry, Observation
from smartcar_gym.envs.robots.entries import robot_entries
from smartcar_gym.envs.robots.smartcar import Pose2D
from smartcar_gym.envs.smartcar_env import SmartCarEnv, previous_action_entry
from smartcar_gym.envs.tasks.goal import FLIPPED, REWARD_TYPES, GoalConditionedTask
from smartcar_gym.model import RobotModel

#: the rows of the ``observation`` key: the robot's state and the last action, no goal
GOAL_OBSERVATION_ORDER = (
    "odom_position", "odom_heading", "odom_linear", "odom_angular", "wheel_positions",
    "wheel_velocities", "previous_action",
)
KEYS = ("observation", "achieved_goal", "desired_goal")


def goal_entries(position_bound_m: float) -> tuple[Entry, Entry]:
    """The achieved goal (odometry position) and the desired goal, both in the ``odom`` frame."""
    b = position_bound_m
    return (
        Entry("achieved_goal", ("achieved_x_odom", "achieved_y_odom"), -b, b, "m",
              "achieved goal: odom position x, y", lambda r: (r.odometry.x, r.odometry.y),
              ("-2A", "2A")),
        Entry("desired_goal", ("goal_x_odom", "goal_y_odom"), -b, b, "m",
              "desired goal: the goal in the ``odom`` frame", lambda r: r.goal, ("-2A", "2A")),
    )


class GoalRewards:
    """``compute_reward`` / ``compute_terminated`` / ``compute_truncated`` of a goal-conditioned
    env (Gymnasium-Robotics' ``GoalEnv`` interface, what HER relabels with), from its
    ``goal_task``: one pair of goals or a batch."""

    goal_task: GoalConditionedTask

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                       info: Any) -> np.ndarray:
        """The reward for these goals (one pair or a batch); ``info`` is not used."""
        return self.goal_task.compute_reward(achieved_goal, desired_goal, info)

    def compute_terminated(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                           info: Any) -> np.ndarray:
        """True where the goal is reached (one pair or a batch)."""
        return self.goal_task.compute_terminated(achieved_goal, desired_goal, info)

    def compute_truncated(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                          info: Any) -> np.ndarray:
        """True where the car left the arena or flipped over (``info["flipped"]``)."""
        return self.goal_task.compute_truncated(achieved_goal, desired_goal, info)


class SmartCarGoalEnv(GoalRewards, SmartCarEnv):
    """## Description

    SmartCar-v0 as a goal-conditioned task, the interface of Gymnasium-Robotics' ``GoalEnv``
    that Stable-Baselines3's ``HerReplayBuffer`` needs: the same car, controller, actions and
    goals, but the observation is a ``Dict`` of ``observation`` (the robot's state),
    ``achieved_goal`` and ``desired_goal``, and the reward is
    ``env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)``, which also takes
    batches. Goals live in the ``odom`` frame and the achieved goal is the odometry position:
    the robot knows no ground truth, so "reached" means reached as far as its odometry can
    tell (``info["distance"]`` still gives the ground-truth distance to the goal).

    ## Action Space

    As SmartCar-v0: ``Box(-1, 1, (2,), float32)``, ``cmd_vel`` linear.x = a[0] * max_linear,
    angular.z = a[1] * max_angular; one step is one controller period (0.1 s).

    ## Observation Space

    ``Dict(observation=Box(..., (17,)), achieved_goal=Box(-2A, 2A, (2,)),
    desired_goal=Box(-2A, 2A, (2,)))``, float32, where A = ``arena_size / 2``;
    ``observation`` is:

    {observation_table}

    and the goals:

    {goal_table}

    ``env.unwrapped.observation_names`` maps each key to the names of its values.

    ## Rewards

    ``reward_type="sparse"`` (default): -1 per step, 0 once the odometry position is within
    ``goal_tolerance`` of the goal; ``"dense"``: minus that distance (m). Both are functions of
    the two goals only (``compute_reward(achieved_goal, desired_goal, info)`` ignores
    ``info``), so HER relabels them exactly; ``achieved_goal`` and ``desired_goal`` may be
    ``(2,)`` or ``(..., 2)``.

    ## Starting State

    As SmartCar-v0: the car at the origin facing +x (the odometry origin), the goal at a
    uniform distance in ``goal_range`` and bearing; ``reset(options={"goal": (x, y)})`` sets it.

    ## Episode End

    Terminated when the goal is reached (``compute_terminated``: odometry within
    ``goal_tolerance``). Truncated (``compute_truncated``) when the odometry position leaves the
    square arena or the car flips over (``info["flipped"]``), and by the ``TimeLimit`` (100
    steps = 10 s for SmartCarGoal-v0). ``info``: SmartCar-v0's keys (``is_success`` as
    ``compute_terminated`` says, ``distance`` ground truth) plus ``flipped``.

    ## Arguments

    SmartCar-v0's, plus ``reward_type`` ("sparse" or "dense", default "sparse").

    ## Vector envs

    ``gym.make_vec("SmartCarGoal-v0", num_envs=N, vectorization_mode="vector_entry_point")``:
    with ``engine="mujoco"`` or ``"planar"``, N cars in one ``SmartCarBatchVectorEnv`` with the
    goal-conditioned part (bit for bit N of this env, ``Dict`` observations of ``(N, ...)``
    arrays, ``compute_reward`` for HER); on
    pybullet, or with ``randomize`` or ``controller_mode="sim"``, N single envs stepped in a
    loop (``SmartCarLoopVectorEnv``); both with the smartcar vector conventions
    (docs/vector.md).

    ## Version History

    * v0 (0.4.0): ``engine="planar"`` and ``planar_params`` (SmartCar-v0's arguments;
      docs/planar.md).
    * v0 (0.3.0): ``engine="mujoco"`` (SmartCar-v0's argument; docs/engines.md).
    * v0 (0.2.0): initial version.
    """

    env_name = "SmartCarGoal-v0"

    def __init__(
        self,
        model: str | os.PathLike | RobotModel | None = None,
        *,
        reward_type: str = "sparse",
        **kwargs: Any,
    ) -> None:
        self.reward_type = checks.one_of("reward_type", reward_type, REWARD_TYPES)
        super().__init__(model, **kwargs)
        self.goal_task = GoalConditionedTask(self.task.goal_tolerance_m,
                                             self.task.arena_half_size_m, reward_type)
        self.observation_space = spaces.Dict({
            "observation": self.observation.space,
            "achieved_goal": self._achieved.space,
            "desired_goal": self._desired.space,
        })
        #: the names of the values of each key
        self.observation_names: dict[str, tuple[str, ...]] = {  # type: ignore[assignment]
            "observation": self.observation.names,
            "achieved_goal": self._achieved.names,
            "desired_goal": self._desired.names,
        }

    def _declare_observation(self) -> Observation:
        """The ``observation`` key's entries (the goals' are declared beside them)."""
        wheels = [w.joint for w in self.robot_model.left_wheels + self.robot_model.right_wheels]
        bound = 2 * self.task.arena_half_size_m
        achieved, desired = goal_entries(bound)
        self._achieved, self._desired = Observation([achieved]), Observation([desired])
        return Observation.compose(GOAL_OBSERVATION_ORDER, robot_entries(wheels, bound),
                                   [previous_action_entry()])

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict]:
        obs, info = super().reset(seed=seed, options=options)
        info["is_success"] = bool(self.goal_task.is_success(obs["achieved_goal"],
                                                            obs["desired_goal"]))
        return obs, info

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict]:
        obs, _, _, _, info = super().step(action)
        achieved, desired = obs["achieved_goal"], obs["desired_goal"]
        terminated = bool(self.compute_terminated(achieved, desired, info))
        info["is_success"] = terminated
        reward = float(self.compute_reward(achieved, desired, info))
        return obs, reward, terminated, bool(self.compute_truncated(achieved, desired, info)), info

    def _observe(self) -> dict[str, np.ndarray]:
        readings = self.readings()
        return {"observation": self.observation.build(readings),
                "achieved_goal": self._achieved.build(readings),
                "desired_goal": self._desired.build(readings)}

    def _info(self, pose: Pose2D, success: bool) -> dict[str, Any]:
        info = super()._info(pose, success)
        info[FLIPPED] = bool(self.task.is_flipped(pose.up_z))
        return info

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        for key in ("_achieved", "_desired"):  # lambdas; __setstate__ declares them again
            state.pop(key, None)
        return state


def _doc_tables() -> tuple[str, str]:
    """The docstring's tables (the shipped car's four wheels)."""
    bound = 5.0
    observation = Observation.compose(
        GOAL_OBSERVATION_ORDER, robot_entries(["lf", "lb", "rf", "rb"], bound),
        [previous_action_entry()])
    goals = Observation(goal_entries(bound))
    return (observation.table().replace("\n", "\n    "), goals.table().replace("\n", "\n    "))


_tables = _doc_tables()
SmartCarGoalEnv.__doc__ = (SmartCarGoalEnv.__doc__.replace("{observation_table}", _tables[0])
                           .replace("{goal_table}", _tables[1]))
