"""The DWA baseline as a driver of smartcar cars: move_base's local planner on the car's laser.

``DWADriver`` drives the N laser-carrying cars of a vector env (SmartCarBARN-v0, or
SmartCarNav-v0 with paths given) at once: it reads what a ROS robot's move_base reads, from
the cars' public state and their task (``envs.vector.view.CarView``): the odometry, the
latest ``/scan``, the global path; with SmartCarBARN-v0's ``localize=True`` the path is
followed from the pose on the map, as amcl's transform gives it to move_base, and with its
``map_mode="laser"`` the path the task plans again on each car's laser costmap is followed
from each new plan, as move_base hands navfn's plans to its local planner. It plans with
``navigation.dwa.DWAPlanner`` and returns the cars' actions, the cmd_vel (v, w) over
``max_linear`` and ``max_angular``, which go through the same emulated ArbotiX controller as
a policy's.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from smartcar_gym.envs.state import SCAN
from smartcar_gym.envs.vector.common import check_num_threads
from smartcar_gym.envs.vector.view import CarView
from smartcar_gym.model.footprint import car_width, footprint_half_extents
from smartcar_gym.navigation.dwa import DWAConfig, DWAPlanner
from smartcar_gym.navigation.footprint import COMPILED as FOOTPRINT_COMPILED
from smartcar_gym.navigation.footprint import FAR_M
from smartcar_gym.navigation.obstacles import ObstacleLayers
from smartcar_gym.navigation.path_trackers import PathTrackers
from smartcar_gym.worlds.barn import JACKAL_TOP_SPEED_M_S, JACKAL_WIDTH_M

PATH_BEHIND_M = 0.2  # the path's window starts this far behind the nearest point
#: The shipped car's turn rate (rad/s, steady) for a commanded angular.z, driving (v > 0) and
#: in place, measured on the planar and MuJoCo engines (pybullet alike): a skid-steer base
#: does not turn below about 0.2 rad/s commanded (0.5 in place) and then at about 0.8 of it.
#: DWA plans the turn it wants; the driver commands what gives it (base_local_planner assumes
#: a base that tracks cmd_vel).
TURN_COMMAND = np.array([0.0, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.3, 1.6, 2.0])
TURN_DRIVING = np.array([0.0, 0.0, 0.08, 0.2, 0.29, 0.38, 0.53, 0.69, 0.98, 1.24, 1.6])
TURN_IN_PLACE = np.array([0.0, 0.0, 0.0, 0.0, 0.02, 0.3, 0.53, 0.69, 1.0, 1.25, 1.6])


def turn_command(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The angular.z to command for a turn rate ``w`` (rad/s) at speed ``v`` (m/s), from the
    car's measured response (``TURN_COMMAND`` -> ``TURN_DRIVING`` / ``TURN_IN_PLACE``)."""
    w = np.asarray(w, dtype=float)
    driving = np.interp(np.abs(w), TURN_DRIVING[1:], TURN_COMMAND[1:])
    in_place = np.interp(np.abs(w), TURN_IN_PLACE[4:], TURN_COMMAND[4:])
    return np.sign(w) * np.where(np.asarray(v) != 0.0, driving, in_place)


