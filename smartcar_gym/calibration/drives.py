"""The calibration drives in the simulator: a straight run, spins and UMBmark squares.

Each drive is steered by the robot's own odometry, as a program on the real robot would be
(drive until odometry says 2 m, turn until it says 90 degrees), then the robot is left to come
to rest. A ``Run`` keeps the encoder counts the controller read at every update and the
ground-truth end pose: enough to integrate the odometry again with other parameters
(``estimate``). A fresh world is built for every drive.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.envs.robots.smartcar import SmartCarRobot, drive
from smartcar_gym.envs.robots.variation import Variation
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.engines import DEFAULT_ENGINE, make_simulator

REST_S = 1.0  # standing still after each leg and at the end: the car coasts to rest
MAX_LEG_S = 60.0  # a leg that takes longer means the car does not move as commanded
MIN_RATE_SHARE = 0.5  # slowest command of a leg's last period, as a share of its rate


class DriveError(RuntimeError):
    """The car did not do what the drive commanded (does not move, does not turn)."""


@dataclass(frozen=True)
class Run:
    """One calibration drive: what the controller counted and where the robot truly ended.

    ``ticks``: (n, 2) left/right encoder counts at each controller update (the first one is
    the reference, as upstream's first update moves nothing). ``true_end``: ground-truth x, y
    (m) and unwrapped yaw (rad) relative to the start pose, in the start frame. ``odom_end``:
    the published odometry x, y, theta at the end.
    """

    name: str
    ticks: np.ndarray
    true_end: tuple[float, float, float]
    odom_end: tuple[float, float, float]


@dataclass(frozen=True)
class Plan:
    """The drives: speeds, the straight run's length, the spins' turns, the squares' side."""

    speed_m_s: float = 0.2
    turn_rate_rad_s: float = 1.0
    straight_m: float = 2.0
    spin_revolutions: float = 2.0
    square_side_m: float = 1.0


class Driver:
    """Runs drives on a robot model + controller config (+ a plant ``Variation``), always in
    hardware mode (in the driver's sim mode odometry is exact by construction)."""

    def __init__(self, model: RobotModel, config: ArbotixConfig,
                 variation: Variation | None = None, wheel_contact: str = "sphere",
                 max_substep_s: float = 0.01, ground_friction: float = 1.0,
                 engine: str = DEFAULT_ENGINE, sim_options: dict | None = None) -> None:
        self.model = model
        self.sim_options = dict(sim_options or {})
        self.engine = engine
        self.config = config
        self.variation = variation
        self.wheel_contact = wheel_contact
        self.max_substep_s = max_substep_s
        self.ground_friction = ground_friction
        self._count = 0

    def controller_base_width(self) -> float:
        """The base width the emulated controller divides by (the YAML's unless the plant's
        track is varied: see ``Variation.config``)."""
        if self.variation is None:
            return self.config.base_width_m
        return self.variation.config(self.config).base_width_m

    def run(self, name: str, steer: Callable[[_Leg], list[tuple[float, float, str]]],
            leg: Callable[[SmartCarRobot], _Leg] | None = None) -> Run:
        """Spawn afresh, drive the legs ``steer`` lists, come to rest, record (``leg``: the
        class that steers, ``_Leg`` or one that records more)."""
        sim = make_simulator(self.engine, max_substep_s=self.max_substep_s,
                             ground_friction=self.ground_friction, **self.sim_options)
        try:
            robot = SmartCarRobot(sim, self.model, self.config, wheel_contact=self.wheel_contact)
            if self.variation is not None:  # each drive its own noise
                self._count += 1
                seed = self.variation.noise_seed + self._count
                robot.vary(dataclasses.replace(self.variation, noise_seed=seed))
            robot.spawn()
            steering = (leg or _Leg)(robot)
            for target, rate, kind in steer(steering):
                steering.go(target, rate, kind)
                steering.rest()
            return steering.run(name)
        finally:
            sim.close()

    def straight(self, plan: Plan) -> Run:
        return self.run("straight", lambda leg: [(plan.straight_m, plan.speed_m_s, "line")])

    def spin(self, plan: Plan, direction: int) -> Run:
        turn = direction * plan.spin_revolutions * 2 * math.pi
        name = "spin ccw" if direction > 0 else "spin cw"
        return self.run(name, lambda leg: [(turn, plan.turn_rate_rad_s, "turn")])

    def square(self, plan: Plan, direction: int,
               leg: Callable[[SmartCarRobot], _Leg] | None = None) -> Run:
        """Borenstein's UMBmark square: 4 legs, each followed by a 90-degree turn in place
        (counter-clockwise for ``direction`` 1, clockwise for -1), by odometry."""
        legs = []
        for _ in range(4):
            legs.append((plan.square_side_m, plan.speed_m_s, "line"))
            legs.append((direction * math.pi / 2, plan.turn_rate_rad_s, "turn"))
        return self.run("square ccw" if direction > 0 else "square cw", lambda _: legs, leg)


class _Leg:
    """Steering one robot by its odometry, recording counts and the true pose."""

    def __init__(self, robot: SmartCarRobot) -> None:
        self.robot = robot
        self.period_s = 1.0 / robot.config.rate_hz
        pose = robot.pose()
        self.start = (pose.x, pose.y, pose.yaw)
        self.yaw = pose.yaw  # unwrapped
        self.heading_goal = 0.0  # odometry heading the turns aim at (sum of the turns)
        self.ticks: list[tuple[int, int]] = []

    def step(self, v: float, w: float) -> None:
        drive(self.robot, v, w)
        c = self.robot.base.controller
        self.ticks.append((c.enc_left, c.enc_right))
        pose = self.robot.pose()
        self.yaw += math.remainder(pose.yaw - self.yaw, 2 * math.pi)
        if pose.up_z < 0.5:
            raise DriveError("the car flipped over during the calibration drive")

    def go(self, target: float, rate: float, kind: str) -> None:
        """Drive ``target`` m straight on, or turn ``target`` rad, at most ``rate``, until
        odometry says so (the last period's command covers just what is left)."""
        odom = self.robot.odometry
        x0, y0 = odom.x, odom.y
        if kind == "turn":
            self.heading_goal += target
        sign = 1.0 if target >= 0 else -1.0
        periods = 0
        while True:
            odom = self.robot.odometry
            if kind == "line":
                left = abs(target) - math.hypot(odom.x - x0, odom.y - y0)
            else:
                left = sign * (self.heading_goal - odom.theta)
            if left <= 0.0:
                return
            # what is left in one period, but not so slow that the board's dead band stalls
            command = sign * min(rate, max(left / self.period_s, MIN_RATE_SHARE * rate))
            self.step(command, 0.0) if kind == "line" else self.step(0.0, command)
            periods += 1
            if periods * self.period_s > MAX_LEG_S + abs(target) / rate:
                what = "move" if kind == "line" else "turn"
                raise DriveError(
                    f"the car did not {what} as commanded: odometry shows {left:.3g} "
                    f"{'m' if kind == 'line' else 'rad'} still to go after {MAX_LEG_S:g} s "
                    f"more than the {abs(target):g} {'m' if kind == 'line' else 'rad'} need "
                    f"at {rate:g} (check the model and the controller's gains and max_accel)"
                )

    def rest(self) -> None:
        for _ in range(round(REST_S / self.period_s)):
            self.step(0.0, 0.0)

    def run(self, name: str) -> Run:
        pose, odom = self.robot.pose(), self.robot.odometry
        x0, y0, yaw0 = self.start
        dx, dy = pose.x - x0, pose.y - y0
        c, s = math.cos(yaw0), math.sin(yaw0)
        true_end = (c * dx + s * dy, -s * dx + c * dy, self.yaw - yaw0)
        if not self.ticks or None in self.ticks[0]:
            raise DriveError(f"{name}: the controller read no encoders")
        return Run(name, np.array(self.ticks, dtype=float), true_end,
                   (odom.x, odom.y, odom.theta))
