"""Evaluated episodes as a ROS 2 bag (rosbag2: MCAP or sqlite3 storage), without ROS 2.

``smartcar-eval --bag DIR --bag-format ros2`` writes, from the episodes the evaluation runs
(``smartcar_gym.viewers.capture``), a rosbag2 folder ``DIR`` (``metadata.yaml`` and
``DIR.mcap``, or ``DIR.db3`` with ``--bag-storage sqlite3``) holding CDR-encoded messages:

======================== ============================ ============================================
topic                    type                         what
======================== ============================ ============================================
/robot_description       std_msgs/msg/String          the URDF, once, transient_local (latched)
/tf_static               tf2_msgs/msg/TFMessage       the URDF's fixed joints and world -> odom
                                                      (the episode's start pose), transient_local
/tf                      tf2_msgs/msg/TFMessage       odom -> base_link and the wheel joints
/odom                    nav_msgs/msg/Odometry        the controller's odometry
/base_pose_ground_truth  nav_msgs/msg/Odometry        the simulator's true pose, in ``world``
/joint_states            sensor_msgs/msg/JointState   wheel positions, velocities, efforts
/cmd_vel                 geometry_msgs/msg/Twist      the command sent at each step, stamped
                                                      ``COMMAND_LAG_NS`` after the update it
                                                      answers (it acts at the next one)
/scan                    sensor_msgs/msg/LaserScan    SmartCarNav-v0's laser
/goal_pose               geometry_msgs/msg/PoseStamped each episode's goal (Nav2's topic)
======================== ============================ ============================================

Stamps are simulated time as in the ROS 1 bags (``smartcar_gym.bags.ros1``): episode ``i``
starts ``EPISODE_GAP_S`` after the end of episode ``i - 1``, the first at ``START_S``. Written
by ``rosbags`` (its ``rosbag2.Writer``, metadata version 8: ``ros2 bag`` of Iron and newer);
Foxglove opens the ``.mcap`` file.
"""

from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.bags import cdr
from smartcar_gym.bags import messages as m
from smartcar_gym.bags.ros1 import COMMAND_LAG_NS, EPISODE_GAP_S, ROS_EXTRA, START_S
from smartcar_gym.envs.robots.smartcar import pose_from
from smartcar_gym.model.kinematics import matrix_quaternion, quaternion_matrix, rpy_matrix
from smartcar_gym.model.urdf import UrdfRobot, parse_urdf
from smartcar_gym.viewers.capture import Episode, Frame, Scene

STORAGES = ("mcap", "sqlite3")
BAG_VERSION = 8
TOPICS = {  # topic -> message type, in the order the connections are made
    "/robot_description": "std_msgs/msg/String",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/odom": "nav_msgs/msg/Odometry",
    f"/{m.GROUND_TRUTH_TOPIC}": "nav_msgs/msg/Odometry",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/cmd_vel": "geometry_msgs/msg/Twist",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/goal_pose": "geometry_msgs/msg/PoseStamped",
}
LATCHED = ("/robot_description", "/tf_static")


def missing_library() -> str | None:
    """What is missing to write ROS 2 bags (None if nothing is): one line naming the extra."""
    from smartcar_gym.extras import missing_modules

    missing = missing_modules(("rosbags",))
    if missing:
        return f"{', '.join(missing)} not installed; --bag needs the ros extra: {ROS_EXTRA}"
    return None


def typestore() -> Any:
    """rosbags' ROS 2 (Jazzy) typestore."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


class Ros2Types(m.RosbagsTypes):
    """``bags.messages``' builders with ROS 2 messages: a ``std_msgs/Header`` has no ``seq``."""

    def __init__(self, typestore: Any) -> None:
        super().__init__(typestore)
        self._classes: dict[str, Any] = {}

    def __call__(self, msg_type: str, /, **fields: Any) -> Any:
        cls = self._classes.get(msg_type)
        if cls is None:
            package, _, message = msg_type.partition("/")
            cls = self._classes[msg_type] = self.typestore.types[f"{package}/msg/{message}"]
        if msg_type == "std_msgs/Header":
            fields.pop("seq", None)
        return cls(**fields)


def _qos(latched: bool) -> Any:
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    never = QosTime(sec=0, nsec=0)
    return Qos(history=QosHistory.KEEP_LAST, depth=1 if latched else 10,
               reliability=QosReliability.RELIABLE,
               durability=QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
               deadline=never, lifespan=never, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=never, avoid_ros_namespace_conventions=False)


