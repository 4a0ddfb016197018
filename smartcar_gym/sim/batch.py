"""The car-batch contract: what the batched vector env needs from N cars of one engine.

An engine that can step many cars at once describes it in its ``Engine`` (``sim.engines``):
``car_batch`` makes a ``CarBatch`` from a settled single env (its robot and its world, just
reset), and ``batches_differential`` says whether it runs differential-drive models. The
batched env (``envs.vector.batched.SmartCarBatchVectorEnv``) holds everything else: the
clocks, the events, the batched ArbotiX boards, the tasks' arithmetic, autoreset and ``park``.
It reads and writes the physics only through the methods below, each over arrays of cars.

Each car of the batch is the single env's car, bit for bit: the same numbers from the same
inputs, whatever the other cars do. Arrays are over all N cars in car order unless a method
takes a list of cars (``idx``, an int array).

``LazyCarBatch`` is the ``car_batch`` of the built-in engines: it names the class and imports
it when a batch is first made (listing the engines imports no physics library), and says how
much memory a car takes, for the env's check of ``num_envs`` before it makes the cars.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    import numpy as np


@runtime_checkable
class CarBatch(Protocol):
    """N copies of one settled car of one engine, stepped in arrays (``car_batch``'s result).

    Made by ``car_batch(env, num_cars, threads)`` from ``env``, a single smartcar env of the
    engine just reset (spawned and settled): every car starts as its world is then.
    ``threads`` is how many worker threads may step the cars (an engine may ignore it).
    A batch can be copied (``copy.deepcopy``, pickle); a copy may leave out what ``close``
    frees, and the env calls ``reopen`` on it before its first reset.

    An engine may also offer ``run_period(base, now, next_update, end, pending, period_ns,
    max_substep_ns) -> bool``: every pending car's events (``base``'s boards) and physics
    until ``end`` in a loop of its own, the same sequence per car as the env's event loop
    (``envs.vector.events.Clocks``), returning False where it cannot (the env then runs
    them). The planar engine's does (``sim.planar.period``).
    """

    def reset(self, idx: np.ndarray) -> None:
        """The listed cars back to the settled world they were made from, their motors off."""

    def encoder_angles(self) -> np.ndarray:
        """(N, 2): the encoder wheels' forward-positive angles (rad), left then right, as the
        single robot's ``encoder_angles``."""

    def read_pose(self, pose: np.ndarray) -> np.ndarray:
        """Every car's ground-truth x, y (m) and yaw (rad) written into ``pose`` ((N, 3)), as
        the single env's ``pose_from`` computes them; returns the z component of each car's up
        axis ((N,); 1 upright, below ``FLIP_UP_Z`` flipped)."""

    def read_wheels(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, W) each: every wheel joint's angle (rad) and speed (rad/s), in the order of the
        robot's ``wheel_joint_indices`` (the observation's)."""

    def set_drive(self, mask: np.ndarray, torque: np.ndarray, damping: np.ndarray) -> None:
        """For the masked cars ((N,) bool): each side's motor torque and back-EMF damping
        (``torque``, ``damping``: (N, 2), left then right, the boards' ``drive_torque`` and
        ``damping``) shared by that side's wheels as the single robot's ``set_motor_output``
        does; held until set again."""

    def step(self, idx: np.ndarray, nstep: np.ndarray, timestep: np.ndarray) -> None:
        """Car ``idx[k]``: ``nstep[k]`` substeps of ``timestep[k]`` s each, its drive held."""

    def take_unstable(self) -> Sequence[Warning]:
        """The instabilities the engine met in ``step`` since the last call (and taken from
        it), one warning each, its category the engine's and its message naming the car and
        its state; empty for an engine that has none. The env issues them."""

    def close(self) -> None:
        """Free what the cars hold beyond arrays (worlds, threads); ``reopen`` restores it."""

    def reopen(self) -> None:
        """After ``close`` (or in a copy): every car a copy of the settled world again."""

    # -- SmartCarNav-v0: a world per episode, the laser and the clearance -------------------
    def load(self, car: int, env: Any) -> None:
        """Car ``car`` becomes the world ``env`` (a single env of the engine, just reset for
        this car's episode) has built: its obstacles (``env.sim``, ``env.obstacle_bodies``),
        the car at its spawn (``env.robot``)."""

    def cast(self, idx: np.ndarray, laser: Any) -> tuple[np.ndarray, np.ndarray]:
        """The listed cars' laser beams (``laser``: a ``SimulatedLaser``, its ``beams`` and
        ``config.range_max``) cast against each car's own world, as the single env's scan
        casts them: which beams hit ((K, B) bool) and how far along (fraction, 1 where
        none)."""

    def clearances(self, pose: np.ndarray, max_distance_m: float, idx: np.ndarray
                   ) -> np.ndarray:
        """(K,): the listed cars' ``nearest_distance`` to their obstacles (<= 0: touching), at
        most ``max_distance_m``; ``pose`` is what ``read_pose`` last wrote (every car's). A
        car's value does not depend on which others are listed."""


class CarBatchFactory(Protocol):
    """An engine's ``car_batch``: makes the batch; ``bytes_per_car`` (optional) is about how
    much memory one car holds, which the env checks ``num_envs`` against first."""

    def __call__(self, env: Any, num_cars: int, threads: int) -> CarBatch: ...


@dataclass(frozen=True)
class LazyCarBatch:
    """A ``car_batch`` that imports its class (``"package.module:Class"``) when first called,
    with the memory one car holds (bytes, measured)."""

    path: str
    bytes_per_car: int

    def __call__(self, env: Any, num_cars: int, threads: int) -> CarBatch:
        module, name = self.path.split(":")
        return getattr(importlib.import_module(module), name)(env, num_cars, threads)
