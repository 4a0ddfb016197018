"""The robot's part of an observation: odometry and wheel joint states, as ROS publishes them,
and the previous action: their entries and their columns over the cars' state.

Module-level so that code without a simulator (the ROS policy node) declares the same entries
and computes the same values from a state it fills from messages.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from smartcar_gym.envs.observation import Entry
from smartcar_gym.envs.state import split

MAX_SPEED_M_S = 5.0  # odometry twist bounds: far above the car's 0.84 m/s
MAX_TURN_RAD_S = 50.0
MAX_WHEEL_RAD_S = 200.0
TWO_PI = 2 * math.pi


def robot_entries(wheel_joints: Sequence[str], position_bound_m: float,
                  position_doc: str = "2A") -> list[Entry]:
    """Odometry pose and twist (``odom`` -> ``base_link``) and each wheel's joint state.

    ``position_bound_m`` bounds the odometry position (``position_doc`` writes it in the docs).
    """
    joints = tuple(wheel_joints)
    b, doc = position_bound_m, position_doc
    return [
        Entry("odom_position", ("odom_x", "odom_y"), -b, b, "m",
              "odom pose x, y (``odom`` -> ``base_link``)", (f"-{doc}", doc)),
        Entry("odom_heading", ("odom_cos_yaw", "odom_sin_yaw"), -1.0, 1.0, "",
              "cos, sin of odom yaw"),
        Entry("odom_linear", ("odom_v",), -MAX_SPEED_M_S, MAX_SPEED_M_S, "m/s",
              "odom twist linear.x"),
        Entry("odom_angular", ("odom_omega",), -MAX_TURN_RAD_S, MAX_TURN_RAD_S, "rad/s",
              "odom twist angular.z"),
        Entry("wheel_positions", tuple(f"{j}.position" for j in joints), -math.pi, math.pi,
              "rad", "wheel joint positions, wrapped (left then right, front then back)"),
        Entry("wheel_velocities", tuple(f"{j}.velocity" for j in joints), -MAX_WHEEL_RAD_S,
              MAX_WHEEL_RAD_S, "rad/s", "wheel joint velocities (same order)"),
    ]


def previous_action_entry() -> Entry:
    """The action of the previous step (zeros after reset), as the agent sent it."""
    return Entry("previous_action", ("prev_linear", "prev_angular"), -1.0, 1.0, "",
                 "previous action")


def heading(odometry: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cosine and sine of the odometry's heading (``odometry``: the state's, as
    ``Cars.values`` gives it: (N, 5) or one car's (5,))."""
    theta = odometry[..., 2]
    return np.cos(theta), np.sin(theta)


def robot_columns(cars: Any, cos: np.ndarray, sin: np.ndarray) -> dict[str, Any]:
    """The columns of ``robot_entries`` and ``previous_action_entry`` from ``cars``' state
    (``tasks.base.Cars``; ``cos``, ``sin``: ``heading`` of its odometry; a 2-D value holds
    one column a row; one car's values give numbers and rows)."""
    state, values = cars.state, cars.values
    x, y, _, v, w = split(values(state.odometry))
    return {
        "odom_position": (x, y),
        "odom_heading": (cos, sin),
        "odom_linear": (v,),
        "odom_angular": (w,),
        # Python's float % and numpy's are both fmod with the divisor's sign: the same bits
        "wheel_positions": [(p + math.pi) % TWO_PI - math.pi
                            for p in split(values(state.wheel_position))],
        "wheel_velocities": split(values(state.wheel_velocity)),
        "previous_action": split(values(state.previous_action)),
    }
