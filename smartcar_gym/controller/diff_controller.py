"""The host side of the ArbotiX base: ``arbotix_python``'s ``DiffController``.

``cmd_vel`` sets the wheel targets; each ``update`` is one firing of the upstream controller,
in upstream order: odometry, (publish), command timeout, then in hardware mode the slew-limited
wheel speeds to write to the board. Nothing here talks to a simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from smartcar_gym.controller.config import ArbotixConfig

Mode = Literal["hardware", "sim"]
HARDWARE: Mode = "hardware"  # the real path: encoders, board PID, motors
KINEMATIC: Mode = "sim"  # the driver's `sim: true`: the base follows the commanded twist
MODES: tuple[Mode, ...] = (HARDWARE, KINEMATIC)
FRAMES_PER_S = 30.0  # upstream divides m/s by 30.0 to get ticks per frame


def _ns(t_s: float) -> int:
    """Seconds to integer nanoseconds, as rospy.Time/Duration compare them."""
    return round(t_s * 1e9)


@dataclass(frozen=True)
class Odometry:
    """One ``odom`` message: planar pose in ``frame_id``, twist in ``child_frame_id``.

    ``theta`` is never wrapped (as upstream). ``v``/``omega`` are the commanded twist in sim
    mode and the encoder-measured one in hardware mode.
    """

    stamp_s: float
    frame_id: str
    child_frame_id: str
    x: float
    y: float
    theta: float
    v: float
    omega: float

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        """Orientation ``(x, y, z, w)`` = ``(0, 0, sin(theta/2), cos(theta/2))``."""
        return 0.0, 0.0, math.sin(self.theta / 2.0), math.cos(self.theta / 2.0)

    def as_ros_dict(self) -> dict[str, Any]:
        """The message as a nested dict shaped like ``nav_msgs/Odometry`` (zero covariances)."""
        ns = _ns(self.stamp_s)
        qx, qy, qz, qw = self.quaternion
        return {
            "header": {
                "stamp": {"secs": ns // 1_000_000_000, "nsecs": ns % 1_000_000_000},
                "frame_id": self.frame_id,
            },
            "child_frame_id": self.child_frame_id,
            "pose": {
                "pose": {
                    "position": {"x": self.x, "y": self.y, "z": 0.0},
                    "orientation": {"x": qx, "y": qy, "z": qz, "w": qw},
                },
                "covariance": [0.0] * 36,
            },
            "twist": {
                "twist": {
                    "linear": {"x": self.v, "y": 0.0, "z": 0.0},
                    "angular": {"x": 0.0, "y": 0.0, "z": self.omega},
                },
                "covariance": [0.0] * 36,
            },
        }


class DiffController:
    """``arbotix_python``'s ``diff_controller`` with its state kept inspectable.

    Call ``update`` once per controller period (``1/config.rate_hz``); upstream fires on the
    first driver-loop tick strictly after ``t_next``, which is the caller's business here.

    Attributes:
        v_des_left, v_des_right: hardware targets, ticks/frame (int, truncated toward zero).
        v_left, v_right: slew-limited speeds last written, ticks/frame.
        last_write: ``(v_left, v_right)`` written by the latest ``update``; ``None`` if it wrote
            nothing (sim mode, or an encoder read failure).
        enc_left, enc_right: encoder counts at the previous update (``None`` before the first).
        dx, dr: sim mode: the commanded twist; hardware: the measured one (m/s, rad/s).
        then, last_cmd: times (s) of the previous update and of the latest ``cmd_vel``.
    """

    def __init__(self, config: ArbotixConfig, mode: Mode, now_s: float = 0.0) -> None:
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        self.config = config
        self.mode: Mode = mode
        self.max_accel = config.max_accel
        self.x = self.y = self.theta = 0.0
        self.dx = self.dr = 0.0
        self.v_des_left = self.v_des_right = 0
        self.v_left = self.v_right = 0
        self.enc_left: int | None = None
        self.enc_right: int | None = None
        self.last_write: tuple[int, int] | None = None
        self.then = float(now_s)
        self.last_cmd = float(now_s)
        self.odometry = self._odometry(now_s)

    def cmd_vel(self, linear_x: float, angular_z: float, now_s: float) -> None:
        """A ``geometry_msgs/Twist`` on ``cmd_vel``: only ``linear.x`` and ``angular.z`` count."""
        if not (math.isfinite(linear_x) and math.isfinite(angular_z)):
            raise ValueError(f"cmd_vel must be finite, got ({linear_x!r}, {angular_z!r})")
        self.last_cmd = float(now_s)
        if self.mode == KINEMATIC:
            self.dx, self.dr = float(linear_x), float(angular_z)
            return
        width, ticks = self.config.base_width_m, self.config.ticks_meter
        # Same operations and order as upstream; int() truncates toward zero.
        self.v_des_left = int(((linear_x - (angular_z * width / 2.0)) * ticks) / FRAMES_PER_S)
        self.v_des_right = int(((linear_x + (angular_z * width / 2.0)) * ticks) / FRAMES_PER_S)

    def update(self, now_s: float, encoders: tuple[int, int] | None = None) -> Odometry:
        """One controller firing at ``now_s``; ``encoders`` = the board's (left, right) counts.

        In hardware mode ``encoders=None`` is a failed read: as upstream, only ``then`` moves,
        and odometry, timeout and motor write are skipped.
        """
        elapsed = now_s - self.then
        if elapsed < 0:
            raise ValueError(f"time went backwards: update at {now_s} s after {self.then} s")
        self.then = float(now_s)
        self.last_write = None
        if self.mode == KINEMATIC:
            self._integrate_twist(elapsed)
        elif encoders is None:
            return self.odometry
        else:
            self._integrate_encoders(encoders, elapsed)
        self.odometry = self._odometry(now_s)
        if _ns(now_s) > _ns(self.last_cmd) + _ns(self.config.timeout_s):
            self.v_des_left = self.v_des_right = 0  # no effect in sim mode, as upstream
        if self.mode == HARDWARE:
            self.v_left = self._ramp(self.v_left, self.v_des_left)
            self.v_right = self._ramp(self.v_right, self.v_des_right)
            self.last_write = (self.v_left, self.v_right)
        return self.odometry

    def _integrate_twist(self, elapsed: float) -> None:
        """Sim mode: Euler step with the latest commanded twist (heading at the step start)."""
        self.x += math.cos(self.theta) * self.dx * elapsed
        self.y += math.sin(self.theta) * self.dx * elapsed
        self.theta += self.dr * elapsed

    def _integrate_encoders(self, encoders: tuple[int, int], elapsed: float) -> None:
        """Hardware mode: dead reckoning from encoder deltas, with upstream's theta - dtheta."""
        left, right = encoders
        if self.enc_left is None or self.enc_right is None:
            d_left = d_right = 0.0
        else:  # plain int deltas, as upstream: a wrapped 32-bit counter (~524 km) would jump
            d_left = (left - self.enc_left) / self.config.ticks_meter
            d_right = (right - self.enc_right) / self.config.ticks_meter
        self.enc_left, self.enc_right = left, right
        d = (d_left + d_right) / 2
        th = (d_right - d_left) / self.config.base_width_m
        self.dx = d / elapsed if elapsed > 0 else 0.0  # upstream would divide by zero
        self.dr = th / elapsed if elapsed > 0 else 0.0
        if d != 0:
            # Upstream's rotation of (d cos th, -d sin th): a step along theta - th.
            x = math.cos(th) * d
            y = -math.sin(th) * d
            self.x = self.x + (math.cos(self.theta) * x - math.sin(self.theta) * y)
            self.y = self.y + (math.sin(self.theta) * x + math.cos(self.theta) * y)
        if th != 0:
            self.theta = self.theta + th

    def _ramp(self, v: int, v_des: int) -> int:
        """Slew ``v`` toward ``v_des`` by at most ``max_accel`` ticks/frame."""
        if v < v_des:
            return min(v + self.max_accel, v_des)
        return max(v - self.max_accel, v_des)

    def _odometry(self, now_s: float) -> Odometry:
        c = self.config
        return Odometry(
            float(now_s), c.odom_frame_id, c.base_frame_id,
            self.x, self.y, self.theta, self.dx, self.dr,
        )
