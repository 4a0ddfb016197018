"""The DWA baseline as a driver of smartcar envs: move_base's local planner on the car's laser.

``DWADriver`` drives N laser-carrying envs (SmartCarBARN-v0, or SmartCarNav-v0 with a path
given) at once: it reads what a ROS robot's move_base reads (the odometry, the latest
``/scan``, the global path), plans with ``DWAPlanner`` and returns the envs' actions, the
cmd_vel (v, w) over ``max_linear`` and ``max_angular``, which go through the same emulated
ArbotiX controller as a policy's.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from smartcar_gym.envs.barn_env import car_width, footprint_half_extents
from smartcar_gym.envs.tasks.barn import PathTracker
from smartcar_gym.navigation.dwa import DWAConfig, DWAPlanner
from smartcar_gym.navigation.footprint import COMPILED as FOOTPRINT_COMPILED
from smartcar_gym.navigation.footprint import FAR_M
from smartcar_gym.worlds.barn import JACKAL_TOP_SPEED_M_S, JACKAL_WIDTH_M

CELL_OFFSET = 1 << 30  # makes cell indices positive for the memory's keys
PATH_BEHIND_M = 0.2  # the path's window starts this far behind the nearest point
#: The shipped car's turn rate (rad/s, steady) for a commanded angular.z, driving (v > 0) and
#: in place, measured on the planar and MuJoCo engines (pybullet alike): a skid-steer base
#: does not turn below about 0.2 rad/s commanded (0.5 in place) and then at about 0.8 of it.
#: DWA plans the turn it wants; the driver commands what gives it (base_local_planner assumes
#: a base that tracks cmd_vel).
TURN_COMMAND = np.array([0.0, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.3, 1.6, 2.0])
TURN_DRIVING = np.array([0.0, 0.0, 0.08, 0.2, 0.29, 0.38, 0.53, 0.69, 0.98, 1.24, 1.6])
TURN_IN_PLACE = np.array([0.0, 0.0, 0.0, 0.0, 0.02, 0.3, 0.53, 0.69, 1.0, 1.25, 1.6])


def scan_points(ranges: np.ndarray, angles: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """A scan's returns as points (K, 2) in base_link; ``+inf`` (nothing) and ``-inf`` (closer
    than range_min) are left out, as the costmap's obstacle layer leaves them."""
    r = np.asarray(ranges, dtype=float)
    keep = np.isfinite(r)
    count = int(keep.sum())
    local = np.stack([r[keep] * np.cos(angles[keep]), r[keep] * np.sin(angles[keep]),
                      np.zeros(count), np.ones(count)])
    return (mount @ local)[:2].T


class ObstacleMemory:
    """The local costmap's obstacle layer, marking only, in the odom frame: a square cell of
    ``cell_m`` is marked by a laser return in it and stays marked for ``scans`` scans after
    the last one, at that return's point, so that an obstacle stays in the map when it comes
    closer than the laser's range_min (or behind what the laser sees)."""

    def __init__(self, scans: int = 50, cell_m: float = 0.005) -> None:
        self.scans = scans
        self.cell_m = cell_m
        self.count = 0  # scans marked so far
        self.keys = np.zeros(0, dtype=np.int64)  # the marked cells, sorted
        self.points = np.zeros((0, 2))
        self.seen = np.zeros(0, dtype=np.int64)  # the scan that last marked each

    def add(self, points: np.ndarray) -> None:
        """Mark the cells of ``points`` (K, 2), odom frame, and forget the cells no scan of
        the last ``scans`` marked."""
        self.count += 1
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        cells = np.floor(points / self.cell_m).astype(np.int64) + CELL_OFFSET
        keys, first = np.unique(cells[:, 0] * (2 * CELL_OFFSET) + cells[:, 1],
                                return_index=True)
        at = np.minimum(np.searchsorted(self.keys, keys), max(len(self.keys) - 1, 0))
        known = (self.keys[at] == keys) if len(self.keys) else np.zeros(len(keys), dtype=bool)
        self.points[at[known]] = points[first[known]]
        self.seen[at[known]] = self.count
        keys = np.concatenate([self.keys, keys[~known]])
        order = np.argsort(keys, kind="stable")
        fresh = np.concatenate([self.seen, np.full(int((~known).sum()), self.count)])[order]
        keep = fresh > self.count - self.scans
        self.keys = keys[order][keep]
        self.points = np.concatenate([self.points, points[first[~known]]])[order][keep]
        self.seen = fresh[keep]

    def near(self, pose: np.ndarray, reach_m: float) -> np.ndarray:
        """The marked points within ``reach_m`` of ``pose`` (x, y, theta), in its base frame."""
        points = to_base(self.points, pose)
        return points[points[:, 0] ** 2 + points[:, 1] ** 2 < reach_m * reach_m]


