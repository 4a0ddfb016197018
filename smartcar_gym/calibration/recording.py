"""Drives as the planar fit sees them: the ``cmd_vel`` sent once per controller period and
where the robot truly was, from a physics engine's own drives or from a robot's bag.

A ``Recording`` starts with the robot at rest at ``truth[0]``; ``commands[t]`` is the twist
that arrived during period t (NaN: none published, so the driver's 1 s timeout runs) and
``truth[t + 1]`` the ground-truth pose when the controller fired at its end. ``record`` makes
them on any engine with the emulated ArbotiX base (the fit's own maneuvers: ``FIT_MANEUVERS``);
``calibration.bag_source`` reads them from ROS 1 and ROS 2 bags.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from smartcar_gym.calibration.drives import Driver, Plan, _Leg
from smartcar_gym.calibration.maneuvers import Twist, hold, random_commands
from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.envs.robots.smartcar import SmartCarRobot, drive
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.engines import default_max_substep, make_simulator

FIT_SEED = 7  # the random drive's seed (the fidelity table's odometry drive uses 2026)


@dataclass(frozen=True)
class Recording:
    """One drive: ``commands`` (T, 2) linear.x m/s, angular.z rad/s per controller period (NaN
    rows: nothing published); ``truth`` (T + 1, 3) x, y (m) and unwrapped yaw (rad) at the
    start and at each controller update, in the world; ``odom`` (T + 1, 3, or None) the
    odometry the controller published then (x, y, theta in its ``odom`` frame); ``rate_hz``:
    the controller's rate."""

    name: str
    rate_hz: float
    commands: np.ndarray
    truth: np.ndarray
    odom: np.ndarray | None = None

    def __post_init__(self) -> None:
        commands = np.asarray(self.commands, dtype=float)
        if commands.ndim != 2 or commands.shape[1] != 2:
            raise ValueError(f"{self.name}: commands must be (T, 2), got {commands.shape}")
        for key in ("truth", "odom"):
            value = getattr(self, key)
            if value is None:
                continue
            value = np.asarray(value, dtype=float)
            if value.shape != (len(commands) + 1, 3):
                raise ValueError(f"{self.name}: {key} must be ({len(commands) + 1}, 3) for "
                                 f"{len(commands)} commands, got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{self.name}: {key} has NaN or inf")
            object.__setattr__(self, key, value)
        object.__setattr__(self, "commands", commands)

    @property
    def seconds(self) -> float:
        return len(self.commands) / self.rate_hz


def twists(commands: np.ndarray) -> list[Twist]:
    """The rows of a commands array as ``maneuvers.run``'s twists (None for NaN rows)."""
    return [None if not np.all(np.isfinite(row)) else (float(row[0]), float(row[1]))
            for row in commands]


def fit_maneuvers(rate_hz: float, max_linear: float = 0.5,
                  max_angular: float = 2.0) -> dict[str, list[Twist]]:
    """The drives the fit makes itself on a physics engine: straight runs at five speeds and
    spins at three rates, each from rest and then stopped to coast, two arcs driven forward
    and the same two in reverse, two reversals out of a fast arc (the turn held while the
    wheels brake through zero: the wheels' spin moment loads the front, ``spin_reaction``),
    and 10 s of seeded random twists (about 76 s in all)."""
    stop = hold((0.0, 0.0), 1.5, rate_hz)
    drives: dict[str, list[Twist]] = {}
    for v in (0.05, 0.1, 0.2, 0.3, 0.5):
        drives[f"straight {v:g} m/s"] = hold((min(v, max_linear), 0.0), 3.0, rate_hz) + stop
    for w in (0.5, 1.0, 2.0):
        drives[f"spin {w:g} rad/s"] = hold((0.0, min(w, max_angular)), 3.0, rate_hz) + stop
    drives["arc 0.2 m/s 1 rad/s"] = hold((0.2, 1.0), 3.0, rate_hz) + stop
    drives["arc 0.3 m/s -1.5 rad/s"] = hold((0.3, -1.5), 3.0, rate_hz) + stop
    drives["arc -0.2 m/s 1 rad/s"] = hold((-0.2, 1.0), 3.0, rate_hz) + stop
    drives["arc -0.3 m/s -1.5 rad/s"] = hold((-0.3, -1.5), 3.0, rate_hz) + stop
    fast, turn = min(0.45, max_linear), min(1.4, max_angular)
    for side, label in ((1.0, "left"), (-1.0, "right")):
        drives[f"reversal out of a {label} arc"] = (
            hold((fast, side * turn), 1.2, rate_hz) + hold((-fast, side * turn), 1.2, rate_hz)
            + stop)
    drives["random twists"] = random_commands(10.0, rate_hz, FIT_SEED, max_linear, max_angular,
                                              hold_s=0.5)
    return drives


