"""Rigid transforms of URDF origins and link/joint frames in the root link frame."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from smartcar_gym.model.urdf import Origin, UrdfRobot


def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """Rotation matrix of URDF roll, pitch, yaw (fixed axes X, Y, Z: R = Rz Ry Rx)."""
    roll, pitch, yaw = rpy
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def quaternion_matrix(quaternion: Sequence[float] | np.ndarray) -> np.ndarray:
    """The rotation matrix of an (x, y, z, w) unit quaternion (pybullet's and ROS's order);
    an ``(N, 4)`` array of quaternions gives the ``(N, 3, 3)`` matrices (the same arithmetic
    per element)."""
    stacked = isinstance(quaternion, np.ndarray) and quaternion.ndim == 2
    x, y, z, w = quaternion.T if stacked else quaternion
    matrix = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    return np.ascontiguousarray(np.moveaxis(matrix, (0, 1), (1, 2))) if stacked else matrix


def matrix_quaternion(r: np.ndarray) -> tuple[float, float, float, float]:
    """The (x, y, z, w) unit quaternion of a rotation matrix (``quaternion_matrix``'s inverse)."""
    w = np.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2.0
    x = np.copysign(np.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2.0, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2.0, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2.0, r[1, 0] - r[0, 1])
    return float(x), float(y), float(z), float(w)


def transform(origin: Origin) -> np.ndarray:
    """4x4 homogeneous transform of an ``<origin>``."""
    result = np.eye(4)
    result[:3, :3] = rpy_matrix(origin.rpy)
    result[:3, 3] = origin.xyz
    return result


def link_frames(robot: UrdfRobot) -> dict[str, np.ndarray]:
    """Pose (4x4) of every link frame in the root link frame, at zero joint positions."""
    frames = {robot.base_link: np.eye(4)}
    by_parent: dict[str, list[str]] = {}
    for joint in robot.joints.values():
        by_parent.setdefault(joint.parent, []).append(joint.name)
    pending = [robot.base_link]
    while pending:
        parent = pending.pop()
        for name in by_parent.get(parent, []):
            joint = robot.joints[name]
            frames[joint.child] = frames[parent] @ transform(joint.origin)
            pending.append(joint.child)
    return frames


def joint_axis_in_base(robot: UrdfRobot, joint_name: str) -> np.ndarray:
    """Unit axis of a joint expressed in the root link frame."""
    joint = robot.joints[joint_name]
    rotation = link_frames(robot)[joint.child][:3, :3]
    axis = rotation @ np.asarray(joint.axis, dtype=float)
    return axis / np.linalg.norm(axis)
