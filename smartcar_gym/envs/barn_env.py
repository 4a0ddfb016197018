"""SmartCarBARN-v0: SmartCarNav-v0 in the 300 BARN worlds, with the challenge's protocol."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.envs.nav_env import NAV_OBSERVATION_ORDER, SmartCarNavEnv
from smartcar_gym.envs.nav_parts import nav_model
from smartcar_gym.envs.observation import Entry, Observation, Readings
from smartcar_gym.envs.robots.entries import robot_entries
from smartcar_gym.envs.sensors.scan import LaserConfig, scan_entry
from smartcar_gym.envs.smartcar_env import SmartCarEnv, observed_wheels, previous_action_entry
from smartcar_gym.envs.tasks.barn import (
    COLLISION,
    FAILURE,
    SUCCESS,
    TIMEOUT,
    BarnProtocol,
    PathTracker,
    RunClock,
    barn_score,
)
from smartcar_gym.envs.tasks.obstacles import Obstacle
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.model.kinematics import link_frames, transform
from smartcar_gym.model.urdf import UrdfRobot
from smartcar_gym.navigation.grid_planner import distance_grid, plan_path
from smartcar_gym.navigation.localization import (
    IDENTITY,
    Localizer,
    Pose,
    ScanMatcher,
    beam_geometry,
)
from smartcar_gym.sim.obstacles import nearest_distance
from smartcar_gym.worlds.barn import (
    GOAL_XY,
    JACKAL_WIDTH_M,
    TRAIN_WORLDS,
    BarnWorld,
    load_worlds,
    to_car_frame,
)

PROGRESS = ("goal", "path")  # what the progress reward measures
WAYPOINT_KEY = "waypoint"  # the next waypoint (map frame) in ``Readings.extra``
MAP_POSE_KEY = "map_pose"  # base_link on the map (x, y, yaw) in ``Readings.extra``
BARN_OBSERVATION_ORDER = (*NAV_OBSERVATION_ORDER, "waypoint_base")
GRID_RESOLUTION_M = 0.02  # the global planner's map
MAP_MARGIN_M = 0.3  # free map around the cylinders, the start and the goal
#: kwargs the protocol sets
PROTOCOL_KWARGS = ("goal_range", "goal_tolerance", "arena_size", "obstacles", "obstacle_size",
                   "obstacle_clearance", "obstacle_layout")


def footprint_half_extents(model: RobotModel, wheel_contact: str = "urdf"
                           ) -> tuple[float, float]:
    """Half the length (along base_link x) and half the width (y) of the box about base_link
    that holds the model's collision shapes' bounding boxes (a mesh counts as its origin);
    with ``wheel_contact="sphere"`` the drive wheels as the simulator has them, spheres of
    their radius."""
    robot = UrdfRobot(model.name, model.links, model.joints, model.base_link)
    frames = link_frames(robot)
    reach = np.zeros(2)
    for name, link in model.links.items():
        for shape in link.collisions:
            pose = frames[name] @ transform(shape.origin)
            g = shape.geometry
            half = {"box": lambda s: np.asarray(s) / 2.0,
                    "cylinder": lambda s: np.array([s[0], s[0], s[1] / 2.0]),
                    "sphere": lambda s: np.full(3, s[0])}.get(g.type, lambda s: np.zeros(3))(
                        g.size)
            # the shape's box's extent along base_link x and y: |t| + |R| . half
            reach = np.maximum(reach, np.abs(pose[:2, 3]) + np.abs(pose[:2, :3]) @ half)
    if wheel_contact == "sphere":
        for wheel in model.left_wheels + model.right_wheels:
            reach = np.maximum(reach, np.abs(wheel.position_m[:2]) + wheel.radius_m)
    return float(reach[0]), float(reach[1])


def car_width(model: RobotModel) -> float:
    """The model's width (m): ``footprint_half_extents``'s, doubled."""
    return 2.0 * footprint_half_extents(model)[1]


def to_base_frame(point: Sequence[float], x: float, y: float,
                  theta: float) -> tuple[float, float]:
    """``point`` (odom frame) in the base_link frame of the odometry pose (x, y, theta)."""
    dx, dy = point[0] - x, point[1] - y
    c, s = math.cos(theta), math.sin(theta)
    return c * dx + s * dy, -s * dx + c * dy


def waypoint_entry(arena_half_size_m: float) -> Entry:
    """The global path's next waypoint in the base_link frame of the pose on the map
    (``extra["map_pose"]``: the odometry's, through the localization's correction if any)."""
    a = arena_half_size_m

    def read(r: Readings) -> tuple[float, float]:
        odom = r.odometry
        return to_base_frame(r.extra[WAYPOINT_KEY],
                             *r.extra.get(MAP_POSE_KEY, (odom.x, odom.y, odom.theta)))

    return Entry("waypoint_base", ("waypoint_x_base", "waypoint_y_base"), -4 * a, 4 * a, "m",
                 "the global path's next waypoint in the base_link frame (ahead, left), "
                 "through odometry (or localize's pose on the map)", read, ("-4A", "4A"))


class SmartCarBARNEnv(SmartCarNavEnv):
    """## Description

    SmartCarNav-v0 in the BARN worlds (Benchmark for Autonomous Robot Navigation, the ICRA BARN
    Challenge): 300 fields of 0.15 m cylinders, scaled so that the car's width is to the gaps
    what the Jackal's 0.43 m is (the shipped car: 0.18 m, scale 0.4186). The car starts in the
    world's entry corridor at the origin facing +x (the challenge's start and heading); the
    goal is the challenge's, 10 m ahead (4.19 m). A run ends in ``success`` (within the scaled
    1 m of the goal), ``collision`` (touching a cylinder), ``timeout`` (the challenge's 100 s
    at the Jackal's 2 m/s, for the scaled way at this car's top speed: 167.4 s) or
    ``failure`` (flipped over, left the arena). docs/barn.md says what differs from the
    Jackal's contest.

    ## Observation Space

    SmartCarNav-v0's (odometry, wheels, the goal through odometry, the previous action, the
    scan's sectors), then ``waypoint_base``: the global path's next waypoint (``lookahead``
    metres along it beyond the point nearest the odometry pose) in the odometry base_link
    frame. No ground truth. The global path is planned once per world on its occupancy grid
    (0.02 m cells) with the cylinders inflated by half the simulated car's width (0.105 m: the
    default ``wheel_contact="sphere"`` makes the wheels spheres), Dijkstra as move_base's
    navfn: ``env.unwrapped.global_path`` (the map frame, where odometry starts), the same
    path the DWA driver follows.

    With ``localize=True`` the waypoint is taken from the pose on the map instead, as amcl
    gives move_base on a known map: each scan is matched to the world's known cylinders
    (``navigation.localization.ScanMatcher``: its hits brought onto the cylinders' outlines)
    to correct the map -> odom transform (``env.unwrapped.correction``; the pose on the map
    ``env.unwrapped.map_pose``), which starts as the identity (the known start). The
    odometry entries and the goal stay odometry's. DWA follows the path from the same pose.

    ## Episodes

    ``reset(options={"world": i})`` picks world i (0-299); without it a world is drawn with
    ``self.np_random`` from the 250 training worlds (the test worlds are 0, 6, ..., 294).

    ## Info

    SmartCarNav-v0's keys plus ``world``, ``outcome`` (None until the run ends), ``run_time_s``
    (AT: from when the car has moved 0.1 m scaled), ``optimal_time_s`` (OT: the challenge's
    path length, scaled, at ``max_linear``), ``score`` (``OT / clip(AT, 2 OT, 8 OT)`` on
    success, at most 0.5) and ``score_025`` (the metric before 2024, clip from 4 OT: at most
    0.25); the scores are 0 until a success.

    ## Arguments

    SmartCarNav-v0's but those the protocol sets (goal, arena, obstacles), and
    ``lookahead`` (0.5 m), ``world_file`` (None: the shipped worlds) and ``progress``:
    ``"goal"`` (the default) rewards the progress towards the goal as SmartCarNav-v0 does,
    ``"path"`` the progress along the global path instead (the same weight, on the car's
    ground-truth distance to go: its distance to the path's nearest point plus the path
    beyond it), which does not pull the car at the cylinders between it and the goal.
    ``localize`` (False) takes the waypoint from the scan-matched pose on the map (above); it
    needs the laser at the controller's rate (the shipped 10 Hz).
    """

    reset_options = ("world",)
    env_name = "SmartCarBARN-v0"
    pillars = True  # 0.3 m cylinders: on pybullet capsules, their scans 2.6x faster

    def __init__(self, model: str | os.PathLike | RobotModel | None = None, *,
                 model_args: Mapping[str, Any] | None = None,
                 world_file: str | os.PathLike | None = None, lookahead: float = 0.5,
                 collision_penalty: float = 10.0,
                 laser: Mapping[str, Any] | LaserConfig | None = None,
                 laser_mount: Sequence[float] | None = None, scan_sectors: int = 36,
                 progress: str = "goal", localize: bool = False, **kwargs: Any) -> None:
        given = [name for name in PROTOCOL_KWARGS if name in kwargs]
        if given:
            raise TypeError(f"SmartCarBARN-v0 takes no {', '.join(given)}: the BARN protocol "
                            "sets the goal, the arena and the obstacles")
        if not (isinstance(lookahead, int | float) and math.isfinite(lookahead)
                and lookahead > 0):
            raise ValueError(f"lookahead must be a distance > 0 m, got {lookahead!r}")
        self.worlds = load_worlds(world_file)
        model = nav_model(model, model_args, kwargs)
        if not isinstance(model, RobotModel):
            model = load_model(model, package_path=kwargs.pop("package_path", None),
                               wheels=kwargs.pop("wheels", None))
        self.protocol = BarnProtocol(car_width(model) / JACKAL_WIDTH_M,
                                     float(kwargs.get("max_linear", 0.5)))
        self.lookahead_m = float(lookahead)
        if progress not in PROGRESS:
            raise ValueError(f"progress must be one of {', '.join(PROGRESS)}, got {progress!r}")
        self.progress = progress
        if not isinstance(localize, bool):
            raise ValueError(f"localize must be True or False, got {localize!r}")
        #: whether the waypoint follows the pose on the map (scan matching), else odometry
        self.localize = localize
        goal = self.protocol.goal_distance_m
        super().__init__(model, obstacles=0, obstacle_clearance=0.0,
                         collision_penalty=collision_penalty, laser=laser,
                         laser_mount=laser_mount, scan_sectors=scan_sectors,
                         goal_range=(goal, goal),
                         goal_tolerance=self.protocol.success_radius_m,
                         arena_size=2.5 * goal, **kwargs)
        self.timeout_steps = self.protocol.timeout_steps(self.robot.update_period_ns * 1e-9)
        if localize and self.laser_config.rate_hz != self.controller_config.rate_hz:
            raise ValueError(f"localize=True matches each scan with the odometry of its instant: "
                             f"the laser's rate_hz ({self.laser_config.rate_hz:g}) must be the "
                             f"controller's ({self.controller_config.rate_hz:g})")
        #: base_link on the map (x, y, yaw), as the last observation saw it
        self.map_pose: Pose = IDENTITY
        #: this episode's localization on its world's map (``localize``; else None)
        self.localizer: Localizer | None = None
        #: the weight of the progress along the global path (0: the progress to the goal)
        self.path_progress_weight = 0.0
        if progress == "path":
            self.path_progress_weight = self.task.progress_weight
            self.task = replace(self.task, progress_weight=0.0)
        self.world: BarnWorld | None = None
        self.global_path = np.zeros((0, 2))
        self._paths: dict[int, np.ndarray] = {}
        self.outcome: str | None = None

    def _declare_observation(self) -> Observation:
        a = self.task.arena_half_size_m
        return Observation.compose(
            BARN_OBSERVATION_ORDER, robot_entries(observed_wheels(self.robot_model), 2 * a),
            self.task.observation_entries(), [previous_action_entry()],
            [scan_entry(self.laser_config, self.scan_sectors)], [waypoint_entry(a)],
        )

    # -- reset -------------------------------------------------------------------------------
    def _check_options(self, options: Any) -> np.ndarray:
        SmartCarEnv._check_options(self, options)  # a dict of known keys
        if options is not None and "world" in options:
            world = self.worlds.world(options["world"])
        else:
            world = self.worlds.world(int(self.np_random.choice(TRAIN_WORLDS)))
        self.world = world
        centres = to_car_frame(world.centres, self.protocol.scale)
        radii = world.radii * self.protocol.scale
        self._centres, self._radii = centres, radii
        self._next_layout = tuple(Obstacle("cylinder", (float(x), float(y)), (2.0 * float(r),))
                                  for (x, y), r in zip(centres, radii, strict=True))
        self._goal_given = True
        return to_car_frame(np.array(GOAL_XY), self.protocol.scale)

    def _build_world(self) -> None:
        super()._build_world()
        self.global_path = self._global_path()
        self.tracker = PathTracker(self.global_path, self.lookahead_m)
        if self.localize:
            self.localizer = Localizer(ScanMatcher(self._centres, self._radii),
                                       *beam_geometry(self.laser_config.angles,
                                                      self.laser.mount))
        self._reward_tracker = PathTracker(self.global_path, 0.0)  # ground truth, for rewards
        self._to_go = self._reward_tracker.to_go(np.zeros(2))
        self._clock = RunClock(np.zeros(2), self.protocol.moved_m)
        self._optimal = self.protocol.optimal_time_s(self.world.path_length_m
                                                     * self.protocol.scale)
        self._steps = 0
        self.outcome = None

    def _global_path(self) -> np.ndarray:
        """The world's global path (cached): Dijkstra on its grid, cylinders inflated by half
        the simulated car's width, from the start to the goal."""
        index = self.world.index
        if index not in self._paths:
            margin = MAP_MARGIN_M
            low = np.minimum(self._centres.min(axis=0), [0.0, 0.0]) - margin
            high = np.maximum(self._centres.max(axis=0), self.goal) + margin
            grid = distance_grid(self._centres, self._radii, low, high, GRID_RESOLUTION_M)
            half_width = footprint_half_extents(self.robot_model, self.wheel_contact)[1]
            self._paths[index] = plan_path(grid, np.zeros(2), self.goal, half_width)
        return self._paths[index]

    @property
    def planned_paths(self) -> dict[int, np.ndarray]:
        """The global paths planned so far, by world."""
        return dict(self._paths)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = super().reset(seed=seed, options=options)
        return obs, self._barn_info(info)

    # -- step ----------------------------------------------------------------------------------
    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = super().step(action)
        if self.path_progress_weight:
            to_go = self._reward_tracker.to_go(info["pose"][:2])
            reward = float(reward + self.path_progress_weight * (self._to_go - to_go))
            self._to_go = to_go
        self._steps += 1
        self._clock.update(info["pose"][:2], self.sim.time_s)
        if info["collision"]:
            self.outcome = COLLISION
        elif info["is_success"]:
            self.outcome = SUCCESS
        elif terminated:
            self.outcome = FAILURE
        elif self._steps >= self.timeout_steps:
            self.outcome, truncated = TIMEOUT, True
        return obs, reward, terminated, truncated, self._barn_info(info)

    def _clearance(self) -> float:
        """Nav's clearance, against the cylinders near the car only."""
        pose = self.robot.pose()
        reach = self.field.robot_radius_m + self.task.proximity_m
        near = np.hypot(self._centres[:, 0] - pose.x, self._centres[:, 1] - pose.y) - self._radii
        bodies = [self._obstacle_bodies[i] for i in np.flatnonzero(near < reach)]
        return nearest_distance(self.robot.body, bodies, self.task.proximity_m)

    def _barn_info(self, info: dict[str, Any]) -> dict[str, Any]:
        run_time = self._clock.elapsed_s(self.sim.time_s)
        optimal = self._optimal
        success = self.outcome == SUCCESS
        info.update(world=self.world.index, outcome=self.outcome, run_time_s=run_time,
                    optimal_time_s=optimal, score=barn_score(success, run_time, optimal),
                    score_025=barn_score(success, run_time, optimal, floor=4.0))
        return info

    def readings(self) -> Readings:
        """SmartCarNav-v0's readings plus the path's next waypoint (``extra["waypoint"]``)."""
        readings = super().readings()
        odom = readings.odometry
        pose = (odom.x, odom.y, odom.theta)
        if self.localizer is not None:
            scan = self.laser.latest
            pose = self.localizer.locate(pose, scan.stamp_s, scan.ranges)
        self.map_pose = pose
        waypoint = self.tracker.waypoint(np.array(pose[:2]))
        return Readings(readings.odometry, readings.joint_position, readings.joint_velocity,
                        readings.goal, readings.previous_action,
                        {**readings.extra, WAYPOINT_KEY: waypoint, MAP_POSE_KEY: pose})

    @property
    def correction(self) -> Pose:
        """map -> odom (x, y, yaw): the localization's correction (the identity without it)."""
        return IDENTITY if self.localizer is None else self.localizer.correction

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state.pop("tracker", None)
        state.pop("_reward_tracker", None)
        return state


def barn_vector_env(num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """SmartCarBARN-v0's ``vector_entry_point``: batched on an engine with a car batch
    (``SmartCarBatchVectorEnv``, the ``Barn`` part), else N single envs in a loop."""
    from smartcar_gym.envs.vector import make_vector_env

    return make_vector_env("SmartCarBARN-v0", num_envs, **kwargs)
