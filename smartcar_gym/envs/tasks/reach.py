"""Reaching a goal on the ground: SmartCar-v0's task (and SmartCarSim-v0's, SmartCarArrive-v0's).

``ReachTask`` draws a goal per episode, rewards progress towards it and ends the episode on
reaching it, flipping over or leaving the arena, for any number of cars.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from smartcar_gym import checks
from smartcar_gym.envs.exact import exact_hypot, planar_norm, wrap_angles
from smartcar_gym.envs.observation import Entry, Observation
from smartcar_gym.envs.robots.entries import (
    heading,
    previous_action_entry,
    robot_columns,
    robot_entries,
)
from smartcar_gym.envs.state import copied, split
from smartcar_gym.envs.tasks.base import Cars, Score, Task, one_or_many

FLIP_UP_Z = 0.5  # base_link's z axis tilted more than 60 degrees: flipped over
#: the rows of SmartCar-v0's observation, in order (entries come from robot, task and env)
OBSERVATION_ORDER = (
    "odom_position", "odom_heading", "odom_linear", "odom_angular", "wheel_positions",
    "wheel_velocities", "goal_base", "goal_distance", "previous_action", "goal_odom",
)


def goal_columns(pose: Any, cos: Any, sin: Any, goal: Any) -> dict[str, Any]:
    """The goal's columns (``goal_base``, ``goal_distance``, ``goal_odom``) seen from ``pose``
    (the odometry's, (N, k) or one car's row; ``cos``, ``sin``: ``heading`` of it), the goals
    ``goal`` (N, 2) or one car's."""
    x, y = split(pose)[:2]
    goal_x, goal_y = split(goal)
    gx, gy = goal_x - x, goal_y - y
    return {"goal_base": (cos * gx + sin * gy, -sin * gx + cos * gy),
            "goal_distance": (np.hypot(gx, gy),), "goal_odom": (goal_x, goal_y)}


def pose_columns(poses: np.ndarray, goal: np.ndarray) -> dict[str, Any]:
    """The columns that read the car's pose (``odom_position``, ``odom_heading`` and the
    goal's) from ``poses`` (N, 3: x, y, yaw) in place of the odometry's, the goals ``goal``
    (N, 2) in the same frame: a localized car's."""
    cos, sin = heading(poses)
    return {"odom_position": (poses[:, 0], poses[:, 1]), "odom_heading": (cos, sin),
            **goal_columns(poses, cos, sin, goal)}


