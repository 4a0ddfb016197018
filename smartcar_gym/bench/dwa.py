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
a policy's. With ``map_mode="laser"`` it is move_base in full: its recovery behaviours
(``navigation.recovery``: a conservative costmap reset, a rotation in place, an aggressive
reset, a rotation, then it stops commanding), TrajectoryPlanner's in-place turns, oscillation
flags and escape (``navigation.oscillation``) and the speeds commanded through the car's
response; on the known map none of these, its records unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from smartcar_gym.envs.state import SCAN
from smartcar_gym.envs.vector.common import check_num_threads
from smartcar_gym.envs.vector.view import CarView
from smartcar_gym.model.footprint import car_width, footprint_half_extents
from smartcar_gym.navigation.dwa import DWAConfig, DWAPlanner
from smartcar_gym.navigation.footprint import COMPILED as FOOTPRINT_COMPILED
from smartcar_gym.navigation.footprint import FAR_M, footprint_check
from smartcar_gym.navigation.obstacles import ObstacleLayers
from smartcar_gym.navigation.oscillation import Oscillation, OscillationConfig
from smartcar_gym.navigation.path_trackers import PathTrackers
from smartcar_gym.navigation.recovery import (
    AGGRESSIVE,
    CONSERVATIVE,
    CONTROL,
    ROTATE,
    ROTATE_SIM_GRANULARITY,
    ROTATING,
    YAW_GOAL_TOLERANCE,
    Recoveries,
    RecoveryConfig,
    Rotations,
    rotation_speed,
)
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
#: The shipped car's speed (m/s, steady, the three engines' mean) for a commanded linear.x:
#: nothing below about 0.03 m/s (the board's PID rounds it away), then a rising share of it.
SPEED_COMMAND = np.array([0.0, 0.03, 0.04, 0.05, 0.06, 0.075, 0.1, 0.125, 0.15, 0.2])
SPEED_DRIVEN = np.array([0.0, 0.0, 0.0187, 0.029, 0.046, 0.065, 0.089, 0.122, 0.146, 0.2])


