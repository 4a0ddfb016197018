"""One finished episode as plain arrays (``Packet``): what a Rerun recording logs, cheap to
pickle. Packing needs no ``rerun``: the evaluating process packs, and ``RerunSink`` (in the
same process or in ``RerunProcessSink``'s recorder process) logs."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from smartcar_gym.viewers.capture import Episode, Scene


def entity(episode: Episode) -> str:
    """The entity name of an episode (``episode_007``)."""
    return f"episode_{episode.index:03d}"


@dataclass
class Packet:
    """One episode as a recording needs it: plain arrays, cheap to pickle (what
    ``RerunProcessSink`` sends its recorder process). ``scene.urdf`` may be empty: only the
    first episode of a recording needs it."""

    entity: str
    scene: Scene
    table: Table
    scans: tuple[np.ndarray, list[int]] | None  # scan_points of its frames; None: no laser


def pack(episode: Episode, *, urdf: bool = True) -> Packet:
    """``episode`` as a ``Packet`` (``urdf=False``: without the URDF text)."""
    frames, scene = episode.frames, episode.scene
    scans = None
    if scene.laser_mount is not None and any(f.scan is not None for f in frames):
        scans = scan_points([f.scan for f in frames])
    if not urdf:
        scene = replace(scene, urdf="")
    return Packet(entity(episode), scene, Table(frames), scans)


class Table:
    """An episode's per-frame numbers as arrays, read from its frames in one pass."""

    def __init__(self, frames: list) -> None:
        terms = list(frames[-1].reward_terms)
        numbers = np.array([
            (f.time_ns, *f.position, *f.orientation, f.odometry.x, f.odometry.y,
             f.odometry.theta, *f.command, *f.pwm, f.distance_m, f.odom_error_m, f.success,
             *[f.reward_terms.get(t, 0.0) for t in terms], f.reward)
            for f in frames], dtype=np.float64)
        self.time_ns = numbers[:, 0]  # exact: simulated ns stay far below 2**53
        self.position = numbers[:, 1:4]
        self.orientation = numbers[:, 4:8]
        self.odometry = numbers[:, 8:11]  # x, y, theta
        self.command = numbers[:, 11:13]
        self.pwm = numbers[:, 13:15]
        self.distance = numbers[:, 15:16]
        self.odom_error = numbers[:, 16:17]
        self.success = numbers[:, 17:18]
        self.rewards = numbers[:, 18:]  # the terms, then the total
        self.reward_names = [*terms, "total"]
        self.wheel_speed = np.array([f.joints.velocity for f in frames])


def scan_points(scans: list) -> tuple[np.ndarray, list[int]]:
    """The finite ranges of each scan (``LaserScan`` or None) as points in the laser frame,
    all scans' points in one (N, 3) array, and how many each scan has. Scans of the same
    geometry (a whole episode's) are turned into points at once."""
    known = [s for s in scans if s is not None]
    if not known:
        return np.zeros((0, 3)), [0] * len(scans)
    first = known[0]
    geometry = (first.angle_min, first.angle_increment, len(first.ranges))
    if len(known) == len(scans) and all(
            (s.angle_min, s.angle_increment, len(s.ranges)) == geometry for s in known):
        ranges = np.array([s.ranges for s in scans], dtype=np.float64)
        angles = first.angle_min + first.angle_increment * np.arange(ranges.shape[1])
        hit = np.isfinite(ranges)
        r = ranges[hit]
        a = np.broadcast_to(angles, ranges.shape)[hit]
        return (np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)]),
                hit.sum(axis=1).tolist())
    points, lengths = [], []
    for scan in scans:
        if scan is None:
            lengths.append(0)
            continue
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        angles = scan.angle_min + scan.angle_increment * np.arange(len(ranges))
        hit = np.isfinite(ranges)
        r, a = ranges[hit], angles[hit]
        points.append(np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)]))
        lengths.append(len(r))
    return (np.concatenate(points) if points else np.zeros((0, 3))), lengths
