"""Goal reaching: goal sampling, success, failure and reward as pure functions of arrays.

The functions take ``(..., 2)`` positions, so they work on one state or a batch of them. The task
also declares its part of the observation: the goal as the robot sees it through odometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from smartcar_gym.envs.observation import Entry, Readings

FLIP_UP_Z = 0.5  # base_link's z axis tilted more than 60 degrees: flipped over


def _goal_in_base(r: Readings) -> tuple[float, float, float]:
    odom = r.odometry
    dx, dy = r.goal[0] - odom.x, r.goal[1] - odom.y
    c, s = math.cos(odom.theta), math.sin(odom.theta)
    return c * dx + s * dy, -s * dx + c * dy, math.hypot(dx, dy)


@dataclass(frozen=True)
class Outcome:
    """What one step did for the task: reward, success, failure and the new distance (m)."""

    reward: float
    success: bool
    failure: bool
    distance: float
    odometry_error: float = 0.0  # m between odometry and truth (with ``stop_speed_m_s``)


@dataclass(frozen=True)
class GoalReachingTask:
    """Drive base_link to within ``goal_tolerance_m`` of a goal on the ground.

    Reward per step: ``progress_weight`` x (metres the robot got closer to the goal)
    - ``time_cost`` - ``action_cost`` x |action|^2, plus ``success_bonus`` on reaching the goal
    and minus ``failure_penalty`` on flipping over or leaving the arena.

    With ``stop_speed_m_s`` (None: not asked) the goal is reached only at rest and where the
    odometry says so too: within the tolerance in ground truth and by odometry, the base's true
    speed under ``stop_speed_m_s``. While within it each step also costs ``speed_cost`` x speed
    (m/s), so that stopping there pays before the bonus is ever found, and every step costs
    ``odometry_cost`` x (metres the odometry drifted further from the truth): an episode pays
    ``odometry_cost`` x its final odometry error, so that it is driven the way the odometry
    follows (the car turns in place with little error, on arcs its wheels slip).
    """

    goal_range_m: tuple[float, float] = (0.5, 1.5)
    goal_tolerance_m: float = 0.1
    arena_half_size_m: float = 2.5
    progress_weight: float = 10.0
    success_bonus: float = 10.0
    failure_penalty: float = 10.0
    time_cost: float = 0.01
    action_cost: float = 0.01
    stop_speed_m_s: float | None = None
    speed_cost: float = 1.0
    odometry_cost: float = 20.0

    def __post_init__(self) -> None:
        if self.stop_speed_m_s is not None and not (
                math.isfinite(self.stop_speed_m_s) and self.stop_speed_m_s > 0):
            raise ValueError(f"stop_speed must be None or a speed > 0 m/s, got "
                             f"{self.stop_speed_m_s!r}")
        lo, hi = self.goal_range_m
        if not (0.0 <= lo <= hi and math.isfinite(hi)):
            raise ValueError(
                "goal_range must be (min, max) metres with 0 <= min <= max, "
                f"got {self.goal_range_m}"
            )
        if not self.goal_tolerance_m > 0:
            raise ValueError(f"goal_tolerance must be > 0 m, got {self.goal_tolerance_m}")
        if not hi < self.arena_half_size_m:
            raise ValueError(
                f"goal_range max ({hi} m) must lie inside the arena (half size "
                f"{self.arena_half_size_m} m): raise arena_size or lower goal_range"
            )
        if not self.goal_tolerance_m < self.arena_half_size_m:
            raise ValueError(
                f"goal_tolerance ({self.goal_tolerance_m} m) must be smaller than the arena "
                f"(half size {self.arena_half_size_m} m): every position would be a success"
            )

    # -- goals ---------------------------------------------------------------------------------
    def sample_goal(self, rng: np.random.Generator, origin: np.ndarray) -> np.ndarray:
        """A goal at a uniform distance in ``goal_range_m``, uniform bearing, from ``origin``."""
        distance = rng.uniform(*self.goal_range_m)
        bearing = rng.uniform(-math.pi, math.pi)
        return np.asarray(origin, dtype=float) + distance * np.array(
            [math.cos(bearing), math.sin(bearing)]
        )

    def check_goal(self, value: object) -> np.ndarray:
        """A user's goal (``reset(options={"goal": ...})``): a finite (x, y) in the arena."""
        expected = f"options['goal'] must be a finite (x, y) pair, got {value!r}"
        try:
            goal = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(expected) from None
        if goal.shape != (2,) or not np.all(np.isfinite(goal)):
            raise ValueError(expected)
        if self.is_outside(goal):
            raise ValueError(
                f"options['goal'] {goal.tolist()} lies outside the arena (|x|, |y| <= "
                f"{self.arena_half_size_m} m): raise arena_size"
            )
        return goal

    # -- pure functions ------------------------------------------------------------------------
    @staticmethod
    def distance(position: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Euclidean distance (m) between ``(..., 2)`` positions and goals."""
        d = np.asarray(position, dtype=float) - np.asarray(goal, dtype=float)
        return np.sqrt(np.add.reduce(d * d, axis=-1))  # np.linalg.norm's own sum, without it

    def is_success(self, distance: np.ndarray, speed: np.ndarray | float = 0.0) -> np.ndarray:
        """True where the distance to the goal is under the tolerance (and, with
        ``stop_speed_m_s``, the speed (m/s) under it)."""
        inside = np.asarray(distance) < self.goal_tolerance_m
        if self.stop_speed_m_s is None:
            return inside
        return inside & (np.abs(np.asarray(speed)) < self.stop_speed_m_s)

    def is_outside(self, position: np.ndarray) -> np.ndarray:
        """True where a ``(..., 2)`` position has left the square arena."""
        return np.any(np.abs(np.asarray(position)) > self.arena_half_size_m, axis=-1)

    @staticmethod
    def is_flipped(up_z: np.ndarray) -> np.ndarray:
        """True where base_link's z axis has tilted more than 60 degrees (``up_z < 0.5``)."""
        return np.asarray(up_z) < FLIP_UP_Z

    def is_failure(self, position: np.ndarray, up_z: np.ndarray) -> np.ndarray:
        """True where the robot flipped over or left the arena."""
        return self.is_flipped(up_z) | self.is_outside(position)

    def reward(
        self,
        previous_distance: np.ndarray,
        distance: np.ndarray,
        action: np.ndarray,
        success: np.ndarray,
        failure: np.ndarray,
    ) -> np.ndarray:
        """Dense reward: progress, minus time and action costs, plus success/failure terms
        (the arrival terms of ``stop_speed_m_s`` are ``evaluate``'s)."""
        action = np.asarray(action, dtype=float)
        return (
            self.progress_weight * (np.asarray(previous_distance) - np.asarray(distance))
            - self.time_cost
            - self.action_cost * np.sum(action * action, axis=-1)
            + self.success_bonus * np.asarray(success, dtype=float)
            - self.failure_penalty * np.asarray(failure, dtype=float)
        )

    def evaluate(self, previous_distance: float, position: np.ndarray, up_z: float,
                 goal: np.ndarray, action: np.ndarray, speed: float = 0.0,
                 odometry: tuple[float, float] = (0.0, 0.0),
                 previous_odometry_error: float = 0.0) -> Outcome:
        """One step's outcome from the ground-truth position and uprightness (and with
        ``stop_speed_m_s`` the true speed (m/s), the odometry's (x, y) and the odometry error of
        the step before).

        The per-step path: the same arithmetic as ``distance``, ``is_success``, ``is_failure``
        and ``reward``, in the same order on Python floats (bit for bit the same, tested),
        without numpy's cost per call on 2-element arrays.
        """
        x, y = float(position[0]), float(position[1])
        dx, dy = x - float(goal[0]), y - float(goal[1])
        distance = math.sqrt(dx * dx + dy * dy)
        success = distance < self.goal_tolerance_m
        arrival, odometry_error = 0.0, 0.0
        if self.stop_speed_m_s is not None:
            ox, oy = float(odometry[0]), float(odometry[1])
            odometry_error = math.hypot(ox - x, oy - y)
            inside = success and math.hypot(ox - float(goal[0]),
                                             oy - float(goal[1])) < self.goal_tolerance_m
            speed = abs(float(speed))
            success = inside and speed < self.stop_speed_m_s
            arrival = (self.speed_cost * speed * float(inside) + self.odometry_cost
                       * (odometry_error - float(previous_odometry_error)))
        half = self.arena_half_size_m
        failure = float(up_z) < FLIP_UP_Z or abs(x) > half or abs(y) > half
        a0, a1 = float(action[0]), float(action[1])
        reward = (
            self.progress_weight * (float(previous_distance) - distance)
            - self.time_cost
            - self.action_cost * (a0 * a0 + a1 * a1)
            + self.success_bonus * float(success)
            - self.failure_penalty * float(failure)
        )
        if self.stop_speed_m_s is not None:
            reward -= arrival
        return Outcome(reward, success, failure, distance, odometry_error)

    # -- observation ---------------------------------------------------------------------------
    def observation_entries(self) -> list[Entry]:
        """The goal as the robot sees it through odometry (A = ``arena_half_size_m``)."""
        a = self.arena_half_size_m
        return [
            Entry("goal_base", ("goal_x_base", "goal_y_base"), -4 * a, 4 * a, "m",
                  "goal in the odometry base_link frame (ahead, left)",
                  lambda r: _goal_in_base(r)[:2], ("-4A", "4A")),
            Entry("goal_distance", ("goal_distance",), 0.0, 4 * a, "m",
                  "goal distance from the odometry pose", lambda r: _goal_in_base(r)[2:],
                  ("0", "4A")),
            Entry("goal_odom", ("goal_x_odom", "goal_y_odom"), -2 * a, 2 * a, "m",
                  "goal in the ``odom`` frame (as a goal is given in ROS)",
                  lambda r: r.goal, ("-2A", "2A")),
        ]
