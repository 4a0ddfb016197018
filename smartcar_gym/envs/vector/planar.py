"""SmartCar-v0, SmartCarGoal-v0 and SmartCarNav-v0 on the planar engine for N cars, in arrays.

The MuJoCo batches' clocks, events, controller and task arithmetic (``vector/mujoco.py``) with
the planar engine's cars (``sim.planar.batch.PlanarBatch``) in place of MuJoCo's worlds: the
per-car events, the integer ArbotiX boards (``BatchedArbotix``), observations and rewards are
those classes' own code; only where the physics is read and written differs. The Goal and Nav
batches put their MuJoCo class first (``SmartCarGoalPlanarVectorEnv(SmartCarGoalMujocoVectorEnv,
SmartCarPlanarVectorEnv)``), so that their task code runs on the planar cars.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smartcar_gym.controller.batched import cars_index
from smartcar_gym.envs.nav_env import OBSTACLE_HEIGHT_M, SmartCarNavEnv
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.vector.common import batch_limits, nav_limits
from smartcar_gym.envs.vector.goal_mujoco import SmartCarGoalMujocoVectorEnv
from smartcar_gym.envs.vector.mujoco import SmartCarMujocoVectorEnv
from smartcar_gym.envs.vector.nav_mujoco import SmartCarNavMujocoVectorEnv

#: measured (4096 cars, SmartCar-v0): about 6 KiB of arrays per car; the margin covers the
#: per-car generators
BYTES_PER_CAR = 16 * 1024


def supports(kwargs: dict[str, Any]) -> str | None:
    """Why the planar batch cannot run these SmartCar-v0 kwargs (None: it can)."""
    if kwargs.get("engine") != "planar":
        return "only engine='planar' is batched in arrays here"
    return batch_limits(kwargs)


def nav_supports(kwargs: dict[str, Any]) -> str | None:
    """Why the planar Nav batch cannot run these SmartCarNav-v0 kwargs (None: it can)."""
    if kwargs.get("engine") != "planar":
        return "only engine='planar' is batched in arrays here"
    return nav_limits(kwargs)


class SmartCarPlanarVectorEnv(SmartCarMujocoVectorEnv):
    """## Description

    ``SmartCar-v0`` with ``engine="planar"`` for ``num_envs`` cars at once, in arrays. Per car
    it is ``gym.make("SmartCar-v0", engine="planar")`` bit for bit (tested): the single env's
    planar car is copied into every column of ``sim.planar.batch.PlanarBatch``; each car keeps
    its own clock and steps each interval between its own events (board PID frames, controller
    updates) in the fewest equal substeps no longer than ``max_substep_s``, through the same
    substep function as the single env (numba's loop when the ``fast`` extra is installed,
    numpy arrays otherwise: the same numbers). The ArbotiX boards and ``diff_controller`` s
    are ``controller.batched.BatchedArbotix``; observation, reward and resets are numpy over
    cars.

    Made by ``gym.make_vec("SmartCar-v0", num_envs=N, vectorization_mode="vector_entry_point",
    engine="planar", **kwargs)`` with SmartCarEnv's kwargs (``planar_params`` included), plus
    ``autoreset_mode``. ``randomize``, ``render_mode="human"``, ``stop_speed`` and
    ``controller_mode="sim"`` fall back to ``SmartCarLoopVectorEnv``.

    ## Conventions

    As ``SmartCarSimVectorEnv`` (autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
    ``s + i``, ``info`` per car with ``_key`` masks, ``(N, 2)`` actions, ``render()`` tiles the
    first 16 cars top-down).
    """

    env_id = "SmartCar-v0"

    bytes_per_car = BYTES_PER_CAR
    why_not = staticmethod(supports)
    engine = "planar"
    differential = True  # BatchedArbotix starts the encoders mid-tick, as the single env

    def _keep(self, template: SmartCarEnv) -> None:
        template.close()

    def _init_from(self, s: SmartCarEnv, num_threads: int | None) -> None:
        from smartcar_gym.sim.planar.batch import PlanarBatch

        self._take_settings(s)
        n, robot, sim = self.num_envs, s.robot, s.sim
        body = robot.body
        self.cars = PlanarBatch(body, n)
        of = body.groups.of
        self._wheel_joints = [of[j] for j in robot.wheel_joint_indices]
        self._encoder_joints = [of[j] for j in robot._encoder_idx]
        self._encoder_sign = np.array(robot._encoder_signs, dtype=np.float64)
        self._side = [0 if left else 1 for left in robot._left]
        self._share = list(robot._share)
        self._sign = list(robot._signs)
        # the order PlanarBody sums joint torques and damping into its groups
        self._held_joints = [(of[j], k) for k, j in enumerate(robot.wheel_joint_indices)
                             if j in of]
        self._damped_joints = [(of[j], robot.wheel_joint_indices.index(j))
                               for j in body._damping if j in of]
        self.max_substep_ns = sim.max_substep_ns
        wheels = len(robot.wheel_joint_indices)
        self._wheel_group = np.arange(wheels)
        self.period_ns = robot.update_period_ns
        self._allocate(s, wheels)

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release: arrays only (``reset`` starts every car afresh)."""
        self._needs_reset = True

    def _reopen(self) -> None:
        """Nothing to rebuild: the cars are arrays, and ``reset`` respawns them all."""

    def _angles(self) -> np.ndarray:
        """The encoder wheels' forward-positive angles (N, 2), as ``encoder_angles``."""
        return self.cars.joint_angles(self._encoder_joints) * self._encoder_sign

    def _read_pose(self) -> None:
        px, py, yaw = self.cars.pose()
        self._pose[:, 0], self._pose[:, 1], self._pose[:, 2] = px, py, yaw

    def _new_worlds(self, idx: np.ndarray, goals: np.ndarray | None) -> None:
        origin = np.zeros(2)
        for i in idx:
            self.goal[i] = (goals[i] if goals is not None
                            else self.task.sample_goal(self._rng(i), origin))
        self.cars.reset(idx)

    def _motors_to_wheels(self, mask: np.ndarray) -> None:
        """Each side's motor output into its wheel groups, with ``set_motor_output``'s and
        ``PlanarBody._drive``'s arithmetic in their order."""
        cars, ng = self.cars, self.cars.ng
        mask = cars_index(mask)
        drive, damping = self.base.drive_torque[mask], self.base.damping[mask]
        tau = [np.zeros(len(drive)) for _ in range(ng)]
        for (g, sign), k in self._held_joints:
            tau[g] = tau[g] + sign * (drive[:, self._side[k]] * self._share[k] * self._sign[k])
        damp = [np.zeros(len(drive)) for _ in range(ng)]
        for (g, sign), k in self._damped_joints:
            damp[g] = damp[g] + sign * sign * (damping[:, self._side[k]] * self._share[k])
        for g in range(ng):
            cars.drive[g, mask] = tau[g]
            cars.drive[ng + g, mask] = damp[g]

    def _read_wheels(self) -> None:
        self._wheels = self.cars.joint_angles(self._wheel_joints)
        self._wheel_speed = self.cars.joint_speeds(self._wheel_joints)