@dataclass(frozen=True)
class _Encoders:
    odom: cdr.OdometryEncoder
    truth: cdr.OdometryEncoder
    tf: cdr.TransformsEncoder
    joints: cdr.JointStateEncoder
    twist: cdr.TwistEncoder
    scan: cdr.LaserScanEncoder


class Ros2BagSink:
    """Writes ``Episode`` objects, in order, to a rosbag2 folder that appears at ``path``
    complete when ``close`` is called (``discard`` after an error leaves nothing)."""

    def __init__(self, path: str | os.PathLike, storage: str = "mcap") -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        if not cdr.AVAILABLE:
            raise RuntimeError("ROS 2 bags are written on little-endian machines only")
        if storage not in STORAGES:
            raise ValueError(f"bag storage must be one of {', '.join(STORAGES)}, got "
                             f"{storage!r}")
        self.path = Path(path)
        if self.path.exists():
            raise FileExistsError(f"{self.path} exists; a ROS 2 bag is a new folder (remove "
                                  "it or pick another name)")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # written as <parent>/.<name>.partial/<name> (the storage file is named after the
        # folder), moved to <parent>/<name> when complete
        self._scratch = self.path.with_name(f".{self.path.name}.partial")
        shutil.rmtree(self._scratch, ignore_errors=True)
        self._scratch.mkdir()
        self._partial = self._scratch / self.path.name
        self.store = typestore()
        self.types = Ros2Types(self.store)
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        self._writer = Writer(self._partial, version=BAG_VERSION, storage_plugin=plugin)
        self._writer.open()
        self._connections: dict[str, Any] = {}
        self._offset_ns = round(START_S * m.NS_PER_S)
        self._robot: UrdfRobot | None = None
        self._moving: list[tuple] = []  # (name, parent, child, xyz, origin quaternion, axis)
        self._encode: _Encoders | None = None
        self.count = 0
        self.episodes = 0
        self._closed = False

    def __call__(self, episode: Episode) -> None:
        self.write(episode)

    def _write(self, topic: str, msg: Any, time_ns: int) -> None:
        msgtype = TOPICS[topic]
        if topic not in self._connections:
            self._connections[topic] = self._writer.add_connection(
                topic, msgtype, typestore=self.store,
                offered_qos_profiles=[_qos(topic in LATCHED)])
        self._writer.write(self._connections[topic], time_ns,
                           bytes(self.store.serialize_cdr(msg, msgtype)))
        self.count += 1

    def _write_cdr(self, topic: str, data: bytes, time_ns: int) -> None:
        if topic not in self._connections:
            self._connections[topic] = self._writer.add_connection(
                topic, TOPICS[topic], typestore=self.store,
                offered_qos_profiles=[_qos(topic in LATCHED)])
        self._writer.write(self._connections[topic], time_ns, data)
        self.count += 1

    def write(self, episode: Episode) -> None:
        """Write one whole episode after the ones before it."""
        types, scene, start = self.types, episode.scene, self._offset_ns
        if self._robot is None:
            self._start(scene, episode.frames[0])
            self._write("/robot_description", types("std_msgs/String", data=scene.urdf), start)
        self._write("/tf_static", self._static_transforms(scene, episode.frames[0], start),
                    start)
        self._write("/goal_pose", m.goal_message(types, scene.goal, start, m.GROUND_TRUTH_FRAME),
                    start)
        encode = self._encode
        for i, frame in enumerate(episode.frames):
            now = start + frame.time_ns
            if i > 0:  # the command the step sent, just after the update before it
                sent = start + episode.frames[i - 1].time_ns + COMMAND_LAG_NS
                self._write_cdr("/cmd_vel", encode.twist(*frame.command), sent)
            odom = frame.odometry
            quaternion = odom.quaternion
            self._write_cdr("/odom", encode.odom(now, (odom.x, odom.y, 0.0), quaternion,
                                                 (odom.v, 0.0, 0.0), (0.0, 0.0, odom.omega)),
                            now)
            self._write_cdr("/tf", encode.tf(now, [((odom.x, odom.y, 0.0), quaternion),
                                                   *self._wheel_poses(frame)]), now)
            joints = frame.joints
            self._write_cdr("/joint_states", encode.joints(now, joints.position.tolist(),
                                                           joints.velocity.tolist(),
                                                           joints.effort.tolist()), now)
            rotation = quaternion_matrix(frame.orientation).T  # world -> base_link
            self._write_cdr(f"/{m.GROUND_TRUTH_TOPIC}", encode.truth(
                now, frame.position, frame.orientation,
                (rotation @ np.asarray(frame.linear_velocity)).tolist(),
                (rotation @ np.asarray(frame.angular_velocity)).tolist()), now)
            scan = frame.scan
            if scan is not None:
                self._write_cdr("/scan", encode.scan(
                    start + round(scan.stamp_s * m.NS_PER_S), scan.angle_min, scan.angle_max,
                    scan.angle_increment, scan.time_increment, scan.scan_time, scan.range_min,
                    scan.range_max, scan.ranges), now)
        self._offset_ns = start + episode.frames[-1].time_ns + round(EPISODE_GAP_S * m.NS_PER_S)
        self.episodes += 1

    def _start(self, scene: Scene, first: Frame) -> None:
        """The model's joints and the encoders of the per-step messages (fixed frames)."""
        self._robot = parse_urdf(scene.urdf, scene.robot_name)
        self._moving = [
            (j.name, j.parent, j.child, j.origin.xyz, matrix_quaternion(rpy_matrix(j.origin.rpy)),
             tuple(np.asarray(j.axis, dtype=float) / np.linalg.norm(j.axis)))
            for j in self._robot.joints.values() if j.type in ("continuous", "revolute")]
        edges = [(scene.odom_frame, scene.base_frame)] + [(p, c) for _, p, c, *_ in self._moving]
        self._encode = _Encoders(
            odom=cdr.OdometryEncoder(scene.odom_frame, scene.base_frame),
            truth=cdr.OdometryEncoder(m.GROUND_TRUTH_FRAME, scene.base_frame),
            tf=cdr.TransformsEncoder(edges), joints=cdr.JointStateEncoder(first.joints.name),
            twist=cdr.TwistEncoder(),
            scan=cdr.LaserScanEncoder(first.scan.frame_id if first.scan is not None
                                      else scene.laser_frame))

    def _transform(self, parent: str, child: str, xyz: Any, quaternion: Any,
                   stamp_ns: int) -> Any:
        types = self.types
        return types("geometry_msgs/TransformStamped",
                     header=m.header(types, stamp_ns, parent), child_frame_id=child,
                     transform=types("geometry_msgs/Transform",
                                     translation=types("geometry_msgs/Vector3",
                                                       x=float(xyz[0]), y=float(xyz[1]),
                                                       z=float(xyz[2])),
                                     rotation=types("geometry_msgs/Quaternion",
                                                    x=float(quaternion[0]),
                                                    y=float(quaternion[1]),
                                                    z=float(quaternion[2]),
                                                    w=float(quaternion[3]))))

    def _static_transforms(self, scene: Scene, first: Frame, stamp_ns: int) -> Any:
        """The URDF's fixed joints (robot_state_publisher's /tf_static) and world -> odom."""
        x, y, _ = first.position
        yaw = pose_from(first.position, first.orientation).yaw
        transforms = [self._transform(m.GROUND_TRUTH_FRAME, scene.odom_frame, (x, y, 0.0),
                                      (0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)), stamp_ns)]
        for joint in self._robot.joints.values():
            if joint.type == "fixed":
                transforms.append(self._transform(joint.parent, joint.child, joint.origin.xyz,
                                                  matrix_quaternion(rpy_matrix(joint.origin.rpy)),
                                                  stamp_ns))
        return self.types("tf2_msgs/TFMessage", transforms=transforms)

    def _wheel_poses(self, frame: Frame) -> list[tuple[Any, tuple[float, ...]]]:
        """The moving joints at their positions (robot_state_publisher's /tf)."""
        positions = dict(zip(frame.joints.name, frame.joints.position.tolist(), strict=True))
        out = []
        for name, _, _, xyz, origin, axis in self._moving:
            half = positions.get(name, 0.0) / 2.0
            s = math.sin(half)
            out.append((xyz, _multiply(origin, (axis[0] * s, axis[1] * s, axis[2] * s,
                                                 math.cos(half)))))
        return out

    def close(self) -> None:
        """Finish the bag: the folder appears at ``path``. Idempotent: after ``close`` or
        ``discard`` it does nothing; if finishing fails, nothing is left and the error is
        raised."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()
            os.replace(self._partial, self.path)
            self._scratch.rmdir()
        except BaseException:
            shutil.rmtree(self._scratch, ignore_errors=True)
            raise

    def discard(self) -> None:
        """Stop without leaving a bag (after an error); does nothing once closed."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()
        except Exception:  # noqa: BLE001 (a half-written bag after the real error)
            pass
        shutil.rmtree(self._scratch, ignore_errors=True)


def _multiply(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    """The quaternion product ``a b`` ((x, y, z, w)): rotation ``b`` in frame ``a``."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)
