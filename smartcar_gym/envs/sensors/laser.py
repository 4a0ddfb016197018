"""A simulated 2D laser scanner on a robot: one batched ray cast per scan, at its own rate.

The scanner is an event source of the simulator: it scans when attached (t = 0 of an episode)
and then every ``1 / rate_hz`` s of simulated time, whatever the controller does; the latest
scan is what the robot knows. Its frame is fixed to the robot's base_link by a ``mount`` (a 4x4
transform), read from a ``laser`` link of the model (``mount_from_model``) or given as a pose
(``mount_from_pose``). The robot's own body is hidden from the rays.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from smartcar_gym.envs.sensors.scan import LaserConfig, LaserScan
from smartcar_gym.model import RobotModel
from smartcar_gym.model.kinematics import link_frames, quaternion_matrix
from smartcar_gym.model.urdf import UrdfRobot
from smartcar_gym.sim.clock import seconds_to_ns
from smartcar_gym.sim.contracts import Body, BoxPart, Simulator
from smartcar_gym.sim.rays import cast_rays, hide_from_rays

HIT_COLOR = (0.95, 0.1, 0.1, 1.0)
_HIDDEN = (0.0, 0.0, -10.0)


def mount_from_pose(pose: Sequence[float]) -> np.ndarray:
    """The base_link -> laser transform of a mount pose ``(x, y, z, yaw)`` (m, m, m, rad)."""
    try:
        x, y, z, yaw = (float(v) for v in pose)
    except (TypeError, ValueError):
        raise ValueError(f"laser_mount must be (x, y, z, yaw) in base_link (m, m, m, rad), got "
                         f"{pose!r}") from None
    if not all(math.isfinite(v) for v in (x, y, z, yaw)):
        raise ValueError(f"laser_mount must be finite numbers, got {pose!r}")
    mount = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    mount[:2, :2] = [[c, -s], [s, c]]
    mount[:3, 3] = (x, y, z)
    return mount


def mount_from_model(model: RobotModel, link: str = "laser") -> np.ndarray | None:
    """The base_link -> ``link`` transform of the model, or None if it has no such link.

    ValueError if a joint between base_link and ``link`` can move (the mount must be rigid).
    """
    if link not in model.links:
        return None
    parent_joint = {j.child: j for j in model.joints.values()}
    child = link
    while child != model.base_link:
        joint = parent_joint[child]
        if joint.type != "fixed":
            raise ValueError(f"{model.source}: link {link!r} hangs on {joint.type} joint "
                             f"{joint.name!r}; a laser must be fixed to {model.base_link}")
        child = joint.parent
    robot = UrdfRobot(model.name, model.links, model.joints, model.base_link)
    return link_frames(robot)[link]


class SimulatedLaser:
    """A ``LaserConfig`` scanner fixed to a robot body by ``mount`` (base_link -> laser, 4x4).

    Use: ``attach(body, rng)`` after the robot is spawned in a freshly reset world; read
    ``latest`` (a ``LaserScan``) and ``hit_points`` (where its finite ranges end, world frame).
    """

    def __init__(self, config: LaserConfig, mount: np.ndarray) -> None:
        self.config = config
        self.mount = np.asarray(mount, dtype=float)
        angles = config.angles
        # beam directions in base_link (the laser frame's x-y plane, turned by the mount)
        local = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
        self._directions = local @ self.mount[:3, :3].T
        self.period_ns = seconds_to_ns(1.0 / config.rate_hz)
        self.body: Body | None = None
        self.rng: np.random.Generator | None = None
        self.latest: LaserScan | None = None
        self.hit_points = np.zeros((0, 3))
        self.origin = np.zeros(3)  # where the latest scan was taken from (world frame)
        #: when the latest scan was taken (ns of simulated time)
        self.stamp_ns = 0
        self._next_ns = 0

    @property
    def sim(self) -> Simulator:
        return self.body.sim

    def attach(self, body: Body, rng: np.random.Generator | None = None,
               scan: bool = True) -> None:
        """Scan from ``body`` now and every period from now on (``rng``: the range noise's;
        ``scan`` False: the scan now is left to whoever takes the world, ``latest`` None)."""
        if self.config.noise_std_m > 0 and rng is None:
            raise ValueError("a noisy laser needs a random generator")
        self.body, self.rng = body, rng
        hide_from_rays(body)
        self.latest = self.scan() if scan else None
        self._next_ns = body.sim.now_ns + self.period_ns
        body.sim.add_event_source(self)

    # -- EventSource ---------------------------------------------------------------------------
    def next_event_ns(self, now_ns: int) -> int:
        return self._next_ns

    def on_event(self, now_ns: int) -> None:
        self.latest = self.scan()
        self._next_ns += self.period_ns

    # -- scanning ------------------------------------------------------------------------------
    def beams(self, position: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The scan's origin and unit beam directions (world frame) for base_link at
        ``position`` turned by ``rotation``; ``(N, 3)`` and ``(N, 3, 3)`` give N scans' (the
        batched MuJoCo env's), each bit for bit as alone."""
        origin = position + rotation @ self.mount[:3, 3]
        return origin, self._directions @ np.swapaxes(rotation, -1, -2)

    def ranges(self, fraction: np.ndarray, hit: np.ndarray,
               rng: np.random.Generator | None) -> np.ndarray:
        """A scan's ranges (REP 117) from its rays' hit ``fraction`` of ``range_max`` and
        ``hit`` flags, with ``rng``'s noise if the config has any."""
        config = self.config
        ranges = fraction * config.range_max
        if config.noise_std_m > 0:
            ranges = ranges + rng.normal(0.0, config.noise_std_m, size=ranges.shape)
        ranges = np.where(hit & (ranges <= config.range_max), ranges, np.inf)
        return np.where(ranges < config.range_min, -np.inf, ranges)

    def scan(self) -> LaserScan:
        """Cast every beam now (one batch) and return the scan (ranges as REP 117 says)."""
        config = self.config
        position, orientation = self.body.link_pose()
        origin, directions = self.beams(np.asarray(position), quaternion_matrix(orientation))
        hits = cast_rays(self.sim, np.broadcast_to(origin, directions.shape),
                         origin + directions * config.range_max)
        ranges = self.ranges(hits.fraction, hits.hit, self.rng)
        finite = np.isfinite(ranges)
        self.origin = origin
        self.stamp_ns = self.sim.now_ns
        self.hit_points = origin + directions[finite] * ranges[finite, None]
        return LaserScan(
            stamp_s=self.sim.time_s, frame_id=config.frame_id, angle_min=config.angle_min,
            angle_max=float(config.angles[-1]), angle_increment=config.angle_increment,
            time_increment=0.0, scan_time=1.0 / config.rate_hz, range_min=config.range_min,
            range_max=config.range_max, ranges=ranges.astype(np.float32),
        )


class ScanMarkers:
    """Small red cubes on a scan's hit points, for the rgb_array and human renders."""

    def __init__(self, sim: Simulator, count: int, size_m: float = 0.03) -> None:
        self.half = size_m / 2.0
        half = self.half
        part = BoxPart((half, half, half), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), HIT_COLOR)
        self._cubes = sim.add_visual_copies("laser_hit_", [part], count, _HIDDEN)
        self._shown = 0

    def draw(self, points: np.ndarray, origin: np.ndarray) -> None:
        """Put a cube on each point, just outside the surface seen from ``origin`` (the
        laser), and the rest out of sight."""
        identity = (0.0, 0.0, 0.0, 1.0)
        back = np.asarray(origin) - points
        lengths = np.linalg.norm(back, axis=1, keepdims=True)
        points = points + back * np.minimum(self.half, lengths) / np.maximum(lengths, 1e-9)
        for cube, point in zip(self._cubes, points, strict=False):
            cube.set_com_pose(tuple(point), identity)
        for cube in self._cubes[len(points):self._shown]:
            cube.set_com_pose(_HIDDEN, identity)
        self._shown = min(len(points), len(self._cubes))
