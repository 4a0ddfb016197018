"""2D Nav Goals one after another, without ROS: ``GoalDriver`` driving the simulated robot.

What a user clicking goals in rviz gets, in one process: the robot ``smartcar-ros bringup``
runs (``start_robot``, the controller configuration the policy was trained with), the
messages bringup would publish at each controller update (written as plain namespaces and
read by the driver's own readers), and the driver's twist applied to the controller as the env
applies an action. Each goal is drawn from where the car stands by odometry (a distance in
``distance_m``, a uniform bearing, inside the arena the policy was trained in); the next goal
is sent once the driver says the goal is reached (or after ``timeout_s``) and the car has
been left ``settle_s`` at rest, where it is measured by odometry and by ground truth.

Ground truth is the simulator's pose in ``world``, where ``odom`` starts. A goal is clicked
where rviz shows the car, by odometry, so it lies where the user meant it relative to where
the car really stood then: ``GoalResult.real_goal``. Wheel odometry drifts from ``world``
over many goals (a few centimetres each); ``world_distance`` also counts that drift.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from smartcar_gym.bags import messages as m
from smartcar_gym.controller import load_controller_config
from smartcar_gym.envs.policy_settings import PolicySettings
from smartcar_gym.model import load_model
from smartcar_gym.ros.bringup import start_robot
from smartcar_gym.ros.driving import GoalDriver
from smartcar_gym.sim.clock import NS_PER_S

ARENA_MARGIN_M = 0.3  # goals are kept this far inside the arena the policy was trained in


class NamespaceTypes:
    """Messages as plain namespaces (what the driver's readers need: attribute access)."""

    def __call__(self, msg_type: str, /, **fields: Any) -> Any:
        return SimpleNamespace(**fields)

    def time(self, ns: int) -> Any:
        return SimpleNamespace(secs=ns // m.NS_PER_S, nsecs=ns % m.NS_PER_S)


Pose = tuple[float, float, float]  # x, y, yaw


def meant_goal(goal: tuple[float, float], odom: Pose, truth: Pose) -> tuple[float, float]:
    """Where a goal clicked at ``goal`` (``odom``) lies in ``world``: relative to the car's
    true pose ``truth`` as it lies relative to the car's odometry pose ``odom`` at the click."""
    c, s = math.cos(odom[2]), math.sin(odom[2])
    dx, dy = goal[0] - odom[0], goal[1] - odom[1]
    ahead, left = c * dx + s * dy, -s * dx + c * dy
    c, s = math.cos(truth[2]), math.sin(truth[2])
    return truth[0] + c * ahead - s * left, truth[1] + s * ahead + c * left


@dataclass(frozen=True)
class GoalResult:
    """One goal: where it was (``odom`` frame), how long the driver took, where the car came to
    rest by odometry and by ground truth (``world``, where ``odom`` starts) and its speeds.

    ``real_goal`` is the goal where the user meant it: placed relative to the car's true pose
    at the click as it was relative to the car's odometry pose then (``world`` frame).
    """

    goal: tuple[float, float]
    real_goal: tuple[float, float]
    reached: bool  # the driver said so (by odometry, at rest) within the time limit
    time_s: float  # from the goal to the driver's "reached" (the limit if not reached)
    odom: tuple[float, float]
    truth: tuple[float, float]
    odom_speed: float  # |twist.linear.x| of odom, m/s
    truth_speed: float  # the true planar speed of the base, m/s

    @property
    def odom_distance(self) -> float:
        return math.dist(self.odom, self.goal)

    @property
    def truth_distance(self) -> float:
        """Where the car really stopped from where the goal was really meant (m)."""
        return math.dist(self.truth, self.real_goal)

    @property
    def world_distance(self) -> float:
        """Where the car really stopped from the goal's coordinates in ``world`` (m): the
        odometry's drift since the start counts too."""
        return math.dist(self.truth, self.goal)

    def arrived(self, tolerance_m: float, rest_m_s: float) -> bool:
        """Reached, at rest and within ``tolerance_m`` by odometry and by ground truth."""
        return (self.reached and self.odom_distance < tolerance_m
                and self.truth_distance < tolerance_m
                and max(self.odom_speed, self.truth_speed) < rest_m_s)


def next_goal(rng: np.random.Generator, x: float, y: float, distance_m: tuple[float, float],
              half_m: float) -> tuple[float, float]:
    """A goal ``distance_m`` from (x, y) at a uniform bearing with |x|, |y| <= ``half_m``."""
    for _ in range(1000):
        distance, bearing = rng.uniform(*distance_m), rng.uniform(-math.pi, math.pi)
        goal = (x + distance * math.cos(bearing), y + distance * math.sin(bearing))
        if max(abs(goal[0]), abs(goal[1])) <= half_m:
            return goal
    raise ValueError(f"no goal {distance_m} m from ({x:g}, {y:g}) inside |x|, |y| <= {half_m:g}")


def drive_goals(settings: PolicySettings, act: Callable[[np.ndarray], np.ndarray], count: int,
                seed: int, distance_m: tuple[float, float] = (0.3, 2.0),
                timeout_s: float = 30.0, settle_s: float = 1.0, mode: str = "hardware",
                stale_after_s: float = 0.5) -> list[GoalResult]:
    """Send ``count`` goals one after another (drawn with ``seed``) and drive to each."""
    config = settings.controller_config or load_controller_config()
    robot = start_robot(load_model(None), config, mode)
    sim, types = robot.sim, NamespaceTypes()
    driver = GoalDriver(settings, act, stale_after_s)
    rng = np.random.default_rng(seed)
    half = settings.task.arena_half_size_m - ARENA_MARGIN_M
    period_ns = robot.update_period_ns

    def publish() -> None:
        t = sim.now_ns
        driver.on_odometry(m.odometry_message(types, robot.odometry, t))
        driver.on_joint_states(m.joint_state_message(types, robot.joint_states(), t))

    def advance(twist: tuple[float, float] | None) -> None:
        if twist is not None:
            robot.cmd_vel(*twist)
        sim.run_until(sim.now_ns + period_ns, physics=not robot.kinematic)
        publish()

    results = []
    try:
        publish()
        for _ in range(count):
            odom, pose = robot.odometry, robot.pose()
            goal = next_goal(rng, odom.x, odom.y, distance_m, half)
            real_goal = meant_goal(goal, (odom.x, odom.y, odom.theta),
                                   (pose.x, pose.y, pose.yaw))
            driver.on_goal(m.goal_message(types, goal, sim.now_ns, odom.frame_id))
            start_ns, limit_ns = sim.now_ns, sim.now_ns + round(timeout_s * NS_PER_S)
            while driver.goal is not None and sim.now_ns < limit_ns:
                advance(driver.step(sim.now_ns).twist)
            reached = driver.goal is None
            time_s = (sim.now_ns - start_ns) / NS_PER_S
            driver.goal = None  # not reached in time: the user gives up; the car is stopped
            for _ in range(round(settle_s * settings.rate_hz)):
                advance(None if reached else (0.0, 0.0))
            odom = robot.odometry
            (x, y, _), _ = robot.body.link_pose()
            (vx, vy, _), _ = robot.body.velocity()
            results.append(GoalResult(goal, real_goal, reached, time_s, (odom.x, odom.y), (x, y),
                                      abs(odom.v), math.hypot(vx, vy)))
    finally:
        sim.close()
    return results
