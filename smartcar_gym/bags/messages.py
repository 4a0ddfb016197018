"""ROS 1 messages from the robot's state, and what the policy reads back from messages.

The builders write the messages ``arbotix_driver`` publishes (``odom``, the ``odom ->
base_link`` transform) plus the wheel ``joint_states``, ``cmd_vel``, a goal and ``/clock``. They
take a ``MessageTypes``: rospy's classes for the live bridge (``RospyTypes``) or a rosbags
typestore for bag files written without ROS (``RosbagsTypes``), so both carry the same fields.

The readers turn received messages into what ``smartcar_gym.envs.state.CarState`` holds,
refusing malformed ones with a ``MessageError`` that says what is wrong.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from smartcar_gym.controller import Odometry
from smartcar_gym.envs.robots.smartcar import JointStates, pose_from
from smartcar_gym.model.kinematics import quaternion_matrix

NS_PER_S = 1_000_000_000
ZERO_COVARIANCE = np.zeros(36)
GROUND_TRUTH_FRAME = "world"  # stage_ros and Gazebo's p3d publish base_pose_ground_truth
GROUND_TRUTH_TOPIC = "base_pose_ground_truth"
QUATERNION_NORM_TOLERANCE = 1e-3  # |q| - 1; a planar pose from odometry has |q| = 1 to 1e-16


class MessageTypes(Protocol):
    """Makes ROS 1 messages by type (``"nav_msgs/Odometry"``) and stamps from ns."""

    def __call__(self, msg_type: str, /, **fields: Any) -> Any: ...

    def time(self, ns: int) -> Any: ...


class RospyTypes:
    """rospy's message classes (Debian's python3-*-msgs) and ``rospy.Time``."""

    def __init__(self, time_class: Any) -> None:
        self._time = time_class
        self._classes: dict[str, Any] = {}

    def __call__(self, msg_type: str, /, **fields: Any) -> Any:
        cls = self._classes.get(msg_type)
        if cls is None:
            package, _, message = msg_type.partition("/")
            cls = self._classes[msg_type] = getattr(importlib.import_module(f"{package}.msg"),
                                                    message)
        return cls(**fields)

    def time(self, ns: int) -> Any:
        return self._time(ns // NS_PER_S, ns % NS_PER_S)


class RosbagsTypes:
    """A rosbags ROS 1 typestore (no ROS installation needed)."""

    def __init__(self, typestore: Any) -> None:
        self.typestore = typestore

    def __call__(self, msg_type: str, /, **fields: Any) -> Any:
        package, _, message = msg_type.partition("/")
        return self.typestore.types[f"{package}/msg/{message}"](**fields)

    def time(self, ns: int) -> Any:
        return self("builtin_interfaces/Time", sec=ns // NS_PER_S, nanosec=ns % NS_PER_S)


# -- building ----------------------------------------------------------------------------------
def header(types: MessageTypes, stamp_ns: int, frame_id: str) -> Any:
    return types("std_msgs/Header", seq=0, stamp=types.time(stamp_ns), frame_id=frame_id)


def _vector(types: MessageTypes, x: float, y: float, z: float) -> Any:
    return types("geometry_msgs/Vector3", x=float(x), y=float(y), z=float(z))


def _quaternion(types: MessageTypes, q: Sequence[float]) -> Any:
    return types("geometry_msgs/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3])


def _pose(types: MessageTypes, x: float, y: float, q: Sequence[float]) -> Any:
    return types("geometry_msgs/Pose",
                 position=types("geometry_msgs/Point", x=float(x), y=float(y), z=0.0),
                 orientation=_quaternion(types, q))


def odometry_message(types: MessageTypes, odom: Odometry, stamp_ns: int) -> Any:
    """``nav_msgs/Odometry`` as ``diff_controller`` publishes it (zero covariances)."""
    pose = types("geometry_msgs/PoseWithCovariance",
                 pose=_pose(types, odom.x, odom.y, odom.quaternion),
                 covariance=ZERO_COVARIANCE.copy())
    twist = types("geometry_msgs/TwistWithCovariance",
                  twist=twist_message(types, odom.v, odom.omega),
                  covariance=ZERO_COVARIANCE.copy())
    return types("nav_msgs/Odometry", header=header(types, stamp_ns, odom.frame_id),
                 child_frame_id=odom.child_frame_id, pose=pose, twist=twist)


def transform_message(types: MessageTypes, odom: Odometry, stamp_ns: int) -> Any:
    """``tf2_msgs/TFMessage`` with the ``odom -> base_link`` transform of ``odom``."""
    transform = types("geometry_msgs/Transform",
                      translation=_vector(types, odom.x, odom.y, 0.0),
                      rotation=_quaternion(types, odom.quaternion))
    stamped = types("geometry_msgs/TransformStamped",
                    header=header(types, stamp_ns, odom.frame_id),
                    child_frame_id=odom.child_frame_id, transform=transform)
    return types("tf2_msgs/TFMessage", transforms=[stamped])


def ground_truth_message(types: MessageTypes, pose: tuple[Sequence[float], Sequence[float]],
                         velocity: tuple[Sequence[float], Sequence[float]], stamp_ns: int,
                         child_frame_id: str) -> Any:
    """``nav_msgs/Odometry`` of the simulator's true pose in ``world`` (``GROUND_TRUTH_FRAME``).

    ``pose``: position and (x, y, z, w) orientation of the base link; ``velocity``: linear and
    angular velocity in the world frame, written in the base link frame as ``Odometry`` asks.
    The robot starts at the world's origin, where the odometry starts too.
    """
    position, q = pose
    rotation = quaternion_matrix(q).T  # world -> base link
    linear, angular = (rotation @ np.asarray(v, dtype=float) for v in velocity)
    body_pose = types("geometry_msgs/Pose",
                      position=types("geometry_msgs/Point", x=float(position[0]),
                                     y=float(position[1]), z=float(position[2])),
                      orientation=_quaternion(types, [float(v) for v in q]))
    twist = types("geometry_msgs/Twist", linear=_vector(types, *linear),
                  angular=_vector(types, *angular))
    return types(
        "nav_msgs/Odometry", header=header(types, stamp_ns, GROUND_TRUTH_FRAME),
        child_frame_id=child_frame_id,
        pose=types("geometry_msgs/PoseWithCovariance", pose=body_pose,
                   covariance=ZERO_COVARIANCE.copy()),
        twist=types("geometry_msgs/TwistWithCovariance", twist=twist,
                    covariance=ZERO_COVARIANCE.copy()))


def joint_state_message(types: MessageTypes, states: JointStates, stamp_ns: int) -> Any:
    """``sensor_msgs/JointState`` of the wheel joints (rad, rad/s, N m)."""
    return types("sensor_msgs/JointState", header=header(types, stamp_ns, ""),
                 name=list(states.name),
                 position=np.asarray(states.position, dtype=np.float64),
                 velocity=np.asarray(states.velocity, dtype=np.float64),
                 effort=np.asarray(states.effort, dtype=np.float64))


def twist_message(types: MessageTypes, linear_x: float, angular_z: float) -> Any:
    """``geometry_msgs/Twist`` with ``linear.x`` and ``angular.z`` (what a base uses)."""
    return types("geometry_msgs/Twist", linear=_vector(types, linear_x, 0.0, 0.0),
                 angular=_vector(types, 0.0, 0.0, angular_z))


def goal_message(types: MessageTypes, goal: Sequence[float], stamp_ns: int,
                 frame_id: str) -> Any:
    """``geometry_msgs/PoseStamped`` at ``goal`` (x, y), facing +x, as rviz's 2D Nav Goal."""
    return types("geometry_msgs/PoseStamped", header=header(types, stamp_ns, frame_id),
                 pose=_pose(types, goal[0], goal[1], (0.0, 0.0, 0.0, 1.0)))


