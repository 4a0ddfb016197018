"""SmartCarBARN-v0's task: the BARN worlds with the challenge's protocol, for any number of cars."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from smartcar_gym import checks
from smartcar_gym.envs.observation import Entry, Observation
from smartcar_gym.envs.sensors.scan import LaserConfig, scan_entry
from smartcar_gym.envs.state import SCAN, SCAN_TIME
from smartcar_gym.envs.tasks.barn.laser_map import (
    LaserMap,
    checked_planner_frequency,
    costmap_changes,
)
from smartcar_gym.envs.tasks.barn.protocol import (
    COLLISION,
    FAILURE,
    SUCCESS,
    TIMEOUT,
    BarnProtocol,
    RunClock,
    barn_score,
)
from smartcar_gym.envs.tasks.base import Cars, CarSettings, Score
from smartcar_gym.envs.tasks.nav import NAV_OBSERVATION_ORDER, NavTask
from smartcar_gym.envs.tasks.obstacles import Obstacle
from smartcar_gym.envs.tasks.reach import pose_columns
from smartcar_gym.model.footprint import car_width, footprint_half_extents
from smartcar_gym.navigation.costmap import CostmapConfig, LaserCostmaps
from smartcar_gym.navigation.grid_planner import NoPathError, distance_grid, plan_path
from smartcar_gym.navigation.localization import (
    IDENTITY,
    Localizer,
    Pose,
    ScanMatcher,
    beam_geometry,
)
from smartcar_gym.navigation.path_trackers import PathTrackers
from smartcar_gym.parallel import run_chunks
from smartcar_gym.sim.clock import NS_PER_S
from smartcar_gym.worlds.barn import (
    GOAL_XY,
    JACKAL_TOP_SPEED_M_S,
    JACKAL_WIDTH_M,
    BarnWorld,
    BarnWorldError,
    load_worlds,
    to_car_frame,
)

PROGRESS = ("goal", "path")  # what the progress reward measures
#: where the global path comes from: the world's known cylinders, or the car's own scans
MAP_MODES = ("known", "laser")
BARN_OBSERVATION_ORDER = (*NAV_OBSERVATION_ORDER, "waypoint_base")
GRID_RESOLUTION_M = 0.02  # the global planner's map
MAP_MARGIN_M = 0.3  # free map around the cylinders, the start and the goal
#: the keywords the protocol sets
PROTOCOL = "the BARN protocol sets the goal, the arena and the obstacles"
PROTOCOL_KWARGS = ("goal_range", "goal_tolerance", "arena_size", "obstacles", "obstacle_size",
                   "obstacle_clearance", "obstacle_layout")


def waypoint_entry(arena_half_size_m: float) -> Entry:
    """The global path's next waypoint in the base_link frame of the pose on the map (the
    odometry's, through the localization's correction if any)."""
    a = arena_half_size_m
    return Entry("waypoint_base", ("waypoint_x_base", "waypoint_y_base"), -4 * a, 4 * a, "m",
                 "the global path's next waypoint in the base_link frame (ahead, left), "
                 "through odometry (or localize's pose on the map)", ("-4A", "4A"))


class BarnTask(NavTask):
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

    With ``map_mode="laser"`` nothing of the world is known but the start, the goal and the
    car, as in the challenge's move_base: each car builds the challenge's global costmap from
    its own scans (``navigation.costmap``: marking and clearing, inflation, the challenge's
    values scaled; in the odom frame, centred on the start), and its global path is planned on
    what it has seen (unseen cells are free; navfn's costs) at the challenge's planner rate
    (20 Hz, scaled with the world and the speed) and at once when a new mark blocks it
    (``navigation.costmap_planner.Replanner``); the waypoint comes from that path, through
    odometry (``env.unwrapped.costmaps``, ``global_path``). Until a plan succeeds the path is
    the straight line to the goal.

    With ``map_mode="laser"`` and ``localize=True`` the odometry is corrected as a laser SLAM
    front end corrects it: each scan is matched to the map the car's earlier scans made
    (``navigation.scan_map.ScanMaps``: point-to-line ICP against one kept return per costmap
    cell), the map -> odom correction starting as the identity (``env.unwrapped.correction``),
    and the pose on that map (``env.unwrapped.map_pose``) takes the odometry pose's place
    everywhere the car's pose is read: the costmap is marked there, the path planned and
    followed from there, and the observation's ``odom_position``, ``odom_heading``,
    ``goal_base`` and ``goal_distance`` are that pose's (the velocities, the wheels and
    ``info``'s ``odom_pose`` stay the odometry's). No ground truth is read.

    ## Episodes

    ``reset(options={"world": i})`` picks world i (an integer, 0-299); without it a world is
    drawn with ``self.np_random`` from the world file's training worlds (the shipped file's
    250; the test worlds are 0, 6, ..., 294). No step limit but the protocol's timeout,
    which follows ``max_linear``: every run ends with an outcome.
    Batched, ``world`` is one index for every reset car or one per car.

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
    ``localize`` (False) takes the pose from the scans (above): matched to the known
    cylinders, or with ``"laser"`` to the car's own map; it needs the laser at the
    controller's rate (the shipped 10 Hz). ``map_mode``: ``"known"`` (the default: the
    world's cylinders) or ``"laser"`` (the car's own costmap, above). With ``"laser"``,
    ``progress="path"`` still measures the progress along the known map's path: a training
    signal from the simulator's truth, as the reward's other terms are; the observation holds
    nothing of it.
    ``costmap`` (``map_mode="laser"``): a dict of ``CostmapConfig`` fields (m) replacing the
    challenge's scaled ones, e.g. ``{obstacle_range: 3.0, raytrace_range: 3.5,
    inscribed_radius: 0.125, inflation_radius: 0.25}`` (the shipped mapless policy's: marking
    all the laser sees, the car's half width padded by 2 cm). ``planner_frequency``
    (``map_mode="laser"``; None: the challenge's 20 Hz, scaled as the other times): move_base's
    replanning rate; 0 plans only when a new mark blocks the path (the shipped mapless
    policy's), as move_base with ``planner_frequency: 0``.

    ## Version History

    * v0 (0.5.0): ``map_mode="laser"`` (with ``progress="path"``: the known path's progress
      as the reward; with ``localize``, the scans matched to the car's own map);
      ``costmap``, ``planner_frequency``; no step limit but the protocol's
      timeout (was 1676 steps); the world file's own split; the task written once for the
      single and the batched envs (``BarnTask``).
    * v0 (0.4.0): initial version (the known map, ``localize``, ``progress``).
    """

    option_keys = ("world",)
    per_car = ("obstacles", "world_index", "optimal", "global_paths", "matchers")
    exports = ("obstacles", "clearance", "collision", "laser_config", "scan_sectors", "mount",
               "worlds", "protocol", "timeout_steps", "global_paths", "global_path",
               "planned_paths", "waypoints", "localize", "corrections", "correction",
               "map_poses", "map_pose", "world", "world_index", "outcome", "lookahead_m",
               "progress", "path_progress_weight", "map_mode", "costmaps", "costmap_config")
    refused_keywords = {name: PROTOCOL for name in PROTOCOL_KWARGS}
    bytes_per_car = 64 * 1024  # its obstacles, latest scan, global path and tracker
    pillars = True  # 0.3 m cylinders: on pybullet capsules, their scans 2.6x faster

    def __init__(self, world_file: str | os.PathLike | None = None, lookahead: float = 0.5,
                 collision_penalty: float = 10.0, proximity_penalty: float = 0.0,
                 proximity_m: float = 0.3,
                 laser: Mapping[str, Any] | LaserConfig | None = None,
                 laser_mount: Sequence[float] | None = None, scan_sectors: int = 36,
                 progress: str = "goal", localize: bool = False,
                 stop_speed: float | None = None, map_mode: str = "known",
                 costmap: Mapping[str, float] | None = None,
                 planner_frequency: float | None = None) -> None:
        if not (checks.is_finite(lookahead) and lookahead > 0):
            raise ValueError(f"lookahead must be a distance > 0 m, got {lookahead!r}")
        self.worlds = load_worlds(world_file)
        self.lookahead_m = float(lookahead)
        if progress not in PROGRESS:
            raise ValueError(f"progress must be one of {', '.join(PROGRESS)}, got {progress!r}")
        self.progress = progress
        #: whether the waypoint follows the pose on the map (scan matching), else odometry
        self.localize = checks.flag("localize", localize)
        if map_mode not in MAP_MODES:
            raise ValueError(f"map_mode must be one of {', '.join(map(repr, MAP_MODES))}, got "
                             f"{map_mode!r}")
        #: where the global path comes from: "known" (the world's cylinders) or "laser"
        self.map_mode = map_mode
        #: the laser costmap's fields changed from the challenge's scaled ones
        self.costmap_changes = costmap_changes(costmap, map_mode)
        #: move_base's planner_frequency on the laser map (Hz before scaling; the challenge's
        #: 20 unless given; 0: only when the path is blocked)
        self.planner_frequency = checked_planner_frequency(planner_frequency, map_mode)
        #: the global paths planned so far, by world
        self.planned_paths: dict[int, np.ndarray] = {}
        #: each world's cylinders in the car's start frame so far, by world: centres (M, 2),
        #: radii (M,) m and their obstacles
        self.layouts: dict[int, tuple[np.ndarray, np.ndarray, tuple[Obstacle, ...]]] = {}
        # the reaching task's goal and arena come from the protocol, once the car is known
        super().__init__(obstacles=0, obstacle_clearance=0.0,
                         collision_penalty=collision_penalty,
                         proximity_penalty=proximity_penalty, proximity_m=proximity_m,
                         laser=laser, laser_mount=laser_mount, scan_sectors=scan_sectors,
                         stop_speed=stop_speed)

    def bind(self, car: CarSettings) -> None:
        """The protocol for this car (its width and top speed), then Nav's settings."""
        #: the challenge's protocol scaled to the car
        self.protocol = BarnProtocol(car_width(car.robot_model) / JACKAL_WIDTH_M,
                                     car.max_linear)
        goal = self.protocol.goal_distance_m
        self.goal_range_m = (goal, goal)
        self.goal_tolerance_m = self.protocol.success_radius_m
        self.arena_half_size_m = 2.5 * goal / 2.0
        super().bind(car)
        #: steps before a run times out
        self.timeout_steps = self.protocol.timeout_steps(car.period_s)
        rate = car.controller_config.rate_hz
        if self.localize and self.laser_config.rate_hz != rate:
            raise ValueError(f"localize=True matches each scan with the odometry of its instant: "
                             f"the laser's rate_hz ({self.laser_config.rate_hz:g}) must be the "
                             f"controller's ({rate:g})")
        #: the weight of the progress along the global path (0: the progress to the goal)
        self.path_progress_weight = 0.0
        if self.progress == "path":
            self.path_progress_weight, self.progress_weight = self.progress_weight, 0.0
        self._half_width = footprint_half_extents(car.robot_model, car.wheel_contact)[1]
        self._beams = beam_geometry(self.laser_config.angles, self.mount)
        #: the laser costmap's settings (``map_mode="laser"``): the challenge's, scaled, with
        #: the car's half width as its inscribed radius
        self.costmap_config = (dataclasses.replace(
            CostmapConfig.challenge(self.protocol.scale, self._half_width),
            **self.costmap_changes) if self.map_mode == "laser" else None)

    def declare(self) -> Observation:
        return self.compose(BARN_OBSERVATION_ORDER,
                            [scan_entry(self.laser_config, self.scan_sectors)],
                            [waypoint_entry(self.arena_half_size_m)])

    def attach(self, num: int) -> None:
        super().attach(num)
        #: each car's world, its OT, its global path (odom frame) and its map's matcher
        self.world_index = np.zeros(num, dtype=np.int64)
        self.optimal = np.zeros(num)
        self.global_paths: list[np.ndarray] = [np.zeros((0, 2))] * num
        self.matchers: list[ScanMatcher | None] = [None] * num
        #: each car's next waypoint in its base_link frame on the map, (N, 2), and base_link
        #: on the map (x, y, yaw) as the last observation saw it, (N, 3)
        self.waypoints = np.zeros((num, 2))
        self.map_poses = np.zeros((num, 3))
        self.outcome = np.full(num, None, dtype=object)
        self._trackers = PathTrackers(num, self.lookahead_m)
        #: each car's ground-truth distance to go along its path (``progress="path"``)
        self._reward_trackers = PathTrackers(num, 0.0)
        self._to_go = np.zeros(num)
        self._clocks = [RunClock(np.zeros(2), self.protocol.moved_m) for _ in range(num)]
        self._localizers: list[Localizer | None] = [None] * num
        #: each car's AT and scores, (3, N)
        self._timing = np.zeros((3, num))
        self._timeout = np.zeros(num, dtype=bool)
        #: ``map_mode="laser"``: each car's costmap and the planning on it
        self._laser_map = None if self.costmap_config is None else LaserMap(
            self.costmap_config, num, self.protocol.scale,
            self.car.max_linear / JACKAL_TOP_SPEED_M_S, self.laser_config.angles, self.mount,
            self.planner_frequency, self.localize)

    def only_build(self) -> None:
        """A builder keeps no laser map: the batch's own ``begin`` marks the first scan and
        plans (its ``global_paths`` row is the straight line or the known map's path, as
        ``build`` left it, which the batch's first plan replaces; a failed one keeps that line
        as a single env's does)."""
        super().only_build()
        self._laser_map = None

    # -- what a single env shows of its car ----------------------------------------------------
    @property
    def costmaps(self) -> LaserCostmaps | None:
        """Each car's laser costmap (``map_mode="laser"``; None on the known map)."""
        return None if self._laser_map is None else self._laser_map.costmaps

    @property
    def world(self) -> BarnWorld:
        """The first car's world (a single env's)."""
        return self.worlds.world(int(self.world_index[0]))

    @property
    def global_path(self) -> np.ndarray:
        """The first car's global path (a single env's)."""
        return self.global_paths[0]

    @property
    def corrections(self) -> list[Pose]:
        """Each car's map -> odom correction (the identity without ``localize``; laser: on
        the map of its own scans)."""
        if self._laser_map is not None and self.localize:
            return [tuple(row) for row in self._laser_map.corrections.tolist()]
        return [IDENTITY if loc is None else loc.correction for loc in self._localizers]

    @property
    def correction(self) -> Pose:
        """map -> odom (x, y, yaw) of the first car (a single env's)."""
        return self.corrections[0]

    @property
    def map_pose(self) -> Pose:
        """Base_link on the map of the first car (a single env's), as its last observation
        saw it."""
        return tuple(float(v) for v in self.map_poses[0])

    # -- reset ---------------------------------------------------------------------------------
    def check_option(self, key: str, value: Any, vector: bool) -> list[Any]:
        if key != "world":
            return super().check_option(key, value, vector)
        if vector and isinstance(value, list | tuple | np.ndarray):
            chosen = list(value)
            if len(chosen) != self.num:
                raise ValueError(f"options['world'] must be a world index or {self.num} of them "
                                 f"(one per car), got {len(chosen)}")
        else:
            chosen = [value] * self.num
        return [self.worlds.world(index).index for index in chosen]

    def start(self, cars: Cars, idx: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """Each car's world (given, or drawn from the world file's training worlds) and the
        goal the protocol sets."""
        goal = to_car_frame(np.array(GOAL_XY), self.protocol.scale)
        for i in idx.tolist():
            index = options[i].get("world")
            if index is None:
                index = self.worlds.world(int(cars.rng(i).choice(self.worlds.train_worlds))).index
            self.world_index[i] = index
            cars.state.goal[i] = goal

    def build(self, cars: Cars, idx: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """Each car's cylinders, its global path and OT, and its map's scan matcher."""
        scale = self.protocol.scale
        for i in idx.tolist():
            world = self.worlds.world(int(self.world_index[i]))
            if world.index not in self.layouts:
                centres, radii = to_car_frame(world.centres, scale), world.radii * scale
                centres.setflags(write=False)
                radii.setflags(write=False)
                self.layouts[world.index] = (centres, radii, tuple(
                    Obstacle("cylinder", (float(x), float(y)), (2.0 * float(r),))
                    for (x, y), r in zip(centres, radii, strict=True)))
            centres, radii, layout = self.layouts[world.index]
            self.obstacles[i] = layout
            cars.place_obstacles(i, layout, self.pillars)
            # laser: planned on the car's costmap once it has scanned (begin)
            self.global_paths[i] = (self.plan(world.index) if self.map_mode == "known"
                                    else np.array([[0.0, 0.0], cars.state.goal[i]]))
            self.optimal[i] = self.protocol.optimal_time_s(world.path_length_m * scale)
            self.matchers[i] = (ScanMatcher(centres, radii)
                                if self.localize and self.map_mode == "known" else None)

    def plan(self, index: int) -> np.ndarray:
        """World ``index``'s global path in the car's start frame (cached in
        ``planned_paths``): Dijkstra on its grid, bounded by the arena, the cylinders inflated
        by half the simulated car's width, from the start to the goal. BarnWorldError naming
        the world and the file if there is no way."""
        if index not in self.planned_paths:
            world, scale = self.worlds.world(index), self.protocol.scale
            centres, radii = to_car_frame(world.centres, scale), world.radii * scale
            goal = to_car_frame(np.array(GOAL_XY), scale)
            arena = self.arena_half_size_m
            low = np.maximum(np.minimum(centres.min(axis=0), [0.0, 0.0]) - MAP_MARGIN_M, -arena)
            high = np.minimum(np.maximum(centres.max(axis=0), goal) + MAP_MARGIN_M, arena)
            grid = distance_grid(centres, radii, low, high, GRID_RESOLUTION_M)
            try:
                path = plan_path(grid, np.zeros(2), goal, self._half_width)
            except NoPathError as err:
                raise BarnWorldError(f"BARN world {index} of {self.worlds.source} has no way "
                                     f"for this car: {err}") from None
            self.planned_paths[index] = path
        return self.planned_paths[index]

    def begin(self, cars: Cars, idx: np.ndarray) -> None:
        """A fresh run: its clock, no outcome, the path followed from its start (laser: its
        costmap cleared, marked with its first scan and planned on)."""
        super().begin(cars, idx)
        if self._laser_map is not None and len(idx):
            self._laser_map.start(cars.state, idx, self.global_paths, cars.threads)
        for i in idx.tolist():
            self._clocks[i] = RunClock(np.zeros(2), self.protocol.moved_m)
            self._trackers.start(i, self.global_paths[i])
            # progress="path": the known map's path in either mode (laser: a training signal
            # the observation never sees)
            self._reward_trackers.start(i, self.plan(int(self.world_index[i]))
                                        if self.path_progress_weight else self.global_paths[i])
            self._to_go[i] = self._reward_trackers.to_go([i], np.zeros((1, 2)))[0]
            matcher = self.matchers[i]
            self._localizers[i] = None if matcher is None else Localizer(matcher, *self._beams)
        if len(idx):
            self._follow(cars, idx)
        self.outcome[idx] = None
        self._timeout[idx] = False

    def _follow(self, cars: Cars, idx: np.ndarray) -> None:
        """Cars ``idx``' next waypoints from their odometry, or their pose on the map after
        matching a new scan (laser: on the path planned on their costmap)."""
        state = cars.state
        if self._laser_map is not None and len(idx):
            for i in self._laser_map.update(state, idx, self.global_paths, cars.threads):
                self._trackers.start(i, self.global_paths[i])
            poses = self._laser_map.poses(state, idx)
        else:
            poses = state.odometry[idx, :3].astype(float)
        if self.localize and self.map_mode == "known":
            odoms = [tuple(row) for row in poses.tolist()]
            scans = state.readings[SCAN_TIME][idx].tolist()  # each car's scan's key: its time
            ranges = state.readings[SCAN][idx]
            localizers = [self._localizers[i] for i in idx.tolist()]

            def match(a: int, z: int) -> None:  # the cars split over threads (the compiled
                for k in range(a, z):           # matcher frees the GIL)
                    localizers[k].match(odoms[k], scans[k], ranges[k])

            run_chunks(match, len(idx), cars.threads)
            for k, localizer in enumerate(localizers):
                poses[k] = localizer.locate(odoms[k], scans[k], ranges[k])
        self.map_poses[idx] = poses
        self.waypoints[idx] = self._trackers.waypoints_in_base(idx, poses)

    # -- step ----------------------------------------------------------------------------------
    def score(self, cars: Cars, action: np.ndarray) -> Score:
        """Nav's terms (and the progress along the path), the run's clock and outcome, the
        timeout and the next waypoint (a parked car stands: as timed and followed)."""
        reward, success, failure = super().score(cars, action)
        state = cars.state
        pose, now = state.pose, state.now_ns
        if self.path_progress_weight:
            to_go = self._reward_trackers.to_go(np.arange(self.num), pose[:, :2])
            self.terms["path"] = self.path_progress_weight * (self._to_go - to_go)
            self._to_go = to_go
            reward = self.reward()
        running = np.flatnonzero(~state.parked)
        for i in running.tolist():
            self._clocks[i].update(pose[i, :2], int(now[i]) / NS_PER_S)
        self._follow(cars, running)
        collision = self.collision
        ended = collision | success | failure
        self._timeout = ~ended & (state.steps >= self.timeout_steps)
        for outcome, mask in ((TIMEOUT, self._timeout), (FAILURE, failure),
                              (SUCCESS, success), (COLLISION, collision)):
            self.outcome[mask] = outcome  # the last one written wins
        return reward, success, failure

    def truncated(self, cars: Cars) -> np.ndarray:
        return self._timeout.copy()

    def columns(self, cars: Cars) -> dict[str, Any]:
        columns = super().columns(cars)
        if self.localize and self.map_mode == "laser":  # the pose on the map, not odometry's
            columns.update(pose_columns(self.map_poses, cars.state.goal))
        columns["waypoint_base"] = (self.waypoints[:, 0], self.waypoints[:, 1])
        return columns

    def info(self, cars: Cars, success: np.ndarray) -> dict[str, np.ndarray]:
        """Nav's, and the world, outcome, AT, OT and both scores (a parked car's as they
        were: its clock stands)."""
        state = cars.state
        run_time, score, score_025 = self._timing
        for i in np.flatnonzero(~state.parked).tolist():
            run_time[i] = at = self._clocks[i].elapsed_s(int(state.now_ns[i]) / NS_PER_S)
            won = self.outcome[i] == SUCCESS
            score[i] = barn_score(won, at, self.optimal[i])
            score_025[i] = barn_score(won, at, self.optimal[i], floor=4.0)
        return {**super().info(cars, success), "world": self.world_index.copy(),
                "outcome": self.outcome.copy(), "run_time_s": run_time.copy(),
                "optimal_time_s": self.optimal.copy(), "score": score.copy(),
                "score_025": score_025.copy()}
