"""The planar engine's ``CarBatch`` (``sim.batch``): N planar cars in arrays, read and written
as the single ``PlanarBody`` reads and writes its car.

``PlanarCars`` wraps ``batch.PlanarBatch`` (every car a column, stepped by numba's loop or
numpy) with what the single ``SmartCarRobot`` knows of its ``PlanarBody``: which wheel group
each joint turns with (and its sign), and the order the body sums joint torques and damping
into its groups. For SmartCarNav-v0 it keeps each car's obstacle outlines and casts the laser
and measures the clearance against them with ``geometry``'s exact 2D functions (the single
env's ``ray_hits`` and ``clearance``, over cars). Every car is its single env bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smartcar_gym.controller.diff_controller import HARDWARE
from smartcar_gym.model.kinematics import quaternion_matrix
from smartcar_gym.sim.planar import dynamics, period
from smartcar_gym.sim.planar.batch import PlanarBatch, yaw_quaternion_arrays
from smartcar_gym.sim.planar.drive import drive_cars, drive_tables
from smartcar_gym.sim.planar.geometry import OBSTACLE_HEIGHT_M, Shapes2D, cast, clearance
from smartcar_gym.sim.planar.projection import Footprint
from smartcar_gym.sim.planar.world import footprint_of, outlines


class PlanarCars:
    """``num_cars`` copies of ``env``'s planar car at its spawn (a ``PlanarBatch``).

    ``batch`` is the ``PlanarBatch`` itself (the fit's replays give its cars other
    parameters and start states). The planar engine's implicit step is stable at any length:
    it meets no instabilities, and its cars hold nothing to close.
    """

    def __init__(self, env: Any, num_cars: int, threads: int) -> None:
        robot = env.robot
        body = robot.body
        #: the cars' columns
        self.batch = PlanarBatch(body, num_cars, threads)
        of = body.groups.of
        self._wheel_joints = [of[j] for j in robot.wheel_joint_indices]
        self._encoder_joints = [of[j] for j in robot.encoder_joint_indices]
        self._encoder_sign = tuple(float(x) for x in robot.encoder_signs)
        self._side = [0 if left else 1 for left in robot.wheel_left]
        self._share = list(robot.wheel_shares)
        self._sign = list(robot.wheel_signs)
        # the order PlanarBody sums joint torques and damping into its groups
        self._held_joints = [(of[j], k) for k, j in enumerate(robot.wheel_joint_indices)
                             if j in of]
        self._damped_joints = [(of[j], robot.wheel_joint_indices.index(j))
                               for j in body.damped_joints if j in of]
        self._drive_tables = drive_tables(self._held_joints, self._damped_joints, self._side,
                                          self._share, self._sign)
        self._upright = np.ones(self.batch.n)  # a planar car never tips over
        self._body = body
        #: threads the dynamics' and the laser's compiled loops split the cars over
        self.threads = threads
        #: per car, its obstacles' outlines (SmartCarNav-v0; ``load``)
        self._shapes: list[Any] = [None] * self.batch.n
        #: every car's, stacked (``_world_shapes``): its arrays, then their read-only view
        self._rows: tuple[np.ndarray, ...] | None = None
        self._stacked: Shapes2D | None = None
        # a car a ``load`` gave a varied robot (``randomize``) has its own model and
        # footprint, the others the template's
        self._template = (body.compiled(), body.height, footprint_of(body))
        self._varied: set[int] = set()
        self._footprints: list[Footprint] = [self._template[2]] * self.batch.n
        self._footprint: Footprint | None = self._template[2]  # every car's (or a stack)

    def reset(self, idx: np.ndarray) -> None:
        self.batch.reset(idx)

    def encoder_angles(self) -> np.ndarray:
        return self.batch.joint_angles(self._encoder_joints, self._encoder_sign)

    def read_pose(self, pose: np.ndarray) -> np.ndarray:
        pose[:, 0], pose[:, 1], pose[:, 2] = self.batch.pose()
        return self._upright

    def read_wheels(self) -> tuple[np.ndarray, np.ndarray]:
        return (self.batch.joint_angles(self._wheel_joints),
                self.batch.joint_speeds(self._wheel_joints))

    def set_drive(self, mask: np.ndarray, torque: np.ndarray, damping: np.ndarray) -> None:
        """Each side's motor output into its wheel groups, with ``set_motor_output``'s and
        ``PlanarBody._drive``'s arithmetic in their order (numba's loop over the cars where
        installed: the same operations on each car's numbers)."""
        cars, ng = self.batch, self.batch.ng
        if dynamics.COMPILED:  # read at each call: a test switches it off
            drive_cars(mask, 0, cars.n, torque, damping, *self._drive_tables, cars.torque,
                       cars.damping)
            return
        mask = slice(None) if mask.all() else mask  # every car: views, not copies
        drive, damp_side = torque[mask], damping[mask]
        tau = [np.zeros(len(drive)) for _ in range(ng)]
        for (g, sign), k in self._held_joints:
            tau[g] = tau[g] + sign * (drive[:, self._side[k]] * self._share[k] * self._sign[k])
        damp = [np.zeros(len(drive)) for _ in range(ng)]
        for (g, sign), k in self._damped_joints:
            damp[g] = damp[g] + sign * sign * (damp_side[:, self._side[k]] * self._share[k])
        for g in range(ng):
            cars.torque[g, mask] = tau[g]
            cars.damping[g, mask] = damp[g]

    def step(self, idx: np.ndarray, nstep: np.ndarray, timestep: np.ndarray) -> None:
        self.batch.step(idx, nstep, timestep)

    def run_period(self, base: Any, now: np.ndarray, next_update: np.ndarray,
                   end: np.ndarray, pending: np.ndarray, period_ns: int,
                   max_substep_ns: int) -> bool:
        """Every pending car's events and physics until ``end`` in one compiled loop
        (``period.run_period``), for ``period.MIN_CARS`` cars or more where numba runs both
        the physics and ``base``'s boards in hardware mode; False where it does not (the
        caller runs the events)."""
        if self.batch.n < period.MIN_CARS or not (
                period.available() and base.compiled and base.mode == HARDWARE):
            return False
        encoders = self.batch.joint_table(self._encoder_joints, scale=self._encoder_sign)
        period.run_period(self.batch, base, encoders, self._drive_tables, now, next_update,
                          end, pending, period_ns, max_substep_ns)
        return True

    def take_unstable(self) -> tuple[Warning, ...]:
        """None: the implicit step is stable at any length."""
        return ()

    def close(self) -> None:
        """Nothing to release: arrays only."""

    def reopen(self) -> None:
        """Nothing to rebuild: the env's ``reset`` respawns every car."""

    # -- SmartCarNav-v0 ------------------------------------------------------------------------
    def load(self, car: int, env: Any) -> None:
        """Car ``car``'s obstacles (``env``'s statics) and its car: ``env``'s robot as it
        stands where it varies (``randomize``: its parameters, centre of mass, height,
        footprint and spawned state), else the template's at the spawn."""
        self._shapes[car] = outlines(env.sim, tuple(env.sim.statics()))
        self._restack(car)
        idx = np.array([car])
        if env.robot.variation is None:
            if car in self._varied:
                self._varied.discard(car)
                self._set_car(car, *self._template)
            self.batch.reset(idx)
            return
        body = env.robot.body
        self._varied.add(car)
        self._set_car(car, body.compiled(), body.height, footprint_of(body))
        self.batch.reset(idx, np.array(body.state, dtype=np.float64))

    def _set_car(self, car: int, model: Any, height: float, footprint: Footprint) -> None:
        """Car ``car``'s parameters, height and footprint."""
        self.batch.set_model(np.array([car]), model, height)
        self._footprints[car] = footprint
        self._footprint = None if self._varied else self._template[2]

    def _restack(self, car: int) -> None:
        """Car ``car``'s row of the stacked arrays written again after its ``load``, in place
        while the padding stays as wide (the most obstacles of any car), else stacked afresh
        at the next use; a new view of them either way (``distance`` keeps what it derives
        from a ``Shapes2D`` on it)."""
        self._stacked = None
        if self._rows is None:
            return
        if max(p.num_shapes for p in self._shapes) != self._rows[0].shape[1]:
            self._rows = None
            return
        _write_row(self._rows, car, self._shapes[car])

    def _world_shapes(self, idx: np.ndarray) -> Shapes2D:
        """The listed cars' obstacles as one ``Shapes2D`` (padded to the most obstacles): rows
        of every car's, stacked once and each row written again at its car's ``load``."""
        if self._rows is None:
            self._rows = _stack([self._shapes[i] for i in range(self.batch.n)])
        if self._stacked is None:
            # each car's shapes were checked when made: the stack needs no second check
            self._stacked = Shapes2D.derived(*self._rows)
        all_ = self._stacked
        if len(idx) == self.batch.n and (idx == np.arange(self.batch.n)).all():
            return all_
        m = max(self._shapes[i].num_shapes for i in idx.tolist())
        return all_.take(idx, m)

    def cast(self, idx: np.ndarray, laser: Any) -> tuple[np.ndarray, np.ndarray]:
        """``geometry.ray_hits``' arithmetic over cars, every car against its own obstacles."""
        cars = self.batch
        px, py, _ = cars.pose()
        cos_yaw, sin_yaw = cars.heading()
        qz, qw = yaw_quaternion_arrays(cos_yaw[idx], sin_yaw[idx])
        position = np.stack([px[idx], py[idx], cars.height[idx]], axis=1)
        zero = np.zeros(len(idx))
        rotation = quaternion_matrix(np.stack([zero, zero, qz, qw], axis=1))
        origin, directions = laser.beams(position, rotation)
        starts = np.broadcast_to(origin[:, None, :], directions.shape)
        ends = origin[:, None, :] + directions * laser.config.range_max
        vec = ends - starts
        length = np.hypot(vec[..., 0], vec[..., 1])
        moving = length > 0
        units = np.where(moving[..., None],
                         vec[..., :2] / np.where(moving, length, 1.0)[..., None], [1.0, 0.0])
        found = cast(origin[:, :2], units, length, self._world_shapes(idx),
                     threads=self.threads)
        within = moving & (starts[..., 2] >= 0.0) & (starts[..., 2] <= OBSTACLE_HEIGHT_M)
        hit = within & (found.shape >= 0)
        fraction = np.where(hit, found.distance / np.where(moving, length, 1.0), 1.0)
        return hit, fraction

    def clearances(self, pose: np.ndarray, max_distance_m: float, idx: np.ndarray
                   ) -> np.ndarray:
        """The listed cars' footprints against their obstacles: ``geometry.clearance``, on
        every car's stacked shapes (kept between steps) with the others left out."""
        if self._footprint is None:
            self._footprint = Footprint.stack(self._footprints)
        idx = np.asarray(idx, dtype=np.int64)
        listed = np.zeros(self.batch.n, dtype=bool)
        listed[idx] = True
        return clearance(self._footprint, pose, self._world_shapes(np.arange(self.batch.n)),
                         max_distance_m, height=OBSTACLE_HEIGHT_M, cars=listed)[idx]