class DWADriver:
    """DWA on N cars: ``reset(cars, indices)`` once their episodes start, then ``act(cars,
    obs, indices)`` per step (``cars``: a ``CarView``). ``config``: None, the challenge's set
    scaled to the cars' car; ``compensate_turns``: command the turn DWA plans through the
    car's measured response (``turn_command``), else pass DWA's angular.z as it is;
    ``clearing``: each scan clears the obstacle layer's cells its beams pass through
    (costmap_2d's ``clearing: true``, as the challenge's Jackal; ``obstacles.ObstacleLayers``),
    else cells stay marked until they age out."""

    name = "dwa"
    #: cars per ``act`` call in a batched benchmark (None: all at once): numpy's footprint
    #: check holds (cars, candidates, poses, points) arrays; numba's holds none
    act_chunk = None if FOOTPRINT_COMPILED else 4

    def __init__(self, config: DWAConfig | None = None, compensate_turns: bool = True,
                 compiled: bool | None = None, threads: int | None = None,
                 clearing: bool = True) -> None:
        self.config = config
        self.compensate_turns = compensate_turns
        self.clearing = clearing
        self.compiled = compiled  # the obstacle layers and the planner: None, numba if there
        #: the compiled footprint check's robots split over these (None: every core); the same
        #: answers
        self.threads = check_num_threads(threads)
        self.planner: DWAPlanner | None = None
        self.trackers: PathTrackers | None = None  # the global paths' local goals, windows
        self.layers: ObstacleLayers | None = None  # the local costmaps' obstacle layers
        self.following: list[np.ndarray | None] = []  #: the global path each car follows

    @staticmethod
    def config_for(cars: CarView) -> DWAConfig:
        """The challenge's set for the cars' car: its width over the Jackal's, its top speed
        over the Jackal's, its controller period and its footprint as simulated."""
        car = cars.task.car
        half_length, half_width = footprint_half_extents(car.robot_model, car.wheel_contact)
        return DWAConfig.challenge(
            scale=car_width(car.robot_model) / JACKAL_WIDTH_M,
            speed_scale=car.max_linear / JACKAL_TOP_SPEED_M_S, sim_period=car.period_s,
            half_length=half_length, half_width=half_width)

    def reset(self, cars: CarView, indices: Sequence[int] | None = None,
              paths: Sequence[np.ndarray] | None = None) -> None:
        """Start following the paths of the cars ``indices`` (None: all of them):
        ``paths[i]`` (odom frame), or by default each car's global path (the task's)."""
        if self.planner is None:
            self.planner = DWAPlanner(self.config or self.config_for(cars),
                                      compiled=self.compiled, threads=self.threads)
        config = self.planner.config
        if self.layers is None or len(self.layers.size) != cars.num:
            self.trackers = PathTrackers(cars.num, config.local_goal_m,
                                         2.0 * config.local_goal_m, compiled=self.compiled)
            self.layers = ObstacleLayers(cars.num, compiled=self.compiled,
                                         clearing=self.clearing, threads=self.threads)
            self.following = [None] * cars.num
        given = cars.per_car("global_paths") if paths is None else paths
        for i in range(cars.num) if indices is None else indices:
            self.trackers.start(i, given[i])
            self.following[i] = given[i]
            self.layers.clear(i)

    def act(self, cars: CarView, obs: Any = None,
            indices: Sequence[int] | None = None) -> np.ndarray:
        """The actions (K, 2) of the cars ``indices`` (None: all). ``obs``, a policy's input,
        is unused: DWA reads the odometry, the scan and the path as move_base does."""
        config = self.planner.config
        slots = list(range(cars.num) if indices is None else indices)
        state = cars.state
        odometry = state.odometry[slots]
        poses, velocity = odometry[:, :3].astype(float), odometry[:, 3:5].astype(float)
        config_laser, mount = cars.task.laser
        if getattr(cars.task, "map_mode", "known") == "laser":  # each new plan, as it comes
            paths = cars.per_car("global_paths")
            for i in slots:
                if paths[i] is not self.following[i]:
                    self.trackers.start(i, paths[i])
                    self.following[i] = paths[i]
        obstacles, counts = self.layers.update(
            slots, np.array(state.readings[SCAN][slots], dtype=float), config_laser.angles,
            mount, poses, config.reach_m)
        if getattr(cars.task, "localize", False):  # the path from the pose on the map
            map_poses = cars.per_car("map_poses")
            poses = np.array([map_poses[i] for i in slots], dtype=float).reshape(-1, 3)
        cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        d = self.trackers.waypoints(slots, poses[:, :2]) - poses[:, :2]
        goals = np.stack([cos * d[:, 0] + sin * d[:, 1], -sin * d[:, 0] + cos * d[:, 1]], -1)
        windows = self.trackers.windows(slots, poses, cos, sin, PATH_BEHIND_M,
                                        2.0 * config.local_goal_m, FAR_M)
        cmd = self.planner.plan(velocity, obstacles, windows, goals, counts=counts)
        if self.compensate_turns:
            cmd[:, 1] = turn_command(cmd[:, 0], cmd[:, 1])
        car = cars.task.car
        scale = np.array([car.max_linear, car.max_angular])
        return np.clip(cmd / scale, -1.0, 1.0).astype(np.float32)
