"""Scripted drives of a robot with ground truth recorded: the measurements behind the fidelity
figures (steady speed, spin, coast-down, random commands) and the calibration drives.

Each maneuver publishes ``cmd_vel`` once per controller period, as a teleop node would, and
records one ``Sample`` per period after the controller fired.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from smartcar_gym.envs.robots.smartcar import SmartCarRobot, drive

Twist = tuple[float, float] | None  # (linear.x m/s, angular.z rad/s); None: nothing published


@dataclass(frozen=True)
class Sample:
    """The robot after one controller period: ground truth, odometry and wheels."""

    t: float  # s since spawn
    x: float  # ground truth, m
    y: float
    yaw: float  # unwrapped, rad
    z: float  # base_link height, m
    up_z: float
    speed: float  # ground-truth planar speed of base_link, m/s
    wheel_speed: float  # mean forward wheel surface speed, m/s
    odom_x: float
    odom_y: float
    odom_theta: float


def run(robot: SmartCarRobot, commands: Iterable[Twist]) -> list[Sample]:
    """Send ``commands`` (one per controller period) and record a ``Sample`` after each."""
    samples: list[Sample] = []
    yaw = robot.pose().yaw
    previous = yaw
    signs = np.array([w.forward_sign for w in robot.wheels])
    radius = robot.model.wheel_radius_m
    for twist in commands:
        odom = drive(robot, *(twist if twist is not None else (None, None)))
        pose = robot.pose()
        yaw += math.remainder(pose.yaw - previous, 2 * math.pi)
        previous = pose.yaw
        (vx, vy, _), _ = robot.body.velocity()
        wheels = robot.joint_states().velocity * signs * radius
        samples.append(Sample(
            robot.sim.time_s, pose.x, pose.y, yaw, pose.z, pose.up_z, math.hypot(vx, vy),
            float(np.mean(wheels)), odom.x, odom.y, odom.theta,
        ))
    return samples


def hold(twist: Twist, seconds: float, rate_hz: float) -> list[Twist]:
    """The same twist for ``seconds`` at the controller's rate."""
    return [twist] * round(seconds * rate_hz)


def random_commands(seconds: float, rate_hz: float, seed: int, max_linear: float = 0.5,
                    max_angular: float = 2.0, hold_s: float = 1.0,
                    stop_probability: float = 0.2) -> list[Twist]:
    """Seeded random twists, each held ``hold_s``; some are stops (0, 0)."""
    rng = np.random.default_rng(seed)
    out: list[Twist] = []
    per = max(1, round(hold_s * rate_hz))
    while len(out) < round(seconds * rate_hz):
        if rng.random() < stop_probability:
            twist = (0.0, 0.0)
        else:
            twist = (float(rng.uniform(-max_linear, max_linear)),
                     float(rng.uniform(-max_angular, max_angular)))
        out.extend([twist] * per)
    return out[: round(seconds * rate_hz)]


def circle_centre_drift(samples: Sequence[Sample]) -> tuple[float, float]:
    """(revolutions, metres the turning centre moved per revolution) of a spin in place.

    The centre of each whole revolution is the mean position over it; the drift is how far the
    last revolution's centre lies from the first's, per revolution in between.
    """
    yaw = np.array([s.yaw for s in samples]) - samples[0].yaw
    xy = np.array([(s.x, s.y) for s in samples])
    turns = np.floor(np.abs(yaw) / (2 * math.pi)).astype(int)
    revolutions = abs(yaw[-1]) / (2 * math.pi)
    whole = int(turns.max())
    if whole < 2:
        raise ValueError(f"a spin of {revolutions:.2f} revolutions has fewer than 2 whole ones")
    first = xy[turns == 0].mean(axis=0)
    last = xy[turns == whole - 1].mean(axis=0)
    return revolutions, float(np.linalg.norm(last - first)) / (whole - 1)