def clock_message(types: MessageTypes, now_ns: int) -> Any:
    """``rosgraph_msgs/Clock``."""
    return types("rosgraph_msgs/Clock", clock=types.time(now_ns))


# -- reading -----------------------------------------------------------------------------------
class MessageError(ValueError):
    """A received message that cannot be used; the text says what is wrong with it."""


def stamp_ns(stamp: Any) -> int:
    """A ROS time (rospy's ``secs``/``nsecs`` or rosbags' ``sec``/``nanosec``) in ns."""
    if hasattr(stamp, "secs"):
        return int(stamp.secs) * NS_PER_S + int(stamp.nsecs)
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def bare_frame(frame_id: str) -> str:
    """A frame id without tf1's leading slash (rviz configs still write ``/odom``)."""
    return frame_id.lstrip("/")


def _finite(what: str, **values: float) -> None:
    bad = {k: v for k, v in values.items() if not math.isfinite(v)}
    if bad:
        listed = ", ".join(f"{k}={v!r}" for k, v in bad.items())
        raise MessageError(f"{what} has non-finite values ({listed})")


@dataclass(frozen=True)
class OdometryReading:
    """What the observation reads of an ``odom`` message (``CarState.odometry``'s row)."""

    x: float
    y: float
    theta: float  # yaw from the quaternion, in [-pi, pi]
    v: float
    omega: float
    frame_id: str
    stamp_ns: int


