"""Goal-conditioned reaching (SmartCarGoal-v0): a ``Dict`` observation and a reward of the goals.

What Gymnasium-Robotics' ``GoalEnv`` and Stable-Baselines3's ``HerReplayBuffer`` expect:
``compute_reward``, ``compute_terminated`` and ``compute_truncated`` take the achieved and
desired goals of one step (``(2,)``) or of a batch (``(..., 2)``), so HER can recompute rewards
for goals it substitutes. Goals are positions in the ``odom`` frame: the achieved goal is
where the robot's odometry says it is.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from smartcar_gym import checks
from smartcar_gym.envs.observation import Entry, Observation
from smartcar_gym.envs.robots.entries import (
    heading,
    previous_action_entry,
    robot_columns,
    robot_entries,
)
from smartcar_gym.envs.tasks.base import Cars, Score
from smartcar_gym.envs.tasks.reach import CARD_WHEELS, FLIP_UP_Z, ReachTask, card_table

REWARD_TYPES = ("sparse", "dense")
FLIPPED = "flipped"  # the info key that says the car is on its side or roof
#: the rows of the ``observation`` key: the robot's state and the last action, no goal
GOAL_OBSERVATION_ORDER = (
    "odom_position", "odom_heading", "odom_linear", "odom_angular", "wheel_positions",
    "wheel_velocities", "previous_action",
)
KEYS = ("observation", "achieved_goal", "desired_goal")


def info_flags(info: Any, key: str, shape: tuple[int, ...]) -> np.ndarray:
    """``info[key]`` (False when absent) for one info dict or a batch of them, as ``shape``."""
    if info is None:
        return np.zeros(shape, dtype=bool)
    if isinstance(info, Mapping):
        return np.full(shape, bool(info.get(key, False)))
    flags = [bool(i.get(key, False)) if isinstance(i, Mapping) else False
             for i in np.asarray(info, dtype=object).reshape(-1)]
    return np.asarray(flags, dtype=bool).reshape(shape)


def goal_entries(position_bound_m: float) -> tuple[Entry, Entry]:
    """The achieved goal (odometry position) and the desired goal, both in the ``odom`` frame."""
    b = position_bound_m
    return (
        Entry("achieved_goal", ("achieved_x_odom", "achieved_y_odom"), -b, b, "m",
              "achieved goal: odom position x, y", ("-2A", "2A")),
        Entry("desired_goal", ("goal_x_odom", "goal_y_odom"), -b, b, "m",
              "desired goal: the goal in the ``odom`` frame", ("-2A", "2A")),
    )


class GoalTask(ReachTask):
    """## Description

    SmartCar-v0 as a goal-conditioned task, the interface of Gymnasium-Robotics' ``GoalEnv``
    that Stable-Baselines3's ``HerReplayBuffer`` needs: the same car, controller, actions and
    goals, but the observation is a ``Dict`` of ``observation`` (the robot's state),
    ``achieved_goal`` and ``desired_goal``, and the reward is
    ``env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)``, which also takes
    batches. Goals live in the ``odom`` frame and the achieved goal is the odometry position:
    the robot knows no ground truth, so "reached" means reached as far as its odometry can
    tell (``info["distance"]`` still gives the ground-truth distance to the goal).

    ## Observation Space

    ``Dict(observation=Box(..., (16,)), achieved_goal=Box(-2A, 2A, (2,)),
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
    with ``engine="mujoco"`` or ``"planar"``, N cars in one ``SmartCarBatchVectorEnv`` (bit for
    bit N of this env, ``Dict`` observations of ``(N, ...)`` arrays, ``compute_reward`` for
    HER); on pybullet, or with ``randomize`` or ``controller_mode="sim"``, N single envs
    stepped in a loop (``SmartCarLoopVectorEnv``); both with the smartcar vector conventions
    (docs/vector.md).

    ## Version History

    * v0 (0.5.0): the task written once for the single and the batched envs (``GoalTask``).
    * v0 (0.4.0): ``engine="planar"`` and ``planar_params`` (SmartCar-v0's arguments;
      docs/planar.md).
    * v0 (0.3.0): ``engine="mujoco"`` (SmartCar-v0's argument; docs/engines.md).
    * v0 (0.2.0): initial version.
    """

    exports = ("compute_reward", "compute_terminated", "compute_truncated", "reward_type")

    def __init__(self, reward_type: str = "sparse", goal_range: tuple[float, float] = (0.5, 1.5),
                 goal_tolerance: float = 0.1, arena_size: float = 5.0,
                 stop_speed: float | None = None) -> None:
        self.reward_type = checks.one_of("reward_type", reward_type, REWARD_TYPES)
        super().__init__(goal_range, goal_tolerance, arena_size, stop_speed)

    def declare(self) -> dict[str, Observation]:  # type: ignore[override]
        bound = 2 * self.arena_half_size_m
        achieved, desired = goal_entries(bound)
        return {"observation": Observation.compose(
                    GOAL_OBSERVATION_ORDER, robot_entries(self.car.wheel_joints, bound),
                    [previous_action_entry()]),
                "achieved_goal": Observation([achieved]),
                "desired_goal": Observation([desired])}

    def attach(self, num: int) -> None:
        super().attach(num)
        self._flipped = np.zeros(num, dtype=bool)
        self._truncate = np.zeros(num, dtype=bool)
        #: the cars just reset report their reset's success (a goal may start within reach)
        self._just_reset = np.zeros(num, dtype=bool)
        self._reset_success = np.zeros(num, dtype=bool)

    # -- the goals' functions (HER's) ----------------------------------------------------------
    @staticmethod
    def goal_distance(achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """Euclidean distance (m) between ``(..., 2)`` goals."""
        return np.linalg.norm(np.asarray(achieved, dtype=np.float64)
                              - np.asarray(desired, dtype=np.float64), axis=-1)

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                       info: Any) -> np.ndarray:
        """-1 / 0 (sparse) or minus the distance (dense), per goal pair; ``info`` unused."""
        if self.reward_type == "sparse":
            return -(~self.compute_terminated(achieved_goal, desired_goal, info)).astype(
                np.float64)
        return -self.goal_distance(achieved_goal, desired_goal)

    def compute_terminated(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                           info: Any) -> np.ndarray:
        """True where the achieved goal is within the tolerance of the desired one."""
        return self.goal_distance(achieved_goal, desired_goal) < self.goal_tolerance_m

    def compute_truncated(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                          info: Any) -> np.ndarray:
        """True where the achieved goal left the arena or the car flipped over
        (``info["flipped"]``)."""
        outside = np.any(np.abs(np.asarray(achieved_goal)) > self.arena_half_size_m, axis=-1)
        return outside | info_flags(info, FLIPPED, np.shape(outside))

    # -- the cars ------------------------------------------------------------------------------
    @staticmethod
    def _goal_columns(state: Any) -> dict[str, Any]:
        """The achieved (the odometry's position) and desired goals' columns."""
        return {"achieved_goal": (state.odometry[:, 0], state.odometry[:, 1]),
                "desired_goal": (state.goal[:, 0], state.goal[:, 1])}

    def _goals(self, cars: Cars) -> tuple[np.ndarray, np.ndarray]:
        """Every car's observed achieved and desired goals ((N, 2) float32), as ``observe``
        gives them."""
        columns, observation = self._goal_columns(cars.state), self.observation()
        return (observation["achieved_goal"].build(columns),
                observation["desired_goal"].build(columns))

    def begin(self, cars: Cars, idx: np.ndarray) -> None:
        super().begin(cars, idx)
        achieved, desired = self._goals(cars)
        self._reset_success[idx] = self.compute_terminated(achieved, desired, None)[idx]
        self._flipped[idx] = cars.state.up_z[idx] < FLIP_UP_Z
        self._just_reset[idx] = True

    def score(self, cars: Cars, action: np.ndarray) -> Score:
        """The goal-conditioned reward and ends from the observed goals (reaching the goal's
        are computed, as its distance is reported, and not used)."""
        super().score(cars, action)
        self._just_reset[:] = False
        achieved, desired = self._goals(cars)
        self._flipped = cars.state.up_z < FLIP_UP_Z
        success = self.compute_terminated(achieved, desired, None)
        self._truncate = self.compute_truncated(achieved, desired, None) | self._flipped
        reward = self.compute_reward(achieved, desired, None)
        self.terms = {"goal": reward}
        return reward, success, np.zeros(self.num, dtype=bool)

    def truncated(self, cars: Cars) -> np.ndarray:
        return self._truncate.copy()

    def observe(self, cars: Cars) -> dict[str, np.ndarray]:
        state = cars.state
        columns = {**robot_columns(cars, *heading(state.odometry)),
                   **self._goal_columns(state)}
        return {key: o.build(columns) for key, o in self.observation().items()}

    def info(self, cars: Cars, success: np.ndarray) -> dict[str, np.ndarray]:
        return {**super().info(cars, success),
                "is_success": np.where(self._just_reset, self._reset_success, success),
                FLIPPED: self._flipped.copy()}


GoalTask.__doc__ = GoalTask.__doc__.replace("{observation_table}", card_table(Observation.compose(
    GOAL_OBSERVATION_ORDER, robot_entries(CARD_WHEELS, 5.0), [previous_action_entry()]))
).replace("{goal_table}", card_table(Observation(goal_entries(5.0))))