class ReachTask(Task):
    """## Description

    SmartCar-v0's task: drive base_link to within ``goal_tolerance`` of a goal on the ground,
    drawn 0.5-1.5 m away, on odometry and the wheel joint states alone (the observation holds
    no ground truth).

    ## Observation Space

    ``Box(low, high, (21,), float32)`` with finite bounds (values are clipped into them):

    {observation_table}

    where A = ``arena_size / 2``. Wheels are listed left then right, front then back, as the
    model's wheels are found (``env.unwrapped.observation_names`` names every entry, e.g.
    ``left_back_wheel_joint.velocity``); ``info`` has nothing the observation needs.

    ## Rewards

    ``10 * (d_prev - d) - 0.01 - 0.01 * |a|^2``, plus ``+10`` on reaching the goal and ``-10``
    on flipping over or leaving the arena, where d is the ground-truth distance (m) from
    base_link to the goal. With ``stop_speed`` the +10 needs the car at rest (below), each
    step within ``goal_tolerance`` also costs ``1.0 * |v|`` (the true speed, m/s) and each
    step ``20 * (e - e_prev)``, e the odometry's distance (m) from the truth.

    ## Starting State

    The car at the origin facing +x, left to settle for 0.1 s, and the controller starts: the
    start pose is the odometry origin. The goal is drawn with the env's ``np_random`` at a
    uniform distance in ``goal_range`` and a uniform bearing. ``reset(options={"goal": (x,
    y)})`` sets it instead (the only option). With ``randomize``, the robot, the ground and the
    true start pose are then drawn from ``np_random`` (after the goal: the goals are the
    nominal env's for the same seed).

    ## Episode End

    Terminated when the ground-truth distance is under ``goal_tolerance`` (success; with
    ``stop_speed`` the odometry's distance too, and the true speed of base_link under
    ``stop_speed``: at rest), when the car flips over (base_link z axis tilted more than 60
    degrees) or when it leaves the square arena. Truncated by the ``TimeLimit`` (200 steps =
    20 s for SmartCar-v0).

    ``info``: ``is_success`` (bool), ``distance`` (ground truth, m), ``pose`` (ground-truth
    x, y, yaw), ``odom_pose`` (odometry x, y, yaw), ``odom_error`` (m between the two), and
    with ``randomize`` ``randomization``: this episode's draw (factor -> value, ``noise_seed``).

    ## Arguments

    The env's (``SmartCarEnv``: the car, its controller, the engine), and the task's:

    | kwarg             | default        | meaning                                              |
    |-------------------|----------------|------------------------------------------------------|
    | goal_range        | (0.5, 1.5)     | min, max goal distance from the start (m)            |
    | goal_tolerance    | 0.1            | success radius (m)                                   |
    | arena_size        | 5.0            | side of the square arena centred on the start (m)    |
    | stop_speed        | None           | m/s: success only at rest (speed under this) inside  |
    |                   |                | the tolerance; None: on entering it (docs/ros.md)    |

    SmartCarSim-v0 is this task with ``controller_mode="sim"``; SmartCarArrive-v0 with goals
    0.3-2 m away, ``stop_speed=0.01`` and the calibrated controller YAML.
    """

    option_keys = ("goal",)
    #: per step: the progress's weight, the time and action costs, the bonus and penalty
    progress_weight = 10.0
    success_bonus = 10.0
    failure_penalty = 10.0
    time_cost = 0.01
    action_cost = 0.01
    #: with ``stop_speed``: the cost of speed near the goal, and of the odometry's drift
    speed_cost = 1.0
    odometry_cost = 20.0

    def __init__(self, goal_range: tuple[float, float] = (0.5, 1.5),
                 goal_tolerance: float = 0.1, arena_size: float = 5.0,
                 stop_speed: float | None = None) -> None:
        self.goal_range_m = checks.number_pair("goal_range", goal_range)
        self.goal_tolerance_m = checks.positive_number("goal_tolerance", goal_tolerance)
        self.arena_half_size_m = checks.positive_number("arena_size", arena_size) / 2.0
        self.stop_speed_m_s = (None if stop_speed is None
                               else checks.positive_number("stop_speed", stop_speed))
        lo, hi = self.goal_range_m
        if not (0.0 <= lo <= hi and math.isfinite(hi)):
            raise ValueError("goal_range must be (min, max) metres with 0 <= min <= max, "
                             f"got {self.goal_range_m}")
        if not hi < self.arena_half_size_m:
            raise ValueError(f"goal_range max ({hi} m) must lie inside the arena (half size "
                             f"{self.arena_half_size_m} m): raise arena_size or lower "
                             "goal_range")
        if not self.goal_tolerance_m < self.arena_half_size_m:
            raise ValueError(f"goal_tolerance ({self.goal_tolerance_m} m) must be smaller than "
                             f"the arena (half size {self.arena_half_size_m} m): every position "
                             "would be a success")

    def __eq__(self, other: object) -> bool:
        """Two reaching tasks are equal when they score alike: the same class, goals, arena,
        weights and (bound) wheels; their cars' numbers do not count."""
        return type(other) is type(self) and self._settings() == other._settings()

    __hash__ = None  # type: ignore[assignment]  (a task holds arrays that change)

    def _settings(self) -> tuple:
        car = self.__dict__.get("car")
        return (self.goal_range_m, self.goal_tolerance_m, self.arena_half_size_m,
                self.stop_speed_m_s, self.progress_weight, self.success_bonus,
                self.failure_penalty, self.time_cost, self.action_cost, self.speed_cost,
                self.odometry_cost, None if car is None else tuple(car.wheel_joints))

    @property
    def needs_speed(self) -> bool:  # type: ignore[override]
        """``stop_speed``'s success needs the true speed."""
        return self.stop_speed_m_s is not None

    @staticmethod
    def limits(kwargs: Any) -> str | None:
        if kwargs.get("stop_speed") is not None:
            return "stop_speed (the true speed, which a car batch does not read)"
        return None

    # -- observation ---------------------------------------------------------------------------
    def declare(self) -> Observation:
        return self.compose(OBSERVATION_ORDER)

    def compose(self, order: Sequence[str], *more: Sequence[Entry],
                wheel_joints: Sequence[str] | None = None) -> Observation:
        """The entries of the robot (its ``wheel_joints``: the bound car's by default), the
        goal, the previous action and ``more``, in ``order``."""
        bound = 2 * self.arena_half_size_m
        wheels = self.car.wheel_joints if wheel_joints is None else wheel_joints
        return Observation.compose(order, robot_entries(wheels, bound), self.goal_entries(),
                                   [previous_action_entry()], *more)

    def goal_entries(self) -> list[Entry]:
        """The goal as the robot sees it through odometry (A = ``arena_half_size_m``)."""
        a = self.arena_half_size_m
        return [
            Entry("goal_base", ("goal_x_base", "goal_y_base"), -4 * a, 4 * a, "m",
                  "goal in the odometry base_link frame (ahead, left)", ("-4A", "4A")),
            Entry("goal_distance", ("goal_distance",), 0.0, 4 * a, "m",
                  "goal distance from the odometry pose", ("0", "4A")),
            Entry("goal_odom", ("goal_x_odom", "goal_y_odom"), -2 * a, 2 * a, "m",
                  "goal in the ``odom`` frame (as a goal is given in ROS)", ("-2A", "2A")),
        ]

    @one_or_many
    def columns(self, cars: Cars) -> dict[str, Any]:
        state = cars.state
        odometry = cars.values(state.odometry)
        cos, sin = heading(odometry)
        return {**robot_columns(cars, cos, sin),
                **goal_columns(odometry, cos, sin, cars.values(state.goal))}

    # -- cars ----------------------------------------------------------------------------------
    def attach(self, num: int) -> None:
        super().attach(num)
        #: the last step's reward by term (name -> per car, or one number for every car);
        #: the reward is their sum, in this order (a recording shows each)
        self.terms: dict[str, Any] = {}
        #: each car's ground-truth distance to its goal (m), as of the last step
        self.distance = np.zeros(num)
        #: each car's odometry error (m; ``stop_speed``), as of the last step
        self.odometry_error = np.zeros(num)

    # -- reset ---------------------------------------------------------------------------------
    def check_option(self, key: str, value: Any, vector: bool) -> list[Any]:
        if key != "goal":
            return super().check_option(key, value, vector)
        if not vector:
            return [self.check_goal(value)]
        goal = np.asarray(value, dtype=float)
        if goal.shape not in ((2,), (self.num, 2)):
            raise ValueError(f"options['goal'] must be (x, y) or an ({self.num}, 2) array, "
                             f"got shape {goal.shape}")
        rows = [self.check_goal(g) for g in goal.reshape(-1, 2)]
        return rows if len(rows) == self.num else rows * self.num

    def check_goal(self, value: object) -> np.ndarray:
        """A user's goal (``reset(options={"goal": ...})``): a finite (x, y) in the arena."""
        expected = f"options['goal'] must be a finite (x, y) pair, got {value!r}"
        try:
            goal = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(expected) from None
        if goal.shape != (2,) or not np.all(np.isfinite(goal)):
            raise ValueError(expected)
        half = self.arena_half_size_m
        if np.any(np.abs(goal) > half):
            raise ValueError(f"options['goal'] {goal.tolist()} lies outside the arena (|x|, "
                             f"|y| <= {half} m): raise arena_size")
        return goal

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        """A goal at a uniform distance in ``goal_range_m``, uniform bearing, from the
        origin."""
        distance = rng.uniform(*self.goal_range_m)
        bearing = rng.uniform(-math.pi, math.pi)
        return np.zeros(2) + distance * np.array([math.cos(bearing), math.sin(bearing)])

    def start(self, cars: Cars, idx: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """Each listed car's goal: given, or drawn from its generator."""
        goal = cars.state.goal
        for i in idx.tolist():
            given = options[i].get("goal")
            goal[i] = given if given is not None else self.sample_goal(cars.rng(i))

    def begin(self, cars: Cars, idx: np.ndarray) -> None:
        state = cars.state
        pose, goal = state.pose[idx], state.goal[idx]
        self.distance[idx] = planar_norm(pose[:, 0] - goal[:, 0], pose[:, 1] - goal[:, 1])
        if self.stop_speed_m_s is not None:
            odometry, pose = state.odometry[idx], state.pose[idx]
            self.odometry_error[idx] = exact_hypot(odometry[:, 0] - pose[:, 0],
                                                   odometry[:, 1] - pose[:, 1])

    # -- step ----------------------------------------------------------------------------------
    @one_or_many
    def score(self, cars: Cars, action: np.ndarray) -> Score:
        """Progress, time and action costs, the success bonus and the failure penalty (and
        ``stop_speed``'s arrival terms) from each car's true position."""
        state, values = cars.state, cars.values
        x, y, _ = split(values(state.pose))
        goal_x, goal_y = split(values(state.goal))
        distance = planar_norm(x - goal_x, y - goal_y)
        success = distance < self.goal_tolerance_m
        arrival = None
        if self.stop_speed_m_s is not None:
            success, arrival = self._arrival(cars, x, y, success)
        half = self.arena_half_size_m
        failure = (values(state.up_z) < FLIP_UP_Z) | (abs(x) > half) | (abs(y) > half)
        linear, angular = split(action)
        self.terms = {"progress": self.progress_weight * (values(self.distance) - distance),
                      "time": -self.time_cost,
                      "action": -(self.action_cost * (linear * linear + angular * angular)),
                      "success": self.success_bonus * success,
                      "failure": -(self.failure_penalty * failure)}
        if arrival is not None:
            self.terms["arrival"] = -arrival
        self.distance[...] = distance
        return self.reward(), success, failure

    def reward(self) -> np.ndarray:
        """The sum of the last step's ``terms``, in their order (each car's reward)."""
        values = iter(self.terms.values())
        total = next(values)
        for term in values:
            total = total + term
        return total

    def _arrival(self, cars: Cars, px: np.ndarray, py: np.ndarray,
                 success: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``stop_speed``: success at rest and by odometry too, and the arrival cost."""
        state, values = cars.state, cars.values
        ox, oy = split(values(state.odometry))[:2]
        goal_x, goal_y = split(values(state.goal))
        odometry_error = exact_hypot(ox - px, oy - py)
        inside = success & (exact_hypot(ox - goal_x, oy - goal_y) < self.goal_tolerance_m)
        speed = abs(values(state.speed))
        arrival = (self.speed_cost * speed * inside
                   + self.odometry_cost * (odometry_error - values(self.odometry_error)))
        self.odometry_error[...] = odometry_error
        return inside & (speed < self.stop_speed_m_s), arrival

    def is_success(self, distance: np.ndarray | float,
                   speed: np.ndarray | float = 0.0) -> np.ndarray:
        """True where the distance to the goal is under the tolerance (and, with
        ``stop_speed``, the speed (m/s) under it): the ROS node's judge."""
        inside = np.asarray(distance) < self.goal_tolerance_m
        if self.stop_speed_m_s is None:
            return inside
        return inside & (np.abs(np.asarray(speed)) < self.stop_speed_m_s)

    @one_or_many
    def info(self, cars: Cars, success: np.ndarray) -> dict[str, np.ndarray]:
        """Success, the distance, the true and odometry poses and their gap."""
        state, values = cars.state, cars.values
        odometry, pose = values(state.odometry), values(state.pose)
        ox, oy, theta = split(odometry)[:3]
        px, py, _ = split(pose)
        odom_pose = odometry[..., :3].copy()
        odom_pose[..., 2] = wrap_angles(theta)
        return {
            "is_success": copied(success),
            "distance": copied(values(self.distance)),
            "pose": pose.copy(),
            "odom_pose": odom_pose,
            "odom_error": planar_norm(ox - px, oy - py),
        }


#: the shipped car's wheels, as the cards' tables name them
CARD_WHEELS = ("lf", "lb", "rf", "rb")


def card_table(observation: Observation) -> str:
    """An observation's table as a card (a docstring) shows it, indented."""
    return observation.table().replace("\n", "\n    ")


ReachTask.__doc__ = ReachTask.__doc__.replace(
    "{observation_table}", card_table(ReachTask().compose(OBSERVATION_ORDER,
                                                          wheel_joints=CARD_WHEELS)))