def as_array(commands: Sequence[Twist]) -> np.ndarray:
    """Twists (None: nothing published) as a (T, 2) array with NaN rows."""
    return np.array([(math.nan, math.nan) if c is None else c for c in commands], dtype=float)


def run_commands(robot: SmartCarRobot, commands: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drive a spawned robot through ``commands``; its true poses and its odometry (each
    (T + 1, 3); the true yaw unwrapped)."""
    pose = robot.pose()
    yaw = pose.yaw
    odom = robot.odometry
    truth, odometry = [(pose.x, pose.y, yaw)], [(odom.x, odom.y, odom.theta)]
    for twist in twists(commands):
        odom = drive(robot, *(twist if twist is not None else (None, None)))
        pose = robot.pose()
        yaw += math.remainder(pose.yaw - yaw, 2 * math.pi)
        truth.append((pose.x, pose.y, yaw))
        odometry.append((odom.x, odom.y, odom.theta))
    return np.array(truth), np.array(odometry)


def replay(model: RobotModel, config: ArbotixConfig, engine: str, commands: np.ndarray,
           start: Sequence[float] = (0.0, 0.0, 0.0), wheel_contact: str = "sphere",
           max_substep_s: float | None = None, **options: Any,
           ) -> tuple[np.ndarray, np.ndarray]:
    """Spawn the robot at rest at ``start`` (x, y, yaw) on ``engine`` (its ``wheel_contact``,
    ``max_substep_s``: the engine's default if None, and simulator ``options``, e.g.
    ``planar_params``), drive ``commands``; its true poses and odometry (T + 1, 3)."""
    sim = make_simulator(engine, max_substep_s=_substep(engine, max_substep_s), **options)
    try:
        robot = SmartCarRobot(sim, model, config, wheel_contact=wheel_contact)
        robot.spawn(float(start[0]), float(start[1]), float(start[2]))
        return run_commands(robot, commands)
    finally:
        sim.close()


def _substep(engine: str, max_substep_s: float | None) -> float:
    return default_max_substep(engine) if max_substep_s is None else max_substep_s


class _RecordingLeg(_Leg):
    """A calibration drive's steering that also records what it sent and where the robot was
    after every period."""

    def __init__(self, robot: SmartCarRobot) -> None:
        super().__init__(robot)
        pose, odom = robot.pose(), robot.odometry
        self.commands: list[tuple[float, float]] = []
        self.truth = [(pose.x, pose.y, pose.yaw)]
        self.odom = [(odom.x, odom.y, odom.theta)]

    def step(self, v: float, w: float) -> None:
        super().step(v, w)  # unwraps the yaw into self.yaw
        pose, odom = self.robot.pose(), self.robot.odometry
        self.commands.append((v, w))
        self.truth.append((pose.x, pose.y, self.yaw))
        self.odom.append((odom.x, odom.y, odom.theta))


def record_square(model: RobotModel, config: ArbotixConfig, engine: str, direction: int = 1,
                  wheel_contact: str = "sphere", max_substep_s: float | None = None,
                  **options: Any) -> Recording:
    """Borenstein's UMBmark square (``drives.Driver.square``: steered by odometry, 1 m, 0.2 m/s,
    1 rad/s) on ``engine``, recorded period by period: the starts and stops of its turns."""
    legs: list[_RecordingLeg] = []

    def leg(robot: SmartCarRobot) -> _RecordingLeg:
        legs.append(_RecordingLeg(robot))
        return legs[-1]

    driver = Driver(model, config, wheel_contact=wheel_contact,
                    max_substep_s=_substep(engine, max_substep_s), engine=engine,
                    sim_options=options)
    driver.square(Plan(), direction, leg)
    done = legs[-1]
    way = "counter-clockwise" if direction > 0 else "clockwise"
    return Recording(f"UMBmark square {way}", config.rate_hz, np.array(done.commands),
                     np.array(done.truth), np.array(done.odom))


def record(model: RobotModel, config: ArbotixConfig, engine: str,
           drives: dict[str, list[Twist]] | None = None, square: bool = False,
           wheel_contact: str = "sphere", max_substep_s: float | None = None,
           **options: Any) -> list[Recording]:
    """The fit's drives (``fit_maneuvers`` unless given; with ``square`` the UMBmark square
    too, which quadruples a fit's time and measured no better: docs/planar.md) on
    ``engine`` (its ``wheel_contact`` and ``max_substep_s``, as the env's; None: the engine's
    default), one fresh world each."""
    drives = fit_maneuvers(config.rate_hz) if drives is None else drives
    out = []
    for name, commands in drives.items():
        array = as_array(commands)
        truth, odom = replay(model, config, engine, array, wheel_contact=wheel_contact,
                             max_substep_s=max_substep_s, **options)
        out.append(Recording(name, config.rate_hz, array, truth, odom))
    if square:
        out.append(record_square(model, config, engine, wheel_contact=wheel_contact,
                                 max_substep_s=max_substep_s, **options))
    return out
