"""Navigation: reach a goal among obstacles without touching them, seeing them by laser.

``NavTask`` is goal reaching (``ReachTask``) plus the obstacles of each episode (drawn by an
``ObstacleField`` or given), a 2D laser whose scan the policy sees, and a collision term:
touching an obstacle costs ``collision_penalty`` and ends the episode.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from smartcar_gym import checks
from smartcar_gym.controller.config_yaml import calibrated_config_path
from smartcar_gym.envs.observation import Observation
from smartcar_gym.envs.sensors.laser import mount_from_model, mount_from_pose
from smartcar_gym.envs.sensors.scan import SCAN_KEY, LaserConfig, scan_entry, scan_sectors
from smartcar_gym.envs.state import SCAN, SCAN_TIME
from smartcar_gym.envs.tasks.base import Cars, CarSettings, Score
from smartcar_gym.envs.tasks.obstacles import (
    MAX_TRIES,
    Obstacle,
    ObstacleField,
    clearance,
    read_layout,
)
from smartcar_gym.envs.tasks.reach import CARD_WHEELS, OBSERVATION_ORDER, ReachTask, card_table
from smartcar_gym.model.footprint import footprint_radius

#: SmartCar-v0's rows, then the scan
NAV_OBSERVATION_ORDER = (*OBSERVATION_ORDER, SCAN_KEY)


def laser_config(laser: Mapping[str, Any] | LaserConfig | None) -> LaserConfig:
    """The ``laser`` argument as a ``LaserConfig``: None (the defaults), a config, or a dict of
    the fields to change; an error naming an unknown field or a bad value."""
    if laser is None or isinstance(laser, LaserConfig):
        return laser or LaserConfig()
    if not isinstance(laser, Mapping):
        raise TypeError(f"laser must be a dict of LaserConfig fields or a LaserConfig, got "
                        f"{type(laser).__name__}: {laser!r}")
    fields = [f.name for f in dataclasses.fields(LaserConfig)]
    unknown = sorted(set(map(str, laser)) - set(fields))
    if unknown:
        raise ValueError(f"laser: unknown field(s) {unknown}; LaserConfig has "
                         f"{', '.join(fields)}")
    return LaserConfig(**laser)


class NavTask(ReachTask):
    """## Description

    SmartCar-v0 among obstacles: the same car, controller, actions and goal, plus static boxes
    and cylinders between the start and the goals, and a 2D laser scanner on the car (the
    ``laser`` link that the seed's rviz configuration lists) whose scan the policy sees.
    Touching an obstacle ends the episode. The scanner works like a ``sensor_msgs/LaserScan``
    source: beams from ``angle_min`` to ``angle_max`` every ``angle_increment``, ranges in
    [``range_min``, ``range_max``], ``+inf`` where nothing is within range and ``-inf`` where
    something is closer than ``range_min`` (REP 117), one scan every ``1 / rate_hz`` s of
    simulated time, optional Gaussian range noise. Each scan is one batched ray cast;
    ``env.unwrapped.laser.latest`` is the latest ``LaserScan`` (the state's ``scan``
    reading).

    ## Observation Space

    ``Box(low, high, (57,), float32)`` (with the default 36 scan sectors): SmartCar-v0's
    21 values, then the scan:

    {observation_table}

    where A = ``arena_size / 2``. Sector i holds the nearest range of beams
    ``i * B // S`` to ``(i + 1) * B // S - 1`` of the B beams, S sectors (the default: 10 beams,
    10 degrees each; sector 0 starts at angle_min = -180 degrees, i.e. behind the car, and they
    go counter-clockwise, so sector 18 starts straight ahead). ``+inf`` reads ``range_max``,
    ``-inf`` reads 0. ``env.unwrapped.observation_names`` names every value
    (``scan_00`` ...).

    ## Rewards

    SmartCar-v0's (``10 * (d_prev - d) - 0.01 - 0.01 * |a|^2``, ``+10`` on reaching the goal,
    ``-10`` on flipping over or leaving the arena), plus ``-collision_penalty`` (10) when the
    car touches an obstacle.

    ## Starting State

    As SmartCar-v0 (the car at the origin facing +x, the goal at a uniform distance in
    ``goal_range`` and bearing), then the obstacles: ``obstacles`` of them drawn with
    ``self.np_random``, centred in the square ``|x|, |y| <= goal_range[1]``, each a box or a
    cylinder with equal chance, sides and diameters uniform in ``obstacle_size``, each keeping
    ``obstacle_clearance`` of free space around the car's footprint circle (0.15 m for the
    shipped car) at the start and at the goal, and 0.3 m from the others (the car fits
    through every gap). Or a given layout: ``obstacle_layout`` (every episode) or
    ``reset(options={"obstacles": layout})`` (this episode), where a layout is a list of
    ``{"shape": "box" | "cylinder", "position": [x, y], "size": [length, width] | [diameter],
    "yaw": rad}`` or the path of a YAML/JSON file holding one; with a given layout, a drawn
    goal is drawn again until it keeps that clearance. Obstacles are 0.3 m tall. The first
    scan is taken at t = 0. Options: ``goal``, ``obstacles``.

    ## Episode End

    Terminated on reaching the goal (ground-truth distance under ``goal_tolerance``), touching
    an obstacle (``info["collision"]``), flipping over or leaving the arena. Truncated by the
    ``TimeLimit`` (200 steps = 20 s for SmartCarNav-v0). ``info``: SmartCar-v0's keys plus
    ``collision`` (bool) and ``clearance`` (m to the nearest obstacle, at most
    ``proximity_m``).

    ## Arguments

    The env's and SmartCar-v0's, with these defaults changed: ``controller_config`` is the
    shipped ``smartcar_arbotix_calibrated.yaml`` (the tutorial's YAML with odometry
    calibrated: ``base_width`` 0.33 m, the car's effective track, for the tutorial's 0.26,
    which overstates every turn by 27 % and puts odometry 0.25-0.5 m off over these drives),
    the shipped model is expanded with ``laser:=true`` (it adds the ``laser`` link),
    ``goal_range=(0.5, 2.0)``, ``goal_tolerance=0.2`` (the car's length; TurtleBot3 navigation
    work uses 0.2 m), ``arena_size=6.0``; and:

    | kwarg              | default        | meaning                                             |
    |--------------------|----------------|-----------------------------------------------------|
    | obstacles          | 8              | number of obstacles drawn per episode               |
    | obstacle_size      | (0.15, 0.35)   | min, max box side / cylinder diameter (m)           |
    | obstacle_clearance | 0.2            | free space around the car at the start and the goal |
    | obstacle_layout    | None           | a fixed layout (list or file) instead of drawing    |
    | collision_penalty  | 10.0           | reward lost when touching an obstacle               |
    | proximity_penalty  | 0.0            | reward lost per step at most within ``proximity_m``  |
    | proximity_m        | 0.3            | how near an obstacle starts to cost (m)             |
    | laser              | None           | ``LaserConfig`` fields to change (a dict): angle_min,|
    |                    |                | angle_max, angle_increment (rad), range_min,        |
    |                    |                | range_max (m), rate_hz, noise_std_m, frame_id       |
    | laser_mount        | None           | (x, y, z, yaw) of the scan frame in base_link;      |
    |                    |                | None: the model's ``laser`` link                    |
    | scan_sectors       | 36             | scan values in the observation (nearest per sector) |

    The laser defaults: 360 beams over the full turn (angle_min -pi, 1 degree increments),
    0.12 to 3.5 m, 10 Hz, no noise (a TurtleBot3 LDS-01-class lidar at the controller's
    rate). With noise, its generator is seeded from ``self.np_random`` at every reset.

    ## Vector envs

    ``gym.make_vec("SmartCarNav-v0", num_envs=N, vectorization_mode="vector_entry_point")``:
    with ``engine="mujoco"`` or ``"planar"``, N cars in one ``SmartCarBatchVectorEnv`` (each
    car's world built at its reset by a single env of the task, then its physics, laser and
    clearance stepped by the engine's car batch: in C on MuJoCo, against each car's obstacle
    outlines in arrays on planar; bit for bit N of this env, ``randomize`` too: each car
    the robot its episode draws); on pybullet, or with a ``render_mode`` or
    ``controller_mode="sim"``, N single envs stepped in a loop (``SmartCarLoopVectorEnv``);
    both with the smartcar vector conventions (docs/vector.md).

    ## Version History

    * v0 (0.5.0): the task written once for the single and the batched envs (``NavTask``).
    * v0 (0.4.0): ``engine="planar"`` and ``planar_params`` (SmartCar-v0's arguments;
      docs/planar.md): the laser and the clearance from the obstacles' exact outlines.
    * v0 (0.3.0): ``engine="mujoco"`` (SmartCar-v0's argument; docs/engines.md).
    * v0 (0.2.0): initial version.
    """

    option_keys = ("goal", "obstacles")
    builds_worlds = True
    per_car = ("obstacles",)
    exports = ("obstacles", "clearance", "collision", "laser_config", "scan_sectors", "mount",
               "field", "layout")
    car_exports = ("obstacles", "clearance", "collision")
    env_defaults = {"controller_config": calibrated_config_path()}
    model_args = {"laser": "true"}
    bytes_per_car = 48 * 1024  # its obstacles and latest scan
    #: the obstacles' cylinders are pillars (``sim.obstacles.add_obstacle``): not Nav's, whose
    #: tops a car may reach; BARN's
    pillars = False

    def __init__(self, obstacles: int = 8, obstacle_size: tuple[float, float] = (0.15, 0.35),
                 obstacle_clearance: float = 0.2,
                 obstacle_layout: Sequence[Mapping[str, Any]] | str | os.PathLike | None = None,
                 collision_penalty: float = 10.0, proximity_penalty: float = 0.0,
                 proximity_m: float = 0.3,
                 laser: Mapping[str, Any] | LaserConfig | None = None,
                 laser_mount: Sequence[float] | None = None, scan_sectors: int = 36,
                 goal_range: tuple[float, float] = (0.5, 2.0), goal_tolerance: float = 0.2,
                 arena_size: float = 6.0, stop_speed: float | None = None) -> None:
        self.laser_config = laser_config(laser)
        scan_entry(self.laser_config, scan_sectors)  # checks scan_sectors
        self.scan_sectors = scan_sectors
        #: the layout of every episode (None: drawn)
        self.layout = None if obstacle_layout is None else read_layout(obstacle_layout,
                                                                       "obstacle_layout")
        self.collision_penalty = checks.non_negative_number("collision_penalty",
                                                            collision_penalty)
        self.proximity_penalty = checks.non_negative_number("proximity_penalty",
                                                            proximity_penalty)
        self.proximity_m = checks.positive_number("proximity_m", proximity_m)
        self._mount_pose = laser_mount
        self._field = (obstacles, obstacle_size, obstacle_clearance)
        super().__init__(goal_range, goal_tolerance, arena_size, stop_speed)

    @property
    def laser(self) -> tuple[LaserConfig, np.ndarray]:
        return self.laser_config, self.mount

    def bind(self, car: CarSettings) -> None:
        """The laser's mount and the obstacle field, for this car's footprint."""
        super().bind(car)
        model = car.robot_model
        self.mount = (mount_from_pose(self._mount_pose) if self._mount_pose is not None
                      else mount_from_model(model))
        if self.mount is None:
            raise ValueError(f"{model.source} has no 'laser' link: pass "
                             "laser_mount=(x, y, z, yaw), the scan frame in base_link")
        count, size, keep = self._field
        #: how obstacles are drawn
        self.field = ObstacleField(count=count,
                                   size_range_m=checks.number_pair("obstacle_size", size),
                                   clearance_m=keep, half_extent_m=self.goal_range_m[1],
                                   robot_radius_m=footprint_radius(model))
        if self.layout is not None:
            self.check_layout(self.layout, "obstacle_layout")
        else:  # a field that cannot be drawn fails here, not in the middle of training
            for seed in range(3):
                self.field.sample(np.random.default_rng(seed), np.zeros(2),
                                  self.sample_goal(np.random.default_rng(seed)))

    def declare(self) -> Observation:
        return self.compose(NAV_OBSERVATION_ORDER, [scan_entry(self.laser_config,
                                                               self.scan_sectors)])

    @staticmethod
    def limits(kwargs: Any) -> str | None:
        if kwargs.get("render_mode") is not None:
            return ("render_mode: the batch's top-down tiles draw no obstacles or scans (the "
                    "single env's picture does)")
        return ReachTask.limits(kwargs)

    def attach(self, num: int) -> None:
        super().attach(num)
        #: each car's distance to its nearest obstacle (m, at most ``proximity_m``) and
        #: whether it touches one, as of the last step
        self.clearance = np.zeros(num)
        self.collision = np.zeros(num, dtype=bool)
        #: each car's obstacles this episode
        self.obstacles: list[tuple[Obstacle, ...]] = [()] * num
        #: the observation's sectors of each car's latest scan, and that scan's time
        self._sectors = np.zeros((num, self.scan_sectors))
        self._sectors_of = np.full(num, -1, dtype=np.int64)

    # -- reset ---------------------------------------------------------------------------------
    def check_options(self, options: Any, vector: bool) -> list[Mapping[str, Any]]:
        cars = super().check_options(options, vector)
        for car in cars:
            layout, goal = car.get("obstacles", self.layout), car.get("goal")
            if goal is not None and layout is not None and clearance(layout, goal) <= 0:
                raise ValueError(f"options['goal'] {goal.tolist()} lies inside an obstacle")
        return cars

    def check_option(self, key: str, value: Any, vector: bool) -> list[Any]:
        if key != "obstacles":
            return super().check_option(key, value, vector)
        layout = read_layout(value, "options['obstacles']")
        self.check_layout(layout, "options['obstacles']")
        return [layout] * self.num

    def check_layout(self, layout: tuple[Obstacle, ...], name: str) -> None:
        """A given layout must leave the car's footprint at the start free."""
        for i, obstacle in enumerate(layout):
            if obstacle.distance(np.zeros(2)) < self.field.robot_radius_m:
                raise ValueError(f"{name}[{i}] {obstacle.to_dict()} overlaps the car at the "
                                 f"start (a {self.field.robot_radius_m:.3f} m circle around "
                                 "the origin)")

    def build(self, cars: Cars, idx: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """Each car's obstacles: given (a drawn goal drawn again until it keeps clear of them)
        or drawn with its generator, placed in its world."""
        goal = cars.state.goal
        for i in idx.tolist():
            layout = options[i].get("obstacles", self.layout)
            if layout is None:
                layout = self.field.sample(cars.rng(i), np.zeros(2), goal[i])
            elif "goal" not in options[i]:
                goal[i] = self._clear_goal(layout, goal[i], cars.rng(i))
            self.obstacles[i] = layout
            cars.place_obstacles(i, layout, self.pillars)

    def _clear_goal(self, layout: tuple[Obstacle, ...], goal: np.ndarray,
                    rng: np.random.Generator) -> np.ndarray:
        """Draw goals until one keeps the clearance from a given layout."""
        for _ in range(MAX_TRIES):
            if clearance(layout, goal) >= self.field.keep_out_m:
                return goal
            goal = self.sample_goal(rng)
        raise RuntimeError(f"no goal in goal_range {self.goal_range_m} keeps "
                           f"{self.field.keep_out_m:.3f} m from the given obstacles in "
                           f"{MAX_TRIES} draws; move them or pass options['goal']")

    def begin(self, cars: Cars, idx: np.ndarray) -> None:
        super().begin(cars, idx)
        self.clearance[idx] = cars.clearances(idx, self.proximity_m)
        self.collision[idx] = False
        self._sectors_of[idx] = -1

    # -- step ----------------------------------------------------------------------------------
    def score(self, cars: Cars, action: np.ndarray) -> Score:
        """Reaching the goal's terms, and the collision and proximity terms from each car's
        clearance (a parked car stands: its clearance stays)."""
        _, success, failure = super().score(cars, action)
        running = np.flatnonzero(~cars.state.parked)
        self.clearance[running] = cars.clearances(running, self.proximity_m)
        self.collision = self.clearance <= 0.0
        inside = (self.proximity_m - self.clearance) / self.proximity_m
        self.terms["collision"] = -self.collision_penalty * self.collision.astype(float)
        self.terms["proximity"] = -self.proximity_penalty * np.clip(inside, 0.0, 1.0)
        return self.reward(), success, failure | self.collision

    def columns(self, cars: Cars) -> dict[str, Any]:
        columns = super().columns(cars)
        readings = cars.state.readings
        stale = np.flatnonzero(readings[SCAN_TIME] != self._sectors_of)
        if len(stale):  # the sectors of the scans taken since they were last made
            self._sectors[stale] = scan_sectors(readings[SCAN][stale],
                                                self.laser_config.range_max, self.scan_sectors)
            self._sectors_of[stale] = readings[SCAN_TIME][stale]
        columns[SCAN_KEY] = self._sectors.T
        return columns

    def info(self, cars: Cars, success: np.ndarray) -> dict[str, np.ndarray]:
        return {**super().info(cars, success), "collision": self.collision.copy(),
                "clearance": self.clearance.copy()}


NavTask.__doc__ = NavTask.__doc__.replace("{observation_table}", card_table(NavTask().compose(
    NAV_OBSERVATION_ORDER, [scan_entry(LaserConfig(), 36)], wheel_joints=CARD_WHEELS)))