def read_odometry(msg: Any) -> OdometryReading:
    """The planar pose and twist of a ``nav_msgs/Odometry``; MessageError if malformed."""
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    linear, angular = msg.twist.twist.linear, msg.twist.twist.angular
    _finite("odometry", x=p.x, y=p.y, qx=q.x, qy=q.y, qz=q.z, qw=q.w, v=linear.x,
            omega=angular.z)
    norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise MessageError(f"odometry orientation is not a unit quaternion (|q| = {norm:.6g})")
    pose = pose_from((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
    return OdometryReading(p.x, p.y, pose.yaw, linear.x, angular.z,
                           bare_frame(msg.header.frame_id), stamp_ns(msg.header.stamp))


@dataclass(frozen=True)
class WheelReading:
    """The wheel joints' positions and velocities, in the observation's wheel order."""

    position: list[float]
    velocity: list[float]
    stamp_ns: int


def read_wheels(msg: Any, joints: Sequence[str]) -> WheelReading:
    """Positions and velocities of ``joints`` from a ``sensor_msgs/JointState``."""
    names = list(msg.name)
    missing = [j for j in joints if j not in names]
    if missing:
        raise MessageError(f"joint_states has no {', '.join(missing)} (it names "
                           f"{', '.join(names) or 'no joint'})")
    if len(msg.position) != len(names) or len(msg.velocity) != len(names):
        raise MessageError(f"joint_states names {len(names)} joints but has "
                           f"{len(msg.position)} positions and {len(msg.velocity)} velocities")
    index = [names.index(j) for j in joints]
    position = [float(msg.position[i]) for i in index]
    velocity = [float(msg.velocity[i]) for i in index]
    _finite("joint_states", **{f"{j}.position": v for j, v in zip(joints, position, strict=True)},
            **{f"{j}.velocity": v for j, v in zip(joints, velocity, strict=True)})
    return WheelReading(position, velocity, stamp_ns(msg.header.stamp))


@dataclass(frozen=True)
class GoalReading:
    """A goal position and the frame it was given in."""

    x: float
    y: float
    frame_id: str
    stamp_ns: int


def read_goal(msg: Any) -> GoalReading:
    """The position of a ``geometry_msgs/PoseStamped`` goal; MessageError if malformed."""
    p = msg.pose.position
    _finite("goal", x=p.x, y=p.y)
    return GoalReading(float(p.x), float(p.y), bare_frame(msg.header.frame_id),
                       stamp_ns(msg.header.stamp))


def read_twist(msg: Any) -> tuple[float, float]:
    """``(linear.x, angular.z)`` of a ``geometry_msgs/Twist``; MessageError if not finite."""
    _finite("cmd_vel", linear_x=msg.linear.x, angular_z=msg.angular.z)
    return float(msg.linear.x), float(msg.angular.z)
