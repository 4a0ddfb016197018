"""The policy node's decisions, free of rospy: messages in, a twist and a log line out.

``GoalDriver`` keeps the latest odometry, wheel joint states and goal, and for each decision
builds the observation with the env's own task from a one-car state filled as the env fills
its own (``envs.state.CarState``), asks the policy for an action and scales it as
``SmartCarEnv.step`` does. It never drives blind: no goal, a goal in another frame than the
odometry's, a malformed message, stale odometry or joint states, or a car outside the arena
the policy was trained in give a zero twist (or nothing at all when there is no goal) and one
log line saying why.

Each goal starts an episode as the env's ``reset`` does: the policy sees the odometry pose
the car had when the goal came as the origin facing +x (odometry and goal are rewritten in
that frame; the identity for a goal sent at the odometry origin), so that a goal sent from
wherever the car stands looks like one of the episodes the policy was trained on.

The goal is reached when the odometry says so (``stop_on="odometry"``: all a real robot
knows), or, with a simulated robot, when its true pose does (``"ground_truth"``, from
``base_pose_ground_truth``), which is the env's own success test; for a policy trained with
``stop_speed`` (SmartCarArrive-v0) only at rest: with the speed of the same reading under it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from smartcar_gym.bags import messages as m
from smartcar_gym.envs.policy_settings import PolicySettings
from smartcar_gym.envs.state import CarState

STOP = (0.0, 0.0)
STOP_ON = ("odometry", "ground_truth")


@dataclass
class _Car:
    """The robot as the task sees it (``tasks.base.Cars``): its state, no threads."""

    state: CarState
    threads: int = 1

    @staticmethod
    def values(array: np.ndarray) -> np.ndarray:
        """The car's values as a one-row array (the observation is built as a batch's)."""
        return array


@dataclass(frozen=True)
class Command:
    """What to publish on ``cmd_vel`` (None: nothing) and a line to log (level, text)."""

    twist: tuple[float, float] | None
    log: tuple[str, str] | None = None


class GoalDriver:
    """Drives to the latest goal with ``act(observation) -> action`` (the trained policy).

    Args:
        settings: the env settings the policy was trained under.
        act: the policy: a float32 observation to an action in [-1, 1]^2 (before clipping).
        stale_after_s: odometry or joint states older than this (s of ROS time) are stale.
        stop_on: what tells that the goal is reached: ``"odometry"`` or ``"ground_truth"``.
    """

    def __init__(self, settings: PolicySettings, act: Callable[[np.ndarray], np.ndarray],
                 stale_after_s: float, stop_on: str = "odometry") -> None:
        if stop_on not in STOP_ON:
            raise ValueError(f"stop_on must be one of {STOP_ON}, got {stop_on!r}")
        self.stop_on = stop_on
        self.settings = settings
        #: the one car the task sees: its state, filled from the messages
        self.cars = _Car(CarState.zeros(1, len(settings.wheel_joints)))
        self.act = act
        self.stale_after_ns = round(stale_after_s * m.NS_PER_S)
        self.goal: m.GoalReading | None = None
        self.odometry: m.OdometryReading | None = None
        self.wheels: m.WheelReading | None = None
        self.ground_truth: m.OdometryReading | None = None
        self.previous_action = np.zeros(2, dtype=np.float32)
        self.origin: tuple[float, float, float] | None = None  # the episode's (x, y, theta)
        self.last_observation: np.ndarray | None = None  # what the policy was last given
        self._odometry_error: str | None = None
        self._wheels_error: str | None = None
        self._truth_error: str | None = None
        self._last_key: str | None = None

    # -- inputs --------------------------------------------------------------------------------
    def on_goal(self, msg: Any) -> Command:
        """A new goal: accepted (the episode restarts) or refused (the car stops)."""
        try:
            goal = m.read_goal(msg)
        except m.MessageError as err:
            return self._drop(f"goal refused: {err}")
        half = self.settings.task.arena_half_size_m
        if max(abs(goal.x), abs(goal.y)) > half:
            return self._drop(
                f"goal refused: ({goal.x:g}, {goal.y:g}) lies outside the arena the policy was "
                f"trained in (|x|, |y| <= {half:g} m around the odometry origin)")
        self.goal = goal
        self.previous_action = np.zeros(2, dtype=np.float32)  # as the env's reset
        self.origin = None  # taken from the odometry of the first decision
        self._last_key = None
        return Command(None, ("info", f"new goal ({goal.x:g}, {goal.y:g}) in frame "
                                      f"{goal.frame_id or '(none)'}"))

    def on_odometry(self, msg: Any) -> None:
        try:
            self.odometry, self._odometry_error = m.read_odometry(msg), None
        except m.MessageError as err:
            self._odometry_error = str(err)

    def on_joint_states(self, msg: Any) -> None:
        try:
            self.wheels = m.read_wheels(msg, self.settings.wheel_joints)
            self._wheels_error = None
        except m.MessageError as err:
            self._wheels_error = str(err)

    def on_ground_truth(self, msg: Any) -> None:
        try:
            self.ground_truth, self._truth_error = m.read_odometry(msg), None
        except m.MessageError as err:
            self._truth_error = f"ground truth: {err}"

    # -- decisions -----------------------------------------------------------------------------
    def step(self, now_ns: int) -> Command:
        """The command for now: the policy's twist, a stop, or nothing when there is no goal."""
        if self.goal is None:
            return Command(None)
        problem = (self._odometry_problem(now_ns) or self._wheels_problem(now_ns)
                   or self._truth_problem(now_ns))
        if problem:
            return self._stop(*problem)
        odom, goal = self.odometry, self.goal
        if goal.frame_id != odom.frame_id:
            return self._drop(
                f"goal dropped: it is in frame {goal.frame_id or '(none)'!r} but odometry is "
                f"in {odom.frame_id!r}; the policy drives to goals in the odometry frame (in "
                f"rviz, set the Fixed Frame to {odom.frame_id})")
        half = self.settings.task.arena_half_size_m
        if max(abs(odom.x), abs(odom.y)) > half:
            return self._drop(
                f"goal dropped: the car ({odom.x:.2f}, {odom.y:.2f}) is outside the arena the "
                f"policy was trained in (|x|, |y| <= {half:g} m around the odometry origin)")
        judge = odom if self.stop_on == "odometry" else self.ground_truth
        distance = math.hypot(goal.x - judge.x, goal.y - judge.y)
        if bool(self.settings.task.is_success(distance, judge.v)):
            self.goal = None
            self._last_key = None
            odom_distance = math.hypot(goal.x - odom.x, goal.y - odom.y)
            said = (f"odometry says {distance:.3f} m away" if judge is odom else
                    f"ground truth {distance:.3f} m away (odometry says {odom_distance:.3f} m)")
            if self.settings.task.stop_speed_m_s is not None:
                said += f", {judge.v:.3f} m/s"
            return Command(STOP, ("info", f"goal ({goal.x:g}, {goal.y:g}) reached: {said}"))
        if self.origin is None:
            self.origin = (odom.x, odom.y, odom.theta)
        ox, oy, otheta = self.origin
        c, s = math.cos(otheta), math.sin(otheta)

        def local(x: float, y: float) -> tuple[float, float]:
            dx, dy = x - ox, y - oy
            return c * dx + s * dy, -s * dx + c * dy

        x, y = local(odom.x, odom.y)
        state = self.cars.state
        state.odometry[0] = (x, y, odom.theta - otheta, odom.v, odom.omega)
        state.wheel_position[0] = self.wheels.position
        state.wheel_velocity[0] = self.wheels.velocity
        state.goal[0] = local(goal.x, goal.y)
        state.previous_action[0] = self.previous_action
        self.last_observation = self.settings.task.observe(self.cars)[0]
        action = np.asarray(self.act(self.last_observation), dtype=np.float64)
        if action.shape != (2,) or not np.all(np.isfinite(action)):
            return self._stop("action", "error", f"the policy gave the action {action.tolist()} "
                                                  "(expected 2 finite numbers): stopping")
        action = np.clip(action, -1.0, 1.0)  # SmartCarEnv.step's scaling
        self.previous_action = action.astype(np.float32)
        self._last_key = None
        return Command((float(action[0]) * self.settings.max_linear,
                        float(action[1]) * self.settings.max_angular))

    def watchdog(self, now_ns: int) -> Command:
        """Between odometry messages: a stop while a goal is active and odometry is missing or
        stale (decisions are otherwise made when odometry arrives)."""
        if self.goal is None:
            return Command(None)
        problem = self._odometry_problem(now_ns) or self._truth_problem(now_ns)
        return self._stop(*problem) if problem else Command(None)

    # -- helpers -------------------------------------------------------------------------------
    def _problem(self, what: str, reading: Any, error: str | None,
                 now_ns: int) -> tuple[str, str, str] | None:
        """Why ``reading`` (of the topic ``what``) cannot be used now, as (key, level, text)."""
        if error:
            return what, "error", f"{error}: stopping"
        if reading is None:
            return f"no-{what}", "warn", f"no {what} received yet: waiting, stopped"
        age = (now_ns - reading.stamp_ns) / m.NS_PER_S
        limit = self.stale_after_ns / m.NS_PER_S
        if age > limit:
            return (f"stale-{what}", "error",
                    f"{what} is stale ({age:.2f} s old, more than {limit:g} s): stopping")
        return None

    def _odometry_problem(self, now_ns: int) -> tuple[str, str, str] | None:
        return self._problem("odometry", self.odometry, self._odometry_error, now_ns)

    def _wheels_problem(self, now_ns: int) -> tuple[str, str, str] | None:
        return self._problem("joint_states", self.wheels, self._wheels_error, now_ns)

    def _truth_problem(self, now_ns: int) -> tuple[str, str, str] | None:
        if self.stop_on != "ground_truth":
            return None
        return self._problem(m.GROUND_TRUTH_TOPIC, self.ground_truth, self._truth_error, now_ns)

    def _stop(self, key: str, level: str, text: str) -> Command:
        """A zero twist; the reason is logged when it differs from the last one logged."""
        log = None if key == self._last_key else (level, text)
        self._last_key = key
        return Command(STOP, log)

    def _drop(self, text: str) -> Command:
        """Forget the goal and stop."""
        self.goal = None
        self._last_key = None
        return Command(STOP, ("error", text))