def turn_command(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The angular.z to command for a turn rate ``w`` (rad/s) at speed ``v`` (m/s), from the
    car's measured response (``TURN_COMMAND`` -> ``TURN_DRIVING`` / ``TURN_IN_PLACE``)."""
    w = np.asarray(w, dtype=float)
    driving = np.interp(np.abs(w), TURN_DRIVING[1:], TURN_COMMAND[1:])
    in_place = np.interp(np.abs(w), TURN_IN_PLACE[4:], TURN_COMMAND[4:])
    return np.sign(w) * np.where(np.asarray(v) != 0.0, driving, in_place)


def speed_command(v: np.ndarray) -> np.ndarray:
    """The linear.x to command for a speed ``v`` (m/s), from the car's measured response
    (``SPEED_COMMAND`` -> ``SPEED_DRIVEN``); 0 stays 0."""
    v = np.asarray(v, dtype=float)
    return np.sign(v) * np.interp(np.abs(v), SPEED_DRIVEN[1:], SPEED_COMMAND[1:])


class DWADriver:
    """DWA on N cars: ``reset(cars, indices)`` once their episodes start, then ``act(cars,
    obs, indices)`` per step (``cars``: a ``CarView``). ``config``: None, the challenge's set
    scaled to the cars' car; ``compensate_turns``: command the turn DWA plans through the
    car's measured response (``turn_command``), else pass DWA's angular.z as it is;
    ``clearing``: each scan clears the obstacle layer's cells its beams pass through
    (costmap_2d's ``clearing: true``, as the challenge's Jackal; ``obstacles.ObstacleLayers``),
    else cells stay marked until they age out; ``recoveries``: with the task's
    ``map_mode="laser"``, move_base's recovery behaviours (``navigation.recovery``; None:
    ``RecoveryConfig.challenge`` for the cars' car, False: none); on the known map never;
    ``goal_rate_hz``: with them, the goal sent again at this rate, as the challenge's launch
    sends it (``CHALLENGE_GOAL_RATE_HZ``: then no behaviour runs), None: once;
    ``footprint_clearing``: with ``map_mode="laser"``, each scan's marks inside the padded
    footprint forgotten (costmap_2d's ``footprint_clearing_enabled``, true by default and not
    set by the challenge; ``obstacles.ObstacleLayers``); on the known map never.

    With ``map_mode="laser"`` the driver is the challenge's move_base in full: besides the
    recoveries, TrajectoryPlanner's choice of in-place turns, its oscillation flags and its
    escape (``navigation.oscillation``), and the speeds as well as the turns commanded
    through the car's measured response (``speed_command``: base_local_planner's slowest
    speeds are below what the car drives). On the known map the driver stays as it was, its
    records unchanged."""

    name = "dwa"
    #: cars per ``act`` call in a batched benchmark (None: all at once): numpy's footprint
    #: check holds (cars, candidates, poses, points) arrays; numba's holds none
    act_chunk = None if FOOTPRINT_COMPILED else 4

    def __init__(self, config: DWAConfig | None = None, compensate_turns: bool = True,
                 compiled: bool | None = None, threads: int | None = None,
                 clearing: bool = True, recoveries: RecoveryConfig | bool | None = None,
                 goal_rate_hz: float | None = None, footprint_clearing: bool = True) -> None:
        if goal_rate_hz is not None and not (
                isinstance(goal_rate_hz, int | float) and math.isfinite(goal_rate_hz)
                and goal_rate_hz > 0):
            raise ValueError(f"goal_rate_hz must be a rate > 0 (Hz) or None (the goal sent "
                             f"once), got {goal_rate_hz!r}")
        self.config = config
        self.recovery_config = recoveries
        self.goal_rate_hz = goal_rate_hz
        self.compensate_turns = compensate_turns
        self.clearing = clearing
        self.footprint_clearing = footprint_clearing
        self.compiled = compiled  # the obstacle layers and the planner: None, numba if there
        #: the compiled footprint check's robots split over these (None: every core); the same
        #: answers
        self.threads = check_num_threads(threads)
        self.planner: DWAPlanner | None = None
        self.trackers: PathTrackers | None = None  # the global paths' local goals, windows
        self.layers: ObstacleLayers | None = None  # the local costmaps' obstacle layers
        self.following: list[np.ndarray | None] = []  #: the global path each car follows
        #: move_base's state machine and the rotations in place (``map_mode="laser"``)
        self.recoveries: Recoveries | None = None
        self.rotations: Rotations | None = None
        #: TrajectoryPlanner's flags and escape (``map_mode="laser"``)
        self.oscillation: Oscillation | None = None

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
            self.recoveries = self.oscillation = None
        laser = getattr(cars.task, "map_mode", "known") == "laser"
        if laser and self.recovery_config is not False and self.recoveries is None:
            self.recoveries = Recoveries(cars.num, self.recovery_config_for(cars))
            self.rotations = Rotations(cars.num, YAW_GOAL_TOLERANCE)
        if laser and self.oscillation is None:
            self.oscillation = Oscillation(cars.num, OscillationConfig.challenge(
                car_width(cars.task.car.robot_model) / JACKAL_WIDTH_M))
        given = cars.per_car("global_paths") if paths is None else paths
        for i in range(cars.num) if indices is None else indices:
            self.trackers.start(i, given[i])
            self.following[i] = given[i]
            self.layers.clear(i)
        state = cars.state
        for i in range(cars.num) if indices is None else indices:
            if self.recoveries is not None:
                self.recoveries.reset(i, int(state.now_ns[i]) / 1e9, state.odometry[i, :2])
            if self.oscillation is not None:
                self.oscillation.reset(i, state.odometry[i, :3].astype(float))

    def recovery_config_for(self, cars: CarView) -> RecoveryConfig:
        """move_base's recovery set for the cars' car: the given one, or the challenge's
        scaled as ``config_for`` scales DWA's, the aggressive reset 4 x the circumscribed
        radius of the planner's padded footprint."""
        if isinstance(self.recovery_config, RecoveryConfig):
            return self.recovery_config
        car, c = cars.task.car, self.planner.config
        return RecoveryConfig.challenge(
            scale=car_width(car.robot_model) / JACKAL_WIDTH_M,
            speed_scale=car.max_linear / JACKAL_TOP_SPEED_M_S,
            circumscribed_m=float(np.hypot(*c.padded)),
            goal_rate_hz=self.goal_rate_hz)

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
        new_plan = np.zeros(len(slots), dtype=bool)
        laser = getattr(cars.task, "map_mode", "known") == "laser"
        if laser:  # each new plan, as it comes
            paths = cars.per_car("global_paths")
            for k, i in enumerate(slots):
                if paths[i] is not self.following[i]:
                    new_plan[k] = True
                    self.trackers.start(i, paths[i])
                    self.following[i] = paths[i]
        obstacles, counts = self.layers.update(
            slots, np.array(state.readings[SCAN][slots], dtype=float), config_laser.angles,
            mount, poses, config.reach_m,
            footprint=config.padded if laser and self.footprint_clearing else None)
        if getattr(cars.task, "localize", False):  # the path from the pose on the map
            map_poses = cars.per_car("map_poses")
            poses = np.array([map_poses[i] for i in slots], dtype=float).reshape(-1, 3)
        cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        d = self.trackers.waypoints(slots, poses[:, :2]) - poses[:, :2]
        goals = np.stack([cos * d[:, 0] + sin * d[:, 1], -sin * d[:, 0] + cos * d[:, 1]], -1)
        windows = self.trackers.windows(slots, poses, cos, sin, PATH_BEHIND_M,
                                        2.0 * config.local_goal_m, FAR_M)
        if self.oscillation is not None:  # TrajectoryPlanner's choice, as move_base runs it
            samples, valid, cost = self.planner.score(velocity, obstacles, windows, goals,
                                                      counts=counts)
            cmd = self.oscillation.choose(slots, odometry[:, :3].astype(float), samples, valid,
                                          cost, goals, self.planner.forward, config.sim_time)
        else:
            cmd = self.planner.plan(velocity, obstacles, windows, goals, counts=counts)
        if self.recoveries is not None:
            cmd = self._recover(cars, slots, odometry[:, :3].astype(float), poses[:, :2],
                                new_plan, cmd, obstacles, counts)
        if self.compensate_turns:
            cmd[:, 1] = turn_command(cmd[:, 0], cmd[:, 1])
            if self.oscillation is not None:
                cmd[:, 0] = speed_command(cmd[:, 0])
        car = cars.task.car
        scale = np.array([car.max_linear, car.max_angular])
        return np.clip(cmd / scale, -1.0, 1.0).astype(np.float32)

    def _recover(self, cars: CarView, slots: list[int], odom: np.ndarray, at: np.ndarray,
                 new_plan: np.ndarray, cmd: np.ndarray, obstacles: np.ndarray,
                 counts: np.ndarray) -> np.ndarray:
        """move_base's cycle around DWA's commands ``cmd`` (K, 2; (0, 0): none valid) of cars
        ``slots`` at odometry poses ``odom`` (K, 3), at ``at`` (K, 2) in their costmaps' frame
        (the pose on the map where localized): the commands to send."""
        c = self.planner.config
        now = cars.state.now_ns[slots].astype(float) / 1e9
        valid = np.any(cmd != 0.0, axis=1)
        todo = self.recoveries.step(slots, now, odom[:, :2], new_plan, valid)
        out = np.where((todo == CONTROL)[:, None], cmd, 0.0)
        for k, i in enumerate(slots):
            if todo[k] in (CONSERVATIVE, AGGRESSIVE):
                costmaps, car = self._costmap_of(cars, i)
                if costmaps is not None:
                    costmaps.clear_outside([car], at[k],
                                           self.recoveries.reset_distance(todo[k]))
                self.layers.clear(i)  # no partial clear there: all of it (docs/barn.md)
            elif todo[k] == ROTATE:
                self.rotations.start(i, odom[k, 2])
            if todo[k] not in (ROTATE, ROTATING):
                continue
            left = self.rotations.left(i, odom[k, 2])
            if left <= 0.0 or not self._can_rotate(obstacles[k], counts[k], left):
                self.recoveries.rotated(i, float(now[k]))
                continue
            out[k] = (0.0, rotation_speed(left, c.acc_lim_theta, c.min_in_place_vel_theta,
                                          c.max_vel_theta))
        return out

    def _can_rotate(self, obstacles: np.ndarray, count: int, left: float) -> bool:
        """rotate_recovery's check: the padded footprint, turned in place every
        ``sim_granularity`` up to ``left`` rad, touches no obstacle point (base frame)."""
        c = self.planner.config
        theta = np.arange(0.0, left, ROTATE_SIM_GRANULARITY)
        poses = np.zeros((1, 1, len(theta), 3))
        poses[..., 2] = theta
        valid, _ = footprint_check(poses, np.cos(theta)[None, None], np.sin(theta)[None, None],
                                   obstacles[None], np.array([count]), *c.padded,
                                   self.planner.cutoff_m, compiled=self.compiled)
        return bool(valid[0, 0])

    @staticmethod
    def _costmap_of(cars: CarView, i: int) -> tuple[Any, int]:
        """Car ``i``'s global costmap: its task's ``LaserCostmaps`` and its row there (a
        batch: one task, row i; a loop of single envs: env i's task, row 0)."""
        tasks = cars.tasks()
        if len(tasks) == cars.num:
            return getattr(tasks[i], "costmaps", None), 0
        return getattr(tasks[0], "costmaps", None), i
