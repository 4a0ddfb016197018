"""One car in a simulated world of its own: what a single env steps, on any engine.

``World`` holds the engine's simulator, the robot (body and emulated ArbotiX base), the
obstacles a task placed, the laser and the markers drawn for a render, and fills a one-car
``CarState`` from them. The batched envs step their cars otherwise (``envs.vector``), and use a
``World`` only to build an episode's world (``CarBatch.load`` reads ``sim`` and ``robot``).
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.envs.robots.smartcar import SmartCarRobot
from smartcar_gym.envs.sensors.laser import ScanMarkers, SimulatedLaser
from smartcar_gym.envs.sensors.scan import LaserConfig
from smartcar_gym.envs.state import SCAN, SCAN_TIME, CarState
from smartcar_gym.envs.tasks.obstacles import Obstacle
from smartcar_gym.model import RobotModel
from smartcar_gym.model.footprint import footprint_radius
from smartcar_gym.sim.engines import Engine, make_simulator
from smartcar_gym.sim.markers import SceneMarkers
from smartcar_gym.sim.obstacles import add_obstacle, nearest_distance

OBSTACLE_HEIGHT_M = 0.3  # above the shipped laser's 0.1 m scan plane


class World:
    """A simulator of ``engine`` with one robot (see the module). ``open`` makes the
    simulator, ``close`` frees it; ``spawn`` starts an episode's world."""

    def __init__(self, engine: Engine, max_substep_s: float, engine_options: dict[str, Any],
                 robot_model: RobotModel, controller_config: ArbotixConfig,
                 controller_mode: str, wheel_contact: str, render_mode: str | None,
                 goal_tolerance_m: float) -> None:
        self.engine, self.max_substep_s = engine, max_substep_s
        self.engine_options = engine_options
        self.robot_model, self.controller_config = robot_model, controller_config
        self.controller_mode, self.wheel_contact = controller_mode, wheel_contact
        self.render_mode = render_mode
        self.goal_tolerance_m = goal_tolerance_m
        #: the circle about base_link that holds the car (m): obstacles beyond it plus a
        #: distance are further than that distance
        self.footprint_radius_m = footprint_radius(robot_model)
        self.sim: Any = None
        self.robot: SmartCarRobot | None = None
        self.markers: SceneMarkers | None = None
        #: the laser of this episode (None: the task's cars carry none)
        self.laser: SimulatedLaser | None = None
        self.scan_markers: ScanMarkers | None = None
        #: the obstacles placed this episode, their bodies, centres and enclosing radii
        self.obstacles: tuple[Obstacle, ...] = ()
        self.bodies: list[Any] = []
        self._centres = np.zeros((0, 2))
        self._radii = np.zeros(0)
        self._lock = threading.Lock()

    def _robot(self, sim: Any) -> SmartCarRobot:
        return SmartCarRobot(sim, self.robot_model, self.controller_config,
                             mode=self.controller_mode, wheel_contact=self.wheel_contact)

    def open(self) -> None:
        """A fresh simulator (its own world) with the robot and the markers."""
        self.sim = make_simulator(self.engine, max_substep_s=self.max_substep_s,
                                  gui=self.render_mode == "human",
                                  draws=self.render_mode is not None, **self.engine_options)
        self.robot = self._robot(self.sim)
        self.markers = (SceneMarkers(self.sim, self.goal_tolerance_m)
                        if self.render_mode is not None else None)

    def check(self) -> None:
        """Spawn the robot once in a scratch world and step it once, so that a car the engine
        cannot run (planar: it would tip over) is refused in one line (ModelError) when the
        env is made, not at its first reset."""
        sim = make_simulator(self.engine, max_substep_s=self.max_substep_s,
                             **self.engine_options)
        try:
            self._robot(sim).spawn(settle_s=0.0)
            sim.run_until(sim.now_ns + sim.max_substep_ns)
        finally:
            sim.close()

    def close(self) -> None:
        """Free the simulator (``open`` makes a new one)."""
        if self.sim is not None:
            self.sim.close()
        self._forget()

    def _forget(self) -> None:
        self.__dict__.update(_no_world())

    def exclusive(self, call: str) -> _Held:
        """One thread at a time in the env's ``call`` (``with world.exclusive("step"):``): a
        second one gets a clear error, not a corrupted world."""
        if not self._lock.acquire(blocking=False):
            raise RuntimeError(
                f"SmartCarEnv.{call}() called while another thread is inside this env: an env "
                "is one simulated world and is not thread-safe; give each thread its own env "
                "(gym.make_vec with vectorization_mode='async' runs envs in parallel)")
        return _Held(self._lock)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.pop("_lock", None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def detached(self) -> World:
        """A copy with the settings and none of the world (an env's copy opens its own)."""
        copy = World.__new__(World)
        copy.__setstate__({**self.__getstate__(), **_no_world()})
        return copy

    # -- an episode ----------------------------------------------------------------------------
    def spawn(self, randomization: Any, rng: np.random.Generator) -> Any:
        """A fresh world with the robot spawned and settled (with ``randomization``: the robot,
        ground and start pose drawn from ``rng``); the draw (None without)."""
        self.sim.reset()
        self.obstacles, self.bodies, self.laser = (), [], None
        self._centres, self._radii = np.zeros((0, 2)), np.zeros(0)
        start, draw = (0.0, 0.0, 0.0), None
        if randomization is not None:
            draw = randomization.apply(rng, self.sim, self.robot)
            start = draw.start_pose
        self.robot.spawn(*start)
        return draw

    def place(self, obstacles: tuple[Obstacle, ...], pillars: bool) -> None:
        """Static bodies for ``obstacles``, 0.3 m tall (``pillars``: cylinders whose tops
        nothing reaches, which an engine may round)."""
        self.obstacles = tuple(obstacles)
        self.bodies = [add_obstacle(self.sim, f"obstacle_{i}", o.shape, o.size, o.position,
                                    o.yaw, OBSTACLE_HEIGHT_M, pillar=pillars)
                       for i, o in enumerate(self.obstacles)]
        self._centres = np.array([o.position for o in self.obstacles], dtype=float)
        self._centres = self._centres.reshape(-1, 2)
        self._radii = np.array([o.radius for o in self.obstacles], dtype=float)

    def attach_laser(self, config: LaserConfig, mount: np.ndarray,
                     rng: np.random.Generator, scan: bool = True) -> None:
        """The laser on the robot, scanning now (unless ``scan`` is False: a batch's builder,
        whose batch scans its cars) and every period (``rng``: its noise's)."""
        self.laser = SimulatedLaser(config, mount)
        self.laser.attach(self.robot.body, rng, scan)
        self.scan_markers = (ScanMarkers(self.sim, config.beams)
                             if self.render_mode is not None else None)

    def clearance(self, max_distance_m: float) -> float:
        """The car's distance (m) to its nearest obstacle, at most ``max_distance_m``: against
        the obstacles whose enclosing circles come within the car's footprint circle plus
        ``max_distance_m`` of base_link (the others are further than ``max_distance_m``)."""
        if not self.bodies:
            return max_distance_m
        pose = self.robot.pose()
        reach = self.footprint_radius_m + max_distance_m
        near = np.hypot(self._centres[:, 0] - pose.x, self._centres[:, 1] - pose.y) - self._radii
        bodies = [self.bodies[i] for i in np.flatnonzero(near < reach)]
        return nearest_distance(self.robot.body, bodies, max_distance_m)

    # -- the state -----------------------------------------------------------------------------
    def read(self, state: CarState, needs_speed: bool) -> None:
        """Row 0 of ``state`` from the robot now: pose, odometry, wheels, clock, scan."""
        robot, sim = self.robot, self.sim
        pose = robot.pose()
        state.pose[0] = (pose.x, pose.y, pose.yaw)
        state.up_z[0] = pose.up_z
        if needs_speed:
            (vx, vy, _), _ = robot.body.velocity()
            state.speed[0] = math.hypot(vx, vy)
        odom = robot.odometry
        state.odometry[0] = (odom.x, odom.y, odom.theta, odom.v, odom.omega)
        position, velocity = robot.body.joint_lists(robot.wheel_joint_indices)
        state.wheel_position[0] = position
        state.wheel_velocity[0] = velocity
        state.now_ns[0] = sim.now_ns
        if self.laser is not None and self.laser.latest is not None:
            state.readings[SCAN][0] = self.laser.latest.ranges
            state.readings[SCAN_TIME][0] = self.laser.stamp_ns

    def mark_odometry(self) -> None:
        """The odometry's pose on the render's trail."""
        odom = self.robot.odometry
        self.markers.add_pose(odom.x, odom.y, odom.theta)


def _no_world() -> dict[str, Any]:
    """A world's fields when it holds none: no simulator, robot, markers, laser or obstacle
    bodies."""
    return {"sim": None, "robot": None, "markers": None, "laser": None, "scan_markers": None,
            "bodies": []}


class _Held:
    """A lock ``World.exclusive`` has taken, released when its ``with`` block ends (a plain
    context manager: a generator's costs a microsecond a step)."""

    __slots__ = ("lock",)

    def __init__(self, lock: threading.Lock) -> None:
        self.lock = lock

    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        self.lock.release()
