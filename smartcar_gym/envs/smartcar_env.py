"""SmartCar-v0: drive the ROS tutorial smartcar to a goal through an emulated ArbotiX base."""

from __future__ import annotations

import math
import os
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from smartcar_gym.controller import ArbotixConfig, load_controller_config
from smartcar_gym.envs import kwargs as kw
from smartcar_gym.envs.task import GoalReachingTask
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.model.contact import check_wheel_contact
from smartcar_gym.sim.markers import SceneMarkers
from smartcar_gym.sim.robot import MODES, SmartCarRobot
from smartcar_gym.sim.simulator import Simulator


class SmartCarEnv(gym.Env):
    """## Description

    The smartcar of the classic ROS indigo tutorial (a 0.25 x 0.16 m box on four 25 mm wheels)
    in pybullet, driven like the real robot: every action is a ``cmd_vel`` Twist sent to an
    emulation of the ArbotiX ROS ``diff_controller`` (configured by ``smartcar_arbotix.yaml``),
    which turns it into wheel speeds in encoder ticks per frame, slews them by ``accel_limit``,
    and hands them to the board's integer PID, whose PWM drives one DC gearmotor per side.
    The robot sees only what the real one would: the controller's odometry (from the wheel
    encoders) and the wheel joint states. The task is to reach a goal on the ground.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``, scaled and published as a ``geometry_msgs/Twist`` on cmd_vel:

    | Num | Action                          | Min | Max | Unit                  |
    |-----|---------------------------------|-----|-----|-----------------------|
    | 0   | linear.x  = a[0] * max_linear   | -1  | 1   | m/s after scaling     |
    | 1   | angular.z = a[1] * max_angular  | -1  | 1   | rad/s after scaling   |

    Out-of-range values are clipped to [-1, 1]. A wrong shape or a NaN/inf raises ``ValueError``.
    One step is one controller update period (``1 / rate``: 0.1 s with the shipped config): the
    command arrives, the world runs for one period, then the controller fires (odometry, 1 s
    timeout, ramp, write to the board). As on the robot, a command therefore reaches the wheels
    at the next controller update.

    ## Observation Space

    ``Box(low, high, (21,), float32)`` with finite bounds (values are clipped into them):

    | Num   | Observation                                              | Min    | Max   | Unit  |
    |-------|----------------------------------------------------------|--------|-------|-------|
    | 0, 1  | odom pose x, y (``odom`` -> ``base_link``)               | -2A    | 2A    | m     |
    | 2, 3  | cos, sin of odom yaw                                     | -1     | 1     |       |
    | 4     | odom twist linear.x                                      | -5     | 5     | m/s   |
    | 5     | odom twist angular.z                                     | -50    | 50    | rad/s |
    | 6-9   | wheel joint positions, wrapped (lf, lb, rf, rb)          | -pi    | pi    | rad   |
    | 10-13 | wheel joint velocities (lf, lb, rf, rb)                  | -200   | 200   | rad/s |
    | 14,15 | goal in the odometry base_link frame (ahead, left)       | -4A    | 4A    | m     |
    | 16    | goal distance from the odometry pose                     | 0      | 4A    | m     |
    | 17,18 | previous action                                          | -1     | 1     |       |
    | 19,20 | goal in the ``odom`` frame (as a goal is given in ROS)   | -2A    | 2A    | m     |

    where A = ``arena_size / 2``. Wheels are listed left then right, front then back, as the
    model's wheels are found (``env.unwrapped.observation_names`` names every entry, e.g.
    ``left_back_wheel_joint.velocity``); ``info`` has nothing the observation needs.

    ## Rewards

    ``10 * (d_prev - d) - 0.01 - 0.01 * |a|^2``, plus ``+10`` on reaching the goal and ``-10``
    on flipping over or leaving the arena, where d is the ground-truth distance (m) from
    base_link to the goal.

    ## Starting State

    The world is rebuilt (``resetSimulation``), the car is placed at the origin facing +x, left
    to settle for 0.1 s, and the controller starts: the start pose is the odometry origin. The
    goal is drawn with ``self.np_random`` at a uniform distance in ``goal_range`` and a uniform
    bearing. ``reset(options={"goal": (x, y)})`` sets it instead (the only option).
    ``close()`` disconnects the pybullet client; a later ``reset()`` connects a new one.

    ## Episode End

    Terminated when the ground-truth distance is under ``goal_tolerance`` (success), when the
    car flips over (base_link z axis tilted more than 60 degrees) or when it leaves the square
    arena. Truncated by the ``TimeLimit`` (200 steps = 20 s for SmartCar-v0).

    ``info``: ``is_success`` (bool), ``distance`` (ground truth, m), ``pose`` (ground-truth
    x, y, yaw), ``odom_pose`` (odometry x, y, yaw), ``odom_error`` (m between the two).

    ## Arguments

    | kwarg             | default        | meaning                                              |
    |-------------------|----------------|------------------------------------------------------|
    | model             | shipped xacro  | .urdf / .xacro robot description                     |
    | package_path      | None           | folders searched for ``$(find pkg)``                 |
    | wheels            | None (auto)    | ``{"left": [joints], "right": [joints]}``            |
    | controller_config | shipped YAML   | arbotix YAML (``controllers: {..: diff_controller}``)|
    | controller_mode   | None           | "hardware" (PID, encoders, motors) or "sim"; None:   |
    |                   |                | the YAML's ``sim`` key (hardware unless sim: true)   |
    | render_mode       | None           | None, "human" (pybullet GUI) or "rgb_array"          |
    | max_linear        | 0.5            | m/s for a[0] = 1                                     |
    | max_angular       | 2.0            | rad/s for a[1] = 1                                   |
    | goal_range        | (0.5, 1.5)     | min, max goal distance from the start (m)            |
    | goal_tolerance    | 0.1            | success radius (m)                                   |
    | arena_size        | 5.0            | side of the square arena centred on the start (m)    |
    | physics_hz        | 500            | physics rate: a whole multiple of the controller    |
    |                   |                | rate; 34 ms PID frames need 34 ms in whole steps     |
    | wheel_contact     | "sphere"       | drive wheels touch the ground as spheres of their    |
    |                   |                | radius (one contact each, 1.5x faster) or "urdf":    |
    |                   |                | the model's own collision shapes (cylinders)         |
    | render_width/height | 480, 360     | rgb_array image size (px)                            |

    ## Version History

    * v0: initial version.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(
        self,
        model: str | os.PathLike | RobotModel | None = None,
        controller_config: str | os.PathLike | ArbotixConfig | None = None,
        controller_mode: str | None = None,
        render_mode: str | None = None,
        max_linear: float = 0.5,
        max_angular: float = 2.0,
        goal_range: tuple[float, float] = (0.5, 1.5),
        goal_tolerance: float = 0.1,
        arena_size: float = 5.0,
        physics_hz: float = 500.0,
        package_path: list[str | os.PathLike] | None = None,
        wheels: dict[str, list[str]] | None = None,
        render_width: int = 480,
        render_height: int = 360,
        wheel_contact: str = "sphere",
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be None or one of {self.metadata['render_modes']}, "
                f"got {render_mode!r}"
            )
        if controller_mode is not None and controller_mode not in MODES:
            raise ValueError(
                f"controller_mode must be None or one of {MODES}, got {controller_mode!r}"
            )
        self.render_mode = render_mode
        self.wheel_contact = check_wheel_contact(wheel_contact)
        self.max_linear = kw.positive_number("max_linear", max_linear)
        self.max_angular = kw.positive_number("max_angular", max_angular)
        half = kw.positive_number("arena_size", arena_size) / 2.0
        self.physics_hz = kw.positive_number("physics_hz", physics_hz)
        self.render_width = kw.positive_int("render_width", render_width)
        self.render_height = kw.positive_int("render_height", render_height)
        self.task = GoalReachingTask(
            goal_range_m=kw.number_pair("goal_range", goal_range),
            goal_tolerance_m=kw.positive_number("goal_tolerance", goal_tolerance),
            arena_half_size_m=half,
        )
        model = kw.source("model", model, RobotModel)
        controller_config = kw.source("controller_config", controller_config, ArbotixConfig)

        self.robot_model = (
            model if isinstance(model, RobotModel)
            else load_model(model, package_path=package_path, wheels=wheels)
        )
        self.controller_config = (
            controller_config if isinstance(controller_config, ArbotixConfig)
            else load_controller_config(controller_config)
        )
        rate = self.controller_config.rate_hz
        ticks = self.physics_hz / rate
        if not (ticks >= 1 and abs(ticks - round(ticks)) < 1e-9):
            raise ValueError(
                f"physics_hz={physics_hz} must be a whole multiple of the controller rate "
                f"{rate} Hz ({self.controller_config.source}), e.g. {int(rate) * 50}"
            )
        self.ticks_per_step = round(ticks)
        if controller_mode is None:  # as the driver: its `sim` parameter picks the mode
            controller_mode = "sim" if self.controller_config.sim else "hardware"
        self.controller_mode = controller_mode
        frame_ms = self.controller_config.frame_ms + 1  # the firmware's PID frame spacing
        frame_steps = frame_ms * self.physics_hz / 1000
        if controller_mode == "hardware" and abs(frame_steps - round(frame_steps)) > 1e-9:
            warnings.warn(
                f"physics_hz={physics_hz}: the board's {frame_ms} ms PID frames are not a whole "
                "number of physics steps, so each runs late, at the next step; 500 or 1000 Hz "
                "keeps them exact",
                stacklevel=2,
            )
        self.metadata = {**self.metadata, "render_fps": rate}

        self.sim: Simulator | None = None
        self._open()
        wheels_found = [w.joint for w in self.robot.wheels]
        n = len(wheels_found)
        #: what each observation entry is, in order (wheels as found: left then right)
        self.observation_names: tuple[str, ...] = (
            "odom_x", "odom_y", "odom_cos_yaw", "odom_sin_yaw", "odom_v", "odom_omega",
            *(f"{joint}.position" for joint in wheels_found),
            *(f"{joint}.velocity" for joint in wheels_found),
            "goal_x_base", "goal_y_base", "goal_distance", "prev_linear", "prev_angular",
            "goal_x_odom", "goal_y_odom",
        )
        high = np.concatenate([
            [2 * half, 2 * half, 1, 1, 5, 50], [math.pi] * n, [200] * n,
            [4 * half, 4 * half, 4 * half], [1, 1], [2 * half, 2 * half],
        ]).astype(np.float32)
        low = -high
        low[6 + 2 * n + 2] = 0.0  # goal distance
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.goal = np.zeros(2)
        self._distance = 0.0
        self._prev_action = np.zeros(2, dtype=np.float32)
        self._odom = None

    def _open(self) -> None:
        """Connect a fresh simulator (its own BulletClient) with the robot and the markers."""
        self.sim = Simulator(physics_hz=self.physics_hz, gui=self.render_mode == "human")
        self.robot = SmartCarRobot(
            self.sim, self.robot_model, self.controller_config, mode=self.controller_mode,
            wheel_contact=self.wheel_contact,
        )
        self.markers = (
            SceneMarkers(self.sim, self.task.goal_tolerance_m) if self.render_mode is not None
            else None
        )
        self._needs_reset = True

    # -- gymnasium API -----------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if self.sim is None:  # closed: reopen, as a fresh env would start
            self._open()
        options = options or {}
        unknown = set(options) - {"goal"}
        if unknown:
            raise ValueError(f"unknown reset option(s) {sorted(unknown)}; SmartCar-v0 takes 'goal'")
        goal = self._goal_option(options["goal"]) if "goal" in options else None
        with self.sim.building():  # the GUI must not draw a half-built world
            self.sim.reset()
            self.robot.spawn(0.0, 0.0, 0.0)
            self.goal = (
                goal if goal is not None else self.task.sample_goal(self.np_random, np.zeros(2))
            )
            self._prev_action = np.zeros(2, dtype=np.float32)
            self._odom = self.robot.base.odometry
            pose = self.robot.pose()
            self._distance = float(self.task.distance(np.array([pose.x, pose.y]), self.goal))
            if self.markers is not None:
                self.markers.create(self.goal)
                self.markers.add_pose(self._odom.x, self._odom.y, self._odom.theta)
        self._needs_reset = False
        if self.render_mode == "human":
            self.render()
        return self._observation(), self._info(pose, False)

    def _goal_option(self, value: Any) -> np.ndarray:
        """``options["goal"]`` checked before the world is rebuilt: a finite (x, y) in the arena."""
        expected = f"options['goal'] must be a finite (x, y) pair, got {value!r}"
        try:
            goal = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(expected) from None
        if goal.shape != (2,) or not np.all(np.isfinite(goal)):
            raise ValueError(expected)
        if self.task.is_outside(goal):
            raise ValueError(
                f"options['goal'] {goal.tolist()} lies outside the arena (|x|, |y| <= "
                f"{self.task.arena_half_size_m} m): raise arena_size"
            )
        return goal

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self._check_ready("step")
        action = self._validate_action(action)
        self._odom = self.robot.advance(
            float(action[0]) * self.max_linear, float(action[1]) * self.max_angular,
            self.ticks_per_step,
        )
        pose = self.robot.pose()
        position = np.array([pose.x, pose.y])
        distance = float(self.task.distance(position, self.goal))
        success = bool(self.task.is_success(distance))
        failure = bool(pose.up_z < 0.5 or self.task.is_outside(position))
        reward = float(self.task.reward(self._distance, distance, action, success, failure))
        self._distance = distance
        self._prev_action = action.astype(np.float32)
        if self.markers is not None:
            self.markers.add_pose(self._odom.x, self._odom.y, self._odom.theta)
        if self.render_mode == "human":
            self.render()
        return self._observation(), reward, success or failure, False, self._info(pose, success)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array' or 'human' "
                "to gym.make('SmartCar-v0', ...)"
            )
            return None
        self._check_ready("render")
        self.markers.draw()
        pose = self.robot.pose()
        target = (np.array([pose.x, pose.y]) + self.goal) / 2.0
        span = float(np.linalg.norm(self.goal - np.array([pose.x, pose.y])))
        distance = max(0.9, 1.1 * span + 0.5)
        target3 = (float(target[0]), float(target[1]), 0.0)
        if self.render_mode == "human":
            self.sim.client.resetDebugVisualizerCamera(distance, 0.0, -60.0, target3)
            return None
        return self.sim.render(
            self.render_width, self.render_height, target3, distance, yaw_deg=0.0, pitch_deg=-60.0
        )

    def close(self) -> None:
        if getattr(self, "sim", None) is not None:
            self.sim.close()
            self.sim = None

    # -- helpers -------------------------------------------------------------------------------
    def _check_ready(self, call: str) -> None:
        if self.sim is None:
            raise RuntimeError(f"SmartCarEnv is closed: call reset() to reopen it before {call}()")
        if self._needs_reset:
            raise ResetNeeded(f"SmartCarEnv: call reset() before {call}()")

    def _validate_action(self, action: Any) -> np.ndarray:
        if np.iscomplexobj(action):
            raise ValueError(f"action must be real numbers, got {np.asarray(action).tolist()}")
        try:
            arr = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise ValueError(f"action must be 2 numbers (linear, angular), got {action!r}") from err
        if arr.shape != (2,):
            raise ValueError(
                f"action must have shape (2,) (linear, angular), got shape {arr.shape}: {action!r}"
            )
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"action must be finite, got {arr.tolist()}")
        return np.clip(arr, -1.0, 1.0)

    def _observation(self) -> np.ndarray:
        odom = self._odom
        joints = self.robot.joint_states()
        dx, dy = self.goal[0] - odom.x, self.goal[1] - odom.y
        c, s = math.cos(odom.theta), math.sin(odom.theta)
        wrapped = (joints.position + math.pi) % (2 * math.pi) - math.pi
        obs = np.concatenate([
            [odom.x, odom.y, c, s, odom.v, odom.omega], wrapped, joints.velocity,
            [c * dx + s * dy, -s * dx + c * dy, math.hypot(dx, dy)], self._prev_action,
            self.goal,  # the odom frame is the world frame at reset
        ]).astype(np.float32)
        return np.clip(obs, self.observation_space.low, self.observation_space.high)

    def _info(self, pose: Any, success: bool) -> dict[str, Any]:
        odom = self._odom
        return {
            "is_success": success,
            "distance": self._distance,
            "pose": np.array([pose.x, pose.y, pose.yaw]),
            # odometry's theta is never wrapped (as upstream); here it is, like pose's yaw
            "odom_pose": np.array([odom.x, odom.y, math.remainder(odom.theta, 2 * math.pi)]),
            "odom_error": math.hypot(odom.x - pose.x, odom.y - pose.y),
        }
