"""CDR (ROS 2's serialisation) of the per-step messages of a bag, packed with ``struct``.

A ROS 2 bag of an evaluation holds about seven messages per step; building each as a rosbags
message and serialising it costs more than simulating the step. These encoders write the same
bytes directly: XCDR1 little-endian (the 4-byte encapsulation header ``00 01 00 00``), every
primitive aligned to its size counted from the end of that header, which is what ``struct``'s
native mode does on a little-endian machine. ``tests/test_ros2_bag.py`` checks them byte for
byte against rosbags' own ``serialize_cdr``.
"""

from __future__ import annotations

import struct
import sys
from collections.abc import Sequence

import numpy as np

ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR_LE
AVAILABLE = sys.byteorder == "little"  # struct's native alignment is CDR's only there


def _string(text: str) -> tuple[str, list]:
    """Format and values of a CDR string: uint32 length (with the NUL), bytes, NUL."""
    data = text.encode() + b"\0"
    return f"I{len(data)}s", [len(data), data]


def _header(frame_id: str) -> tuple[str, list]:
    """``std_msgs/Header`` without its stamp values: (format, constant values after them)."""
    fmt, values = _string(frame_id)
    return "iI" + fmt, values


def _stamp(ns: int) -> tuple[int, int]:
    return ns // 1_000_000_000, ns % 1_000_000_000


ZERO_36 = (0.0,) * 36


class OdometryEncoder:
    """``nav_msgs/msg/Odometry`` with fixed frames and zero covariances."""

    def __init__(self, frame_id: str, child_frame_id: str) -> None:
        header, self._frame = _header(frame_id)
        child, self._child = _string(child_frame_id)
        self._struct = struct.Struct("@" + header + child + "3d4d36d3d3d36d")

    def __call__(self, stamp_ns: int, position: Sequence[float], orientation: Sequence[float],
                 linear: Sequence[float], angular: Sequence[float]) -> bytes:
        return ENCAPSULATION + self._struct.pack(
            *_stamp(stamp_ns), *self._frame, *self._child, *position, *orientation, *ZERO_36,
            *linear, *angular, *ZERO_36)


class TwistEncoder:
    """``geometry_msgs/msg/Twist``."""

    _struct = struct.Struct("@6d")

    def __call__(self, linear_x: float, angular_z: float) -> bytes:
        return ENCAPSULATION + self._struct.pack(linear_x, 0.0, 0.0, 0.0, 0.0, angular_z)


class JointStateEncoder:
    """``sensor_msgs/msg/JointState`` of fixed joints (empty frame id)."""

    def __init__(self, names: Sequence[str]) -> None:
        header, self._frame = _header("")
        n = len(names)
        fmt, self._names = "I", [n]
        for name in names:
            f, v = _string(name)
            fmt += f
            self._names += v
        self._struct = struct.Struct(f"@{header}{fmt}I{n}dI{n}dI{n}d")
        self._n = n

    def __call__(self, stamp_ns: int, position: Sequence[float], velocity: Sequence[float],
                 effort: Sequence[float]) -> bytes:
        n = self._n
        return ENCAPSULATION + self._struct.pack(
            *_stamp(stamp_ns), *self._frame, *self._names, n, *position, n, *velocity, n,
            *effort)


class TransformsEncoder:
    """``tf2_msgs/msg/TFMessage`` of fixed (parent, child) pairs, all stamped alike."""

    def __init__(self, edges: Sequence[tuple[str, str]]) -> None:
        fmt = "I"
        self._frames = []
        for parent, child in edges:
            header, frame = _header(parent)
            child_fmt, child_values = _string(child)
            fmt += header + child_fmt + "3d4d"
            self._frames.append(frame + child_values)
        self._struct = struct.Struct("@" + fmt)
        self._count = len(edges)

    def __call__(self, stamp_ns: int,
                 poses: Sequence[tuple[Sequence[float], Sequence[float]]]) -> bytes:
        """``poses``: (translation, (x, y, z, w) rotation) of each edge, in order."""
        sec, nanosec = _stamp(stamp_ns)
        values: list = [self._count]
        for frame, (translation, rotation) in zip(self._frames, poses, strict=True):
            values += [sec, nanosec, *frame, *translation, *rotation]
        return ENCAPSULATION + self._struct.pack(*values)


class LaserScanEncoder:
    """``sensor_msgs/msg/LaserScan`` (float32 ranges, no intensities)."""

    def __init__(self, frame_id: str) -> None:
        header, self._frame = _header(frame_id)
        self._head = struct.Struct("@" + header + "7fI")
        self._frame_fmt = header

    def __call__(self, stamp_ns: int, angle_min: float, angle_max: float,
                 angle_increment: float, time_increment: float, scan_time: float,
                 range_min: float, range_max: float, ranges: np.ndarray) -> bytes:
        ranges = np.ascontiguousarray(ranges, dtype="<f4")
        head = self._head.pack(*_stamp(stamp_ns), *self._frame, angle_min, angle_max,
                               angle_increment, time_increment, scan_time, range_min,
                               range_max, len(ranges))
        # the float32 ranges follow the 4-aligned count directly; the intensities' count after
        return ENCAPSULATION + head + ranges.tobytes() + struct.pack("<I", 0)