def _stack(parts: list[Shapes2D]) -> tuple[np.ndarray, ...]:
    """One car's ``Shapes2D`` each as the rows of ``Shapes2D``'s five arrays (kind, centre,
    rotation, half, valid), padded to the most obstacles."""
    m = max(p.num_shapes for p in parts)
    k = len(parts)
    rows = (np.zeros((k, m), dtype=np.int8), np.zeros((k, m, 2)), np.zeros((k, m, 2)),
            np.zeros((k, m, 2)), np.zeros((k, m), dtype=bool))
    for row, p in enumerate(parts):
        _write_row(rows, row, p)
    return rows


def _write_row(rows: tuple[np.ndarray, ...], row: int, shapes: Shapes2D) -> None:
    """``shapes`` (one world's) into row ``row`` of the stacked arrays ``rows``, padded with
    invalid unit boxes at the origin."""
    kind, centre, rotation, half, valid = rows
    j = shapes.num_shapes
    kind[row, :j], centre[row, :j] = shapes.kind[0], shapes.centre[0]
    rotation[row, :j], half[row, :j], valid[row, :j] = shapes.rotation[0], shapes.half[0], True
    kind[row, j:], centre[row, j:], rotation[row, j:] = 0, 0.0, (1.0, 0.0)
    half[row, j:], valid[row, j:] = 1.0, False
