"""SmartCarNav-v0 on MuJoCo for N cars: physics, laser and clearance in C per car's world."""

from __future__ import annotations

from typing import Any

import numpy as np

from smartcar_gym.envs.nav_env import SmartCarNavEnv
from smartcar_gym.envs.sensors.laser import SimulatedLaser
from smartcar_gym.envs.sensors.scan import SCAN_KEY, scan_sectors
from smartcar_gym.envs.tasks.obstacles import Obstacle, read_layout
from smartcar_gym.envs.vector.common import nav_limits
from smartcar_gym.envs.vector.mujoco import SmartCarMujocoVectorEnv
from smartcar_gym.model.kinematics import quaternion_matrix

#: measured with 4.0.0 (64 cars, 8 obstacles): about 0.8 MiB per car, as SmartCar-v0's
BYTES_PER_CAR = 1024 * 1024


def supports(kwargs: dict[str, Any]) -> str | None:
    """Why ``SmartCarNavMujocoVectorEnv`` cannot run these SmartCarNav-v0 kwargs (None: it
    can)."""
    if kwargs.get("engine") != "mujoco":
        return "only engine='mujoco' is batched in C"
    return nav_limits(kwargs)


class SmartCarNavMujocoVectorEnv(SmartCarMujocoVectorEnv):
    """## Description

    ``SmartCarNav-v0`` with ``engine="mujoco"`` for ``num_envs`` cars at once. Per car it is
    ``gym.make("SmartCarNav-v0", engine="mujoco")`` bit for bit (tested): observations (with
    the scan sectors), rewards (with the collision and proximity terms), terminations,
    truncations and ``info`` (SmartCar-v0's keys, ``collision``, ``clearance``).

    Each episode's obstacles differ, so a car's reset builds its world as its single env does:
    one ``SmartCarNavEnv`` (the builder) is reset with the car's own generator (goal,
    obstacles, the laser's noise seed, the first scan at t = 0) and the car's slot of
    ``sim.mujoco.batch.CarBatch`` becomes a copy of that world (``CarBatch.load``; about 7 ms a
    reset). From there on nothing goes through a single env: every car's physics is
    ``mj_step`` in its own world, its laser one ``mj_multiRay`` per scan (``CarBatch.scan``)
    at the laser's rate on the car's own clock, its clearance ``mj_geomDistance`` between the
    car's and the obstacles' geoms (``CarBatch.distances``), all in C, the cars split between
    ``num_threads`` worker threads; the beams' geometry, ranges (REP 117, noise from each
    car's generator), scan sectors, controller, reward and resets are numpy over cars
    (``SimulatedLaser.beams``/``ranges``, ``scan_sectors``, ``NavigationTask``'s terms: the
    single env's arithmetic on arrays).

    Made by ``gym.make_vec("SmartCarNav-v0", num_envs=N, vectorization_mode=
    "vector_entry_point", engine="mujoco", **kwargs)`` with SmartCarNavEnv's kwargs, plus
    ``autoreset_mode`` and ``num_threads``. What SmartCar-v0's MuJoCo batch cannot run
    (``randomize``, ``controller_mode="sim"``, ``stop_speed``, differential-drive models) and
    any ``render_mode`` (the batch's top-down tiles would leave out the obstacles) fall back
    to ``SmartCarLoopVectorEnv``.

    ## Conventions

    As ``SmartCarSimVectorEnv`` (autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
    ``s + i``, ``info`` per car with ``_key`` masks, ``(N, 2)`` actions), plus
    ``reset(options={"obstacles": layout})``: every car gets that layout for this episode (as
    each single env given the same options). ``latest_ranges`` holds every car's latest scan
    (``(N, beams)`` float32) and ``obstacles`` each car's layout.
    """

    single_env = SmartCarNavEnv
    env_id = "SmartCarNav-v0"
    bytes_per_car = BYTES_PER_CAR
    why_not = staticmethod(supports)

    def _keep(self, template: SmartCarNavEnv) -> None:
        """The single env stays: it builds every car's world at the car's resets."""
        self.builder = template

    def _init_from(self, s: SmartCarNavEnv, num_threads: int) -> None:
        super()._init_from(s, num_threads)
        n = self.num_envs
        self.laser = SimulatedLaser(s.laser_config, s.mount)  # its arithmetic, unattached
        self.scan_sectors = s.scan_sectors
        self.latest_ranges = np.zeros((n, s.laser_config.beams), dtype=np.float32)
        self._laser_rngs: list[np.random.Generator | None] = [None] * n
        self._next_scan = np.zeros(n, dtype=np.int64)
        self._init_contacts(s)
        self.clearance = np.zeros(n)
        self.collision = np.zeros(n, dtype=bool)
        self.obstacles: list[tuple[Obstacle, ...]] = [()] * n
        self._layout: Any = None

    def _init_contacts(self, s: SmartCarNavEnv) -> None:
        """What the clearance needs: the car's collision geoms, each car's geom pairs."""
        self._car_geoms = list(s.robot.body._ids.collision_geoms)
        self._pairs = [np.zeros((0, 2), dtype=np.int64)] * self.num_envs

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the worker threads, free the cars' worlds and the builder's."""
        super().close_extras(**kwargs)
        if getattr(self, "builder", None) is not None:
            self.builder.close()

    # -- resets --------------------------------------------------------------------------------
    def _check_options(self, options: Any) -> np.ndarray | None:
        layout = None
        if isinstance(options, dict) and "obstacles" in options:
            options = dict(options)
            layout = options.pop("obstacles")
            self.builder._check_layout(read_layout(layout, "options['obstacles']"),
                                       "options['obstacles']")
        goals = super()._check_options(options)
        self._layout = layout
        return goals

    def _new_worlds(self, idx: np.ndarray, goals: np.ndarray | None) -> None:
        """Each listed car's episode as its single env starts it (goal, obstacles, first
        scan), built by the builder with the car's generator and copied into its slot."""
        b = self.builder
        layout, self._layout = self._layout, None
        for i in idx.tolist():
            options: dict[str, Any] = {}
            if goals is not None:
                options["goal"] = goals[i]
            if layout is not None:
                options["obstacles"] = layout
            b.np_random = self._rng(i)
            _, info = b.reset(options=options or None)
            self.goal[i] = b.goal
            self.latest_ranges[i] = b.laser.latest.ranges
            self._laser_rngs[i] = b.laser.rng
            self._next_scan[i] = self.laser.period_ns
            self.clearance[i], self.collision[i] = info["clearance"], False
            self.obstacles[i] = b.obstacles
            self._load_world(i, b)

    def _load_world(self, i: int, b: SmartCarNavEnv) -> None:
        """Car ``i``'s slot becomes a copy of the builder's world (``CarBatch.load``), and its
        geom pairs the clearance measures."""
        self.cars.load(i, b.sim)
        # nearest_distance's order: per obstacle, per car geom, per obstacle geom
        self._pairs[i] = np.array(
            [(g1, g2) for body in b._obstacle_bodies for g1 in self._car_geoms
             for g2 in body._ids.collision_geoms], dtype=np.int64).reshape(-1, 2)

    # -- the laser -----------------------------------------------------------------------------
    def _next_due(self) -> np.ndarray:
        return np.minimum(self._robot_due(), self._next_scan)

    def _fire_sensors(self, mask: np.ndarray) -> None:
        """The masked cars' scans due at their clocks (the laser's ``on_event``)."""
        due = mask & (self._next_scan <= self._now)
        if due.any():
            self._scan(np.flatnonzero(due))
            self._next_scan[due] += self.laser.period_ns

    def _scan(self, idx: np.ndarray) -> None:
        """``SimulatedLaser.scan`` for the listed cars: one ``mj_multiRay`` per car."""
        laser, range_max = self.laser, self.laser.config.range_max
        q = self.cars.qpos[idx, self._free_q:self._free_q + 7]
        origin, directions = laser.beams(q[:, :3], quaternion_matrix(q[:, [4, 5, 6, 3]]))
        starts = np.broadcast_to(origin[:, None, :], directions.shape)
        hit, fraction = self.cars.scan(idx, starts, origin[:, None, :] + directions * range_max)
        if laser.config.noise_std_m > 0:
            for k, i in enumerate(idx.tolist()):
                self.latest_ranges[i] = laser.ranges(fraction[k], hit[k], self._laser_rngs[i])
        else:
            self.latest_ranges[idx] = laser.ranges(fraction, hit, None)

    # -- step, observation, info ---------------------------------------------------------------
    def _advance(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """SmartCar-v0's step for every car, then ``SmartCarNavEnv.step``'s collision and
        proximity terms from each car's clearance."""
        reward, success, failure = super()._advance(a)
        task = self.task
        self.clearance = self._clearances(task.proximity_m)
        self.collision = self.clearance <= 0.0
        reward = (reward + task.collision_reward(self.collision)
                  + task.proximity_reward(self.clearance))
        return reward, success, failure | self.collision

    def _clearances(self, max_distance_m: float) -> np.ndarray:
        """Every car's ``nearest_distance`` to its obstacles (``mj_geomDistance``)."""
        return self.cars.distances(np.arange(self.num_envs), self._pairs, max_distance_m)

    def _columns(self) -> dict[str, Any]:
        columns = super()._columns()
        sectors = scan_sectors(self.latest_ranges, self.laser.config.range_max,
                               self.scan_sectors)
        columns[SCAN_KEY] = tuple(sectors.T)
        return columns

    def _info_values(self, success: np.ndarray) -> dict[str, np.ndarray]:
        return {**super()._info_values(success), "collision": self.collision.copy(),
                "clearance": self.clearance.copy()}
