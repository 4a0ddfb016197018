"""The robot's part of an observation: odometry and wheel joint states, as ROS publishes them.

Module-level so that code without a simulator (the ROS policy node) declares the same entries.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from smartcar_gym.envs.observation import Entry, Readings

MAX_SPEED_M_S = 5.0  # odometry twist bounds: far above the car's 0.84 m/s
MAX_TURN_RAD_S = 50.0
MAX_WHEEL_RAD_S = 200.0
TWO_PI = 2 * math.pi


def _heading(r: Readings) -> tuple[float, float]:
    return math.cos(r.odometry.theta), math.sin(r.odometry.theta)


def _wrapped(r: Readings) -> list[float]:
    return [(p + math.pi) % TWO_PI - math.pi for p in r.joint_position]


def robot_entries(wheel_joints: Sequence[str], position_bound_m: float,
                  position_doc: str = "2A") -> list[Entry]:
    """Odometry pose and twist (``odom`` -> ``base_link``) and each wheel's joint state.

    ``position_bound_m`` bounds the odometry position (``position_doc`` writes it in the docs).
    """
    joints = tuple(wheel_joints)
    b, doc = position_bound_m, position_doc
    return [
        Entry("odom_position", ("odom_x", "odom_y"), -b, b, "m",
              "odom pose x, y (``odom`` -> ``base_link``)",
              lambda r: (r.odometry.x, r.odometry.y), (f"-{doc}", doc)),
        Entry("odom_heading", ("odom_cos_yaw", "odom_sin_yaw"), -1.0, 1.0, "",
              "cos, sin of odom yaw", _heading),
        Entry("odom_linear", ("odom_v",), -MAX_SPEED_M_S, MAX_SPEED_M_S, "m/s",
              "odom twist linear.x", lambda r: (r.odometry.v,)),
        Entry("odom_angular", ("odom_omega",), -MAX_TURN_RAD_S, MAX_TURN_RAD_S, "rad/s",
              "odom twist angular.z", lambda r: (r.odometry.omega,)),
        Entry("wheel_positions", tuple(f"{j}.position" for j in joints), -math.pi, math.pi,
              "rad", "wheel joint positions, wrapped (left then right, front then back)",
              _wrapped),
        Entry("wheel_velocities", tuple(f"{j}.velocity" for j in joints), -MAX_WHEEL_RAD_S,
              MAX_WHEEL_RAD_S, "rad/s", "wheel joint velocities (same order)",
              lambda r: r.joint_velocity),
    ]
