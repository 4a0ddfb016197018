"""MuJoCo's ``CarBatch`` (``sim.batch``): N copies of the single env's world, read and written
at the single robot's addresses.

``MujocoCars`` wraps ``batch.CarBatch`` (the worlds, stepped in C by worker threads) with what
the single ``SmartCarRobot`` knows of its ``MujocoBody``: the qpos/qvel addresses of its wheel,
encoder and free joints, and how each side's motor output is shared by its wheels. Its
arithmetic is the single env's (``pose_from``'s yaw by ``math.atan2``, ``set_motor_output``'s
products in their order), so every car is its single env bit for bit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from smartcar_gym.model.kinematics import quaternion_matrix
from smartcar_gym.sim.mujoco.batch import CarBatch
from smartcar_gym.sim.mujoco.mjlog import MujocoWarning, describe

_NO_WARNINGS: tuple[Warning, ...] = ()


class MujocoCars:
    """``num_cars`` copies of ``env``'s settled MuJoCo world (a ``sim.batch.CarBatch``)."""

    def __init__(self, env: Any, num_cars: int, threads: int) -> None:
        robot, sim = env.robot, env.sim
        ids = robot.body._ids
        qadr, dadr = ids.addresses(robot.wheel_joint_indices)
        self._wheel_q = np.asarray(qadr)
        self._wheel_v = np.asarray(dadr)
        self._encoder_q = np.asarray(ids.addresses(robot.encoder_joint_indices)[0])
        self._encoder_sign = np.array(robot.encoder_signs, dtype=np.float64)
        self._free_q, self._free_v = ids.free_q, ids.free_v
        self._side = np.array([0 if left else 1 for left in robot.wheel_left])
        self._share = np.array(robot.wheel_shares)
        self._sign = np.array(robot.wheel_signs)
        #: the worlds, stepped in C
        self.batch = CarBatch(sim, num_cars, list(dadr), threads)
        self._car_geoms = list(ids.collision_geoms)
        #: per car, the (car geom, obstacle geom) pairs its clearance measures
        self._pairs = [np.zeros((0, 2), dtype=np.int64)] * int(num_cars)

    def reset(self, idx: np.ndarray) -> None:
        self.batch.reset(idx)

    def encoder_angles(self) -> np.ndarray:
        return self.batch.qpos[:, self._encoder_q] * self._encoder_sign

    def read_pose(self, pose: np.ndarray) -> np.ndarray:
        """The free joint's x, y and yaw (``pose_from``'s arithmetic) into ``pose``; up_z."""
        q = self.batch.qpos[:, self._free_q:self._free_q + 7]
        qw, qx, qy, qz = q[:, 3], q[:, 4], q[:, 5], q[:, 6]
        pose[:, 0], pose[:, 1] = q[:, 0], q[:, 1]
        # math.atan2 (libm), as the single env: numpy's arctan2 differs in the last bit
        pose[:, 2] = list(map(math.atan2, (2.0 * (qw * qz + qx * qy)).tolist(),
                              (1.0 - 2.0 * (qy * qy + qz * qz)).tolist()))
        return 1.0 - 2.0 * (qx * qx + qy * qy)

    def read_wheels(self) -> tuple[np.ndarray, np.ndarray]:
        return self.batch.qpos[:, self._wheel_q], self.batch.qvel[:, self._wheel_v]

    def set_drive(self, mask: np.ndarray, torque: np.ndarray, damping: np.ndarray) -> None:
        """Each side's motor output shared by its wheels (``set_motor_output``)."""
        side = self._side
        self.batch.torque[mask] = torque[mask][:, side] * self._share * self._sign
        self.batch.damping[mask] = damping[mask][:, side] * self._share

    def step(self, idx: np.ndarray, nstep: np.ndarray, timestep: np.ndarray) -> None:
        self.batch.step(idx, nstep, timestep)

    def take_unstable(self) -> tuple[Warning, ...]:
        """A ``MujocoWarning`` per car whose world MuJoCo found unstable (and reset), with
        its state then, in car order."""
        if not self.batch.unstable:
            return _NO_WARNINGS
        events, self.batch.unstable = self.batch.unstable, []
        return tuple(MujocoWarning(describe(event, [(f"car {car}", self._free_q, self._free_v)]))
                     for car, event in sorted(events, key=lambda e: e[0]))

    def close(self) -> None:
        self.batch.close()

    def reopen(self) -> None:
        self.batch.reopen()

    # -- SmartCarNav-v0 ------------------------------------------------------------------------
    def load(self, car: int, env: Any) -> None:
        """Car ``car``'s slot becomes a copy of ``env``'s world (``CarBatch.load``), and its
        geom pairs the clearance measures."""
        self.batch.load(car, env.sim)
        # nearest_distance's order: per obstacle, per car geom, per obstacle geom
        self._pairs[car] = np.array(
            [(g1, g2) for body in env.obstacle_bodies for g1 in self._car_geoms
             for g2 in body._ids.collision_geoms], dtype=np.int64).reshape(-1, 2)

    def cast(self, idx: np.ndarray, laser: Any) -> tuple[np.ndarray, np.ndarray]:
        """One ``mj_multiRay`` per listed car (``CarBatch.scan``)."""
        q = self.batch.qpos[idx, self._free_q:self._free_q + 7]
        origin, directions = laser.beams(q[:, :3], quaternion_matrix(q[:, [4, 5, 6, 3]]))
        starts = np.broadcast_to(origin[:, None, :], directions.shape)
        return self.batch.scan(idx, starts,
                               origin[:, None, :] + directions * laser.config.range_max)

    def clearances(self, pose: np.ndarray, max_distance_m: float, idx: np.ndarray
                   ) -> np.ndarray:
        """``mj_geomDistance`` over each listed car's pairs (``CarBatch.distances``)."""
        return self.batch.distances(np.asarray(idx, dtype=np.int64), self._pairs,
                                    max_distance_m)