def turn_command(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The angular.z to command for a turn rate ``w`` (rad/s) at speed ``v`` (m/s), from the
    car's measured response (``TURN_COMMAND`` -> ``TURN_DRIVING`` / ``TURN_IN_PLACE``)."""
    w = np.asarray(w, dtype=float)
    driving = np.interp(np.abs(w), TURN_DRIVING[1:], TURN_COMMAND[1:])
    in_place = np.interp(np.abs(w), TURN_IN_PLACE[4:], TURN_COMMAND[4:])
    return np.sign(w) * np.where(np.asarray(v) != 0.0, driving, in_place)


def to_odom(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (..., 2) of the base frame of ``pose`` (x, y, theta) in the odom frame."""
    p = np.asarray(points, dtype=float)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.stack([c * p[..., 0] - s * p[..., 1] + pose[0],
                     s * p[..., 0] + c * p[..., 1] + pose[1]], -1)


def to_base(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (..., 2) of the odom frame in the base frame of ``pose`` (x, y, theta)."""
    d = np.asarray(points, dtype=float) - pose[:2]
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], -1)


def pad(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """(N, max K, 2) of N (K_i, 2) arrays, padded with points ``FAR_M`` away."""
    size = max(1, max(len(a) for a in arrays))
    out = np.full((len(arrays), size, 2), FAR_M)
    for i, a in enumerate(arrays):
        out[i, :len(a)] = a
    return out


class DWADriver:
    """DWA on N envs: ``reset(envs, paths)`` once their episodes start, then ``act(envs)`` per
    step. ``config``: None, the challenge's set scaled to the first env's car;
    ``compensate_turns``: command the turn DWA plans through the car's measured response
    (``turn_command``), else pass DWA's angular.z as it is."""

    name = "dwa"
    #: cars per ``act`` call in a batched benchmark (None: all at once): numpy's footprint
    #: check holds (cars, candidates, poses, points) arrays; numba's holds none
    act_chunk = None if FOOTPRINT_COMPILED else 4

    def __init__(self, config: DWAConfig | None = None, compensate_turns: bool = True) -> None:
        self.config = config
        self.compensate_turns = compensate_turns
        self.planner: DWAPlanner | None = None
        self.trackers: list[PathTracker | None] = []
        self.memories: list[ObstacleMemory | None] = []

    def config_for(self, env: Any) -> DWAConfig:
        """The challenge's set for ``env``'s car: its width over the Jackal's, its top speed
        over the Jackal's, its controller period and its footprint as simulated."""
        half_length, half_width = footprint_half_extents(env.robot_model, env.wheel_contact)
        return DWAConfig.challenge(
            scale=car_width(env.robot_model) / JACKAL_WIDTH_M,
            speed_scale=env.max_linear / JACKAL_TOP_SPEED_M_S,
            sim_period=env.robot.update_period_ns * 1e-9,
            half_length=half_length, half_width=half_width)

    def reset(self, envs: Sequence[Any], indices: Sequence[int] | None = None,
              paths: Sequence[np.ndarray] | None = None) -> None:
        """Start following the paths of ``envs[i]`` for i in ``indices`` (None: all of them):
        ``paths[i]`` (odom frame), or by default each env's ``global_path``."""
        envs = [getattr(env, "unwrapped", env) for env in envs]
        if self.planner is None:
            self.planner = DWAPlanner(self.config or self.config_for(envs[0]))
        if len(self.trackers) != len(envs):
            self.trackers, self.memories = [None] * len(envs), [None] * len(envs)
        config = self.planner.config
        for i in range(len(envs)) if indices is None else indices:
            path = envs[i].global_path if paths is None else paths[i]
            self.trackers[i] = PathTracker(path, config.local_goal_m, 2.0 * config.local_goal_m)
            self.memories[i] = ObstacleMemory()

    def act(self, envs: Sequence[Any], obs: Any = None,
            indices: Sequence[int] | None = None) -> np.ndarray:
        """The actions (N, 2) of ``envs``, the ones at ``indices`` of those ``reset`` was
        given (None: all). ``obs``, a policy's input, is unused: DWA reads the odometry, the
        scan and the path as move_base does."""
        envs = [getattr(env, "unwrapped", env) for env in envs]
        config = self.planner.config
        slots = range(len(envs)) if indices is None else indices
        velocity, obstacles, windows, goals = [], [], [], []
        for env, i in zip(envs, slots, strict=True):
            tracker, memory = self.trackers[i], self.memories[i]
            odom = env.robot.odometry
            pose = np.array([odom.x, odom.y, odom.theta])
            velocity.append((odom.v, odom.omega))
            laser = env.laser
            memory.add(to_odom(scan_points(laser.latest.ranges, laser.config.angles,
                                           laser.mount), pose))
            obstacles.append(memory.near(pose, config.reach_m))
            goals.append(to_base(tracker.waypoint(pose[:2]), pose))
            lo = int(np.searchsorted(tracker.arc, tracker.arc[tracker.index] - PATH_BEHIND_M))
            hi = int(np.searchsorted(tracker.arc, tracker.arc[tracker.index]
                                     + 2.0 * config.local_goal_m, side="right"))
            windows.append(to_base(tracker.path[lo:max(hi, lo + 1)], pose))
        cmd = self.planner.plan(np.array(velocity), pad(obstacles), pad(windows),
                                np.array(goals), counts=np.array([len(o) for o in obstacles]))
        if self.compensate_turns:
            cmd[:, 1] = turn_command(cmd[:, 0], cmd[:, 1])
        scale = np.array([[env.max_linear, env.max_angular] for env in envs])
        return np.clip(cmd / scale, -1.0, 1.0).astype(np.float32)
