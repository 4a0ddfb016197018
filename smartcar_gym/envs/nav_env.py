"""SmartCarNav-v0: reach a goal among obstacles, seeing them with a simulated 2D laser."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from smartcar_gym import checks
from smartcar_gym.controller.config_yaml import calibrated_config_path
from smartcar_gym.envs.nav_parts import footprint_radius, laser_config, nav_model
from smartcar_gym.envs.observation import Observation, Readings
from smartcar_gym.envs.robots.entries import robot_entries
from smartcar_gym.envs.sensors.laser import (
    ScanMarkers,
    SimulatedLaser,
    mount_from_model,
    mount_from_pose,
)
from smartcar_gym.envs.sensors.scan import SCAN_KEY, LaserConfig, scan_entry
from smartcar_gym.envs.smartcar_env import (
    OBSERVATION_ORDER,
    SmartCarEnv,
    previous_action_entry,
)
from smartcar_gym.envs.tasks.nav import NavigationTask
from smartcar_gym.envs.tasks.obstacles import (
    MAX_TRIES,
    Obstacle,
    ObstacleField,
    clearance,
    read_layout,
)
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.obstacles import add_obstacle, nearest_distance

#: SmartCar-v0's rows, then the scan
NAV_OBSERVATION_ORDER = (*OBSERVATION_ORDER, SCAN_KEY)
OBSTACLE_HEIGHT_M = 0.3  # above the shipped laser's 0.1 m scan plane
CAMERA_PITCH_DEG = -75.0
CAMERA_MARGIN_M = 0.6  # obstacles this close to the way from the car to the goal are framed


class SmartCarNavEnv(SmartCarEnv):
    """## Description

    SmartCar-v0 among obstacles: the same car, controller, actions and goal, plus static boxes
    and cylinders between the start and the goals, and a 2D laser scanner on the car (the
    ``laser`` link that the seed's rviz configuration lists) whose scan the policy sees.
    Touching an obstacle ends the episode. The scanner works like a ``sensor_msgs/LaserScan``
    source: beams from ``angle_min`` to ``angle_max`` every ``angle_increment``, ranges in
    [``range_min``, ``range_max``], ``+inf`` where nothing is within range and ``-inf`` where
    something is closer than ``range_min`` (REP 117), one scan every ``1 / rate_hz`` s of
    simulated time, optional Gaussian range noise. Each scan is one batched ray cast;
    ``env.unwrapped.laser.latest`` is the latest ``LaserScan``.

    ## Action Space

    As SmartCar-v0: ``Box(-1, 1, (2,), float32)``, ``cmd_vel`` linear.x = a[0] * max_linear,
    angular.z = a[1] * max_angular; one step is one controller period (0.1 s).

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
    ``collision`` (bool).

    ## Arguments

    SmartCar-v0's (``controller_mode``, ``render_mode``, ...), with these defaults changed:
    ``controller_config`` is the shipped ``smartcar_arbotix_calibrated.yaml`` (the tutorial's
    YAML with odometry calibrated: ``base_width`` 0.33 m, the car's effective track, for the
    tutorial's 0.26, which overstates every turn by 27 % and puts odometry 0.25-0.5 m off over
    these drives), ``goal_range=(0.5, 2.0)``, ``goal_tolerance=0.2`` (the car's length;
    TurtleBot3 navigation work uses 0.2 m), ``arena_size=6.0``; and:

    | kwarg              | default        | meaning                                             |
    |--------------------|----------------|-----------------------------------------------------|
    | model              | shipped xacro  | robot description; the shipped one is expanded with |
    |                    | with laser     | ``laser:=true`` (adds the ``laser`` link)           |
    | model_args         | None           | xacro arguments for ``model`` (a dict)              |
    | obstacles          | 8              | number of obstacles drawn per episode               |
    | obstacle_size      | (0.15, 0.35)   | min, max box side / cylinder diameter (m)           |
    | obstacle_clearance | 0.2            | free space around the car at the start and the goal |
    | obstacle_layout    | None           | a fixed layout (list or file) instead of drawing    |
    | collision_penalty  | 10.0           | reward lost when touching an obstacle               |
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
    with ``engine="mujoco"`` or ``"planar"``, N cars in one ``SmartCarBatchVectorEnv`` with the
    Nav part (each car's world built at its reset as here, then its physics, laser and
    clearance stepped by the engine's car batch: in C on MuJoCo, against each car's obstacle
    outlines in arrays on planar; bit for bit N of this env, ``randomize`` too: each car
    the robot its episode draws); on pybullet, or with a ``render_mode`` or
    ``controller_mode="sim"``, N single envs stepped in a loop (``SmartCarLoopVectorEnv``);
    both with the smartcar vector conventions (docs/vector.md).

    ## Version History

    * v0 (0.4.0): ``engine="planar"`` and ``planar_params`` (SmartCar-v0's arguments;
      docs/planar.md): the laser and the clearance from the obstacles' exact outlines.
    * v0 (0.3.0): ``engine="mujoco"`` (SmartCar-v0's argument; docs/engines.md).
    * v0 (0.2.0): initial version.
    """

    reset_options = ("goal", "obstacles")
    env_name = "SmartCarNav-v0"
    #: the obstacles' cylinders are pillars (``sim.obstacles.add_obstacle``): not Nav's, whose
    #: tops a car may reach; BARN's
    pillars = False

    def __init__(
        self,
        model: str | os.PathLike | RobotModel | None = None,
        *,
        model_args: Mapping[str, Any] | None = None,
        obstacles: int = 8,
        obstacle_size: tuple[float, float] = (0.15, 0.35),
        obstacle_clearance: float = 0.2,
        obstacle_layout: Sequence[Mapping[str, Any]] | str | os.PathLike | None = None,
        collision_penalty: float = 10.0,
        proximity_penalty: float = 0.0,
        proximity_m: float = 0.3,
        laser: Mapping[str, Any] | LaserConfig | None = None,
        laser_mount: Sequence[float] | None = None,
        scan_sectors: int = 36,
        goal_range: tuple[float, float] = (0.5, 2.0),
        goal_tolerance: float = 0.2,
        arena_size: float = 6.0,
        **kwargs: Any,
    ) -> None:
        self.laser_config = laser_config(laser)
        scan_entry(self.laser_config, scan_sectors)  # checks scan_sectors
        self.scan_sectors = scan_sectors
        self.layout = None if obstacle_layout is None else read_layout(obstacle_layout,
                                                                       "obstacle_layout")
        rewards = {"collision_penalty": collision_penalty,
                   "proximity_penalty": proximity_penalty, "proximity_m": proximity_m}
        for name, value in rewards.items():
            if not (checks.is_real(value) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a number >= 0, got {value!r}")
        model = nav_model(model, model_args, kwargs)
        if kwargs.get("controller_config") is None:
            kwargs["controller_config"] = calibrated_config_path()
        super().__init__(model, goal_range=goal_range, goal_tolerance=goal_tolerance,
                         arena_size=arena_size, **kwargs)
        try:
            self._set_up_obstacles(rewards, laser_mount, obstacles,
                                   obstacle_size, obstacle_clearance)
        except BaseException:
            self.close()  # the world super() opened
            raise
        self.obstacles: tuple[Obstacle, ...] = ()
        self._next_layout: tuple[Obstacle, ...] | None = None
        self._goal_given = False

    def _set_up_obstacles(self, rewards: dict[str, float], laser_mount: Any, obstacles: Any,
                          obstacle_size: Any, obstacle_clearance: Any) -> None:
        """The task with its collision penalty, the laser's mount and the obstacle field."""
        self.task = NavigationTask(
            **{f.name: getattr(self.task, f.name) for f in dataclasses.fields(self.task)},
            **{name: float(value) for name, value in rewards.items()},
        )
        self.mount = (mount_from_pose(laser_mount) if laser_mount is not None
                      else mount_from_model(self.robot_model))
        if self.mount is None:
            raise ValueError(f"{self.robot_model.source} has no 'laser' link: pass "
                             "laser_mount=(x, y, z, yaw), the scan frame in base_link")
        radius = footprint_radius(self.robot_model)
        self.field = ObstacleField(
            count=obstacles,
            size_range_m=checks.number_pair("obstacle_size", obstacle_size),
            clearance_m=obstacle_clearance, half_extent_m=self.task.goal_range_m[1],
            robot_radius_m=radius,
        )
        if self.layout is not None:
            self._check_layout(self.layout, "obstacle_layout")
        else:  # a field that cannot be drawn fails here, not in the middle of training
            for seed in range(3):
                self.field.sample(np.random.default_rng(seed), np.zeros(2),
                                  self.task.sample_goal(np.random.default_rng(seed), np.zeros(2)))

    def _declare_observation(self) -> Observation:
        wheels = [w.joint for w in self.robot_model.left_wheels + self.robot_model.right_wheels]
        return Observation.compose(
            NAV_OBSERVATION_ORDER,
            robot_entries(wheels, 2 * self.task.arena_half_size_m),
            self.task.observation_entries(), [previous_action_entry()],
            [scan_entry(self.laser_config, self.scan_sectors)],
        )

    # -- reset -------------------------------------------------------------------------------
    def _check_options(self, options: Any) -> np.ndarray | None:
        goal = super()._check_options(options)
        layout = self.layout
        if options is not None and "obstacles" in options:
            layout = read_layout(options["obstacles"], "options['obstacles']")
            self._check_layout(layout, "options['obstacles']")
        if goal is not None and layout is not None and clearance(layout, goal) <= 0:
            raise ValueError(f"options['goal'] {goal.tolist()} lies inside an obstacle")
        self._next_layout, self._goal_given = layout, goal is not None
        return goal

    def _check_layout(self, layout: tuple[Obstacle, ...], name: str) -> None:
        """A given layout must leave the car's footprint at the start free."""
        for i, obstacle in enumerate(layout):
            if obstacle.distance(np.zeros(2)) < self.field.robot_radius_m:
                raise ValueError(f"{name}[{i}] {obstacle.to_dict()} overlaps the car at the "
                                 f"start (a {self.field.robot_radius_m:.3f} m circle around "
                                 "the origin)")

    def _build_world(self) -> None:
        start = np.zeros(2)
        if self._next_layout is None:
            layout = self.field.sample(self.np_random, start, self.goal)
        else:
            layout = self._next_layout
            if not self._goal_given:
                self.goal = self._clear_goal(layout)
        self.obstacles = layout
        self._obstacle_bodies = [
            add_obstacle(self.sim, f"obstacle_{i}", o.shape, o.size, o.position, o.yaw,
                         OBSTACLE_HEIGHT_M, pillar=self.pillars) for i, o in enumerate(layout)
        ]
        rng = np.random.default_rng(self.np_random.integers(2**63))  # the laser's noise
        self.laser = SimulatedLaser(self.laser_config, self.mount)
        self.laser.attach(self.robot.body, rng)
        self._scan_markers = (ScanMarkers(self.sim, self.laser_config.beams)
                              if self.render_mode is not None else None)

    def _clear_goal(self, layout: tuple[Obstacle, ...]) -> np.ndarray:
        """Draw goals until one keeps the clearance from a given layout."""
        goal = self.goal
        for _ in range(MAX_TRIES):
            if clearance(layout, goal) >= self.field.keep_out_m:
                return goal
            goal = self.task.sample_goal(self.np_random, np.zeros(2))
        raise RuntimeError(f"no goal in goal_range {self.task.goal_range_m} keeps "
                           f"{self.field.keep_out_m:.3f} m from the given obstacles in "
                           f"{MAX_TRIES} draws; move them or pass options['goal']")

    # -- step, observation, render -------------------------------------------------------------
    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = super().step(action)
        nearest = self._clearance()
        collision = nearest <= 0.0
        info["collision"], info["clearance"] = collision, nearest
        reward = float(reward + self.task.collision_reward(collision)
                       + self.task.proximity_reward(nearest))
        return obs, reward, terminated or collision, truncated, info

    def _clearance(self) -> float:
        """Ground-truth distance (m) between the car and the nearest obstacle, at most
        ``proximity_m``; <= 0 when they touch."""
        return nearest_distance(self.robot.body, self._obstacle_bodies, self.task.proximity_m)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = super().reset(seed=seed, options=options)
        info["collision"], info["clearance"] = False, self._clearance()
        return obs, info

    def readings(self) -> Readings:
        """SmartCar-v0's readings plus the latest scan's ranges (``extra["scan"]``)."""
        readings = super().readings()
        return dataclasses.replace(readings,
                                   extra={**readings.extra, SCAN_KEY: self.laser.latest.ranges})

    def render(self) -> np.ndarray | None:
        """SmartCar-v0's picture (car, goal, odometry trail) with the laser's hit points, from
        a camera that also frames the obstacles near the way to the goal."""
        if self.render_mode is None:
            return super().render()  # warns
        self._check_ready("render")
        self.markers.draw()
        self._scan_markers.draw(self.laser.hit_points, self.laser.origin)
        target, distance = self._camera()
        if self.render_mode == "human":
            self._show(target, distance, CAMERA_PITCH_DEG)
            return None
        return self.sim.render(self.render_width, self.render_height, target, distance,
                               yaw_deg=0.0, pitch_deg=CAMERA_PITCH_DEG)

    def _camera(self) -> tuple[tuple[float, float, float], float]:
        """Camera target and distance framing the car, the goal and the obstacles within
        ``CAMERA_MARGIN_M`` of the straight line between them."""
        pose = self.robot.pose()
        car = np.array([pose.x, pose.y])
        points = [car, self.goal]
        for obstacle in self.obstacles:
            centre = np.asarray(obstacle.position)
            if _segment_distance(centre, car, self.goal) - obstacle.radius < CAMERA_MARGIN_M:
                points.append(centre)
        low, high = np.min(points, axis=0), np.max(points, axis=0)
        centre = (low + high) / 2.0
        span = float(np.linalg.norm(high - low))
        return (float(centre[0]), float(centre[1]), 0.0), max(1.2, 1.1 * span + 0.6)

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        for key in ("laser", "_obstacle_bodies", "_scan_markers"):  # bodies of this world
            state.pop(key, None)
        return state


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from ``point`` to the segment from ``a`` to ``b``."""
    ab = b - a
    length2 = float(ab @ ab)
    s = 0.0 if length2 == 0 else min(1.0, max(0.0, float((point - a) @ ab) / length2))
    return float(np.linalg.norm(point - (a + s * ab)))


def _doc_table() -> str:
    """SmartCarNav-v0's observation table as its docstring shows it (the shipped car)."""
    task = NavigationTask(goal_range_m=(0.5, 2.0), arena_half_size_m=3.0)
    observation = Observation.compose(
        NAV_OBSERVATION_ORDER,
        robot_entries(["lf", "lb", "rf", "rb"], 2 * task.arena_half_size_m),
        task.observation_entries(), [previous_action_entry()], [scan_entry(LaserConfig(), 36)],
    )
    return observation.table().replace("\n", "\n    ")


SmartCarNavEnv.__doc__ = SmartCarNavEnv.__doc__.replace("{observation_table}", _doc_table())