class SmartCarGoalPlanarVectorEnv(SmartCarGoalMujocoVectorEnv, SmartCarPlanarVectorEnv):
    """``SmartCarGoal-v0`` with ``engine="planar"`` for ``num_envs`` cars (dict observations,
    ``final_obs`` per car), per car bit for bit ``gym.make("SmartCarGoal-v0",
    engine="planar")``; otherwise as ``SmartCarPlanarVectorEnv``."""

    env_id = "SmartCarGoal-v0"


class SmartCarNavPlanarVectorEnv(SmartCarNavMujocoVectorEnv, SmartCarPlanarVectorEnv):
    """## Description

    ``SmartCarNav-v0`` with ``engine="planar"`` for ``num_envs`` cars at once, per car bit for
    bit ``gym.make("SmartCarNav-v0", engine="planar")`` (tested): observations (with the scan
    sectors), rewards (with the collision and proximity terms), ends and ``info``.

    A car's reset builds its episode as its single env does (the builder, a kept
    ``SmartCarNavEnv``, reset with the car's generator: goal, obstacles, the laser's noise seed,
    the first scan at t = 0); from there on the physics is ``PlanarBatch``, the laser one
    ``geometry.cast`` of every scanning car's beams against its own obstacles' outlines (the
    single env's ``geometry.ray_hits``, vectorised over cars), the clearance one
    ``geometry.clearance`` of every car's footprint against its obstacles. What the planar
    batch of SmartCar-v0 cannot run, and any ``render_mode``, falls back to
    ``SmartCarLoopVectorEnv``.
    """

    env_id = "SmartCarNav-v0"
    why_not = staticmethod(nav_supports)
    bytes_per_car = 64 * 1024  # its obstacles and latest scan besides SmartCar-v0's arrays

    def _init_contacts(self, s: SmartCarNavEnv) -> None:
        from smartcar_gym.sim.planar.world import footprint_of

        self._footprint = footprint_of(s.robot.body)
        self._height = OBSTACLE_HEIGHT_M
        self._shapes: list[Any] = [None] * self.num_envs

    def _new_worlds(self, idx: np.ndarray, goals: np.ndarray | None) -> None:
        super()._new_worlds(idx, goals)
        self.cars.reset(idx)

    def _load_world(self, i: int, b: SmartCarNavEnv) -> None:
        """Car ``i``'s obstacles (its car is the template's at its spawn: ``cars.reset``)."""
        from smartcar_gym.sim.planar.world import obstacle_shapes

        self._shapes[i] = obstacle_shapes(b.sim.statics())

    def _world_shapes(self, idx: np.ndarray) -> Any:
        """The listed cars' obstacles as one ``Shapes2D`` (padded to the most obstacles)."""
        from smartcar_gym.sim.planar.geometry import Shapes2D

        parts = [self._shapes[i] for i in idx.tolist()]
        m = max(p.num_shapes for p in parts)
        k = len(parts)
        kind = np.zeros((k, m), dtype=np.int8)
        centre, rotation = np.zeros((k, m, 2)), np.tile([1.0, 0.0], (k, m, 1))
        half, valid = np.ones((k, m, 2)), np.zeros((k, m), dtype=bool)
        for row, p in enumerate(parts):
            j = p.num_shapes
            kind[row, :j], centre[row, :j] = p.kind[0], p.centre[0]
            rotation[row, :j], half[row, :j], valid[row, :j] = p.rotation[0], p.half[0], True
        return Shapes2D(kind, centre, rotation, half, valid)

    def _scan(self, idx: np.ndarray) -> None:
        """``SimulatedLaser.scan`` for the listed cars: ``geometry.ray_hits``' arithmetic over
        cars, every car against its own obstacles."""
        from smartcar_gym.model.kinematics import quaternion_matrix
        from smartcar_gym.sim.planar.batch import yaw_quaternion_arrays
        from smartcar_gym.sim.planar.geometry import cast

        laser, range_max = self.laser, self.laser.config.range_max
        cars = self.cars
        px, py, _ = cars.pose()
        qz, qw = yaw_quaternion_arrays(cars.state[2][idx], cars.state[3][idx])
        position = np.stack([px[idx], py[idx], np.full(len(idx), cars.height)], axis=1)
        zero = np.zeros(len(idx))
        rotation = quaternion_matrix(np.stack([zero, zero, qz, qw], axis=1))
        origin, directions = laser.beams(position, rotation)
        starts = np.broadcast_to(origin[:, None, :], directions.shape)
        ends = origin[:, None, :] + directions * range_max
        vec = ends - starts
        length = np.hypot(vec[..., 0], vec[..., 1])
        moving = length > 0
        units = np.where(moving[..., None],
                         vec[..., :2] / np.where(moving, length, 1.0)[..., None], [1.0, 0.0])
        found = cast(origin[:, :2], units, length, self._world_shapes(idx))
        within = moving & (starts[..., 2] >= 0.0) & (starts[..., 2] <= self._height)
        hit = within & (found.shape >= 0)
        fraction = np.where(hit, found.distance / np.where(moving, length, 1.0), 1.0)
        if laser.config.noise_std_m > 0:
            for k, i in enumerate(idx.tolist()):
                self.latest_ranges[i] = laser.ranges(fraction[k], hit[k], self._laser_rngs[i])
        else:
            self.latest_ranges[idx] = laser.ranges(fraction, hit, None)

    def _clearances(self, max_distance_m: float) -> np.ndarray:
        """Every car's ``nearest_distance`` to its obstacles: ``geometry.clearance``."""
        from smartcar_gym.sim.planar.geometry import clearance

        everyone = np.arange(self.num_envs)
        return clearance(self._footprint, self._pose, self._world_shapes(everyone),
                         max_distance_m, height=self._height)
