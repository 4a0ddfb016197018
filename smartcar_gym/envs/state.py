"""The public state of the cars: what a task may read and write, one row a car.

A single env holds one row, a batched env N. The env fills the rows from its engine and
controller after every reset and step (``pose`` to ``readings``); a task reads them, writes
``goal`` when an episode starts, and keeps its own per-car numbers beside them
(``envs.tasks.base.Task``). Nothing a task needs is elsewhere.

- ``pose`` (N, 3) float64: ground truth, base_link's x, y (m) and yaw (rad, in [-pi, pi]) in
  the world;
- ``up_z`` (N,) float64: ground truth, the z component of base_link's z axis (1 upright,
  < 0.5 flipped over);
- ``speed`` (N,) float64: ground truth, base_link's planar speed (m/s), read where the task
  asks for it (``Task.needs_speed``), else 0;
- ``odometry`` (N, 5) float64: the controller's ``odom``: x, y (m), theta (rad, never wrapped,
  as upstream), v (m/s), omega (rad/s);
- ``wheel_position``, ``wheel_velocity`` (N, W) float64: each wheel joint's angle (rad, not
  wrapped) and speed (rad/s), left then right, front then back;
- ``goal`` (N, 2) float64: the episode's goal in the ``odom`` frame (m);
- ``previous_action`` (N, 2) float32: the last action as the agent sent it, clipped (zeros
  after a reset);
- ``now_ns`` (N,) int64: each car's clock, ns of simulated time since its reset;
- ``steps`` (N,) int64: steps since the car's reset;
- ``parked`` (N,) bool: cars not simulated until a reset names them (``park``);
- ``readings``: each sensor's latest reading by name: the laser's ``scan`` (N, beams) float32
  ranges (REP 117) and ``scan_time_ns`` (N,) int64, when on the car's clock it was taken.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

#: the laser's reading: its latest ranges, and when it was taken (ns on the car's clock)
SCAN = "scan"
SCAN_TIME = "scan_time_ns"


@dataclass(eq=False)
class CarState:
    """N cars' state, one row a car (the module's table says what each field holds)."""

    pose: np.ndarray
    up_z: np.ndarray
    speed: np.ndarray
    odometry: np.ndarray
    wheel_position: np.ndarray
    wheel_velocity: np.ndarray
    goal: np.ndarray
    previous_action: np.ndarray
    now_ns: np.ndarray
    steps: np.ndarray
    parked: np.ndarray
    readings: dict[str, np.ndarray]

    @classmethod
    def zeros(cls, num: int, wheels: int,
              sensors: Mapping[str, tuple[tuple[int, ...], Any]] | None = None) -> CarState:
        """``num`` cars at rest at the origin, upright, with ``wheels`` wheel joints each;
        ``sensors``: each reading's shape per car and dtype (``{"scan": ((360,), float32)}``)."""
        readings = {name: np.zeros((num, *shape), dtype=dtype)
                    for name, (shape, dtype) in (sensors or {}).items()}
        return cls(
            pose=np.zeros((num, 3)), up_z=np.ones(num), speed=np.zeros(num),
            odometry=np.zeros((num, 5)), wheel_position=np.zeros((num, wheels)),
            wheel_velocity=np.zeros((num, wheels)), goal=np.zeros((num, 2)),
            previous_action=np.zeros((num, 2), dtype=np.float32),
            now_ns=np.zeros(num, dtype=np.int64), steps=np.zeros(num, dtype=np.int64),
            parked=np.zeros(num, dtype=bool), readings=readings,
        )

    @property
    def num(self) -> int:
        """How many cars (rows)."""
        return len(self.pose)

    def take(self, car: int, other: CarState, row: int = 0) -> None:
        """Car ``car``'s row becomes ``other``'s row ``row`` (every field, every reading)."""
        for f in fields(self):
            if f.name == "readings":
                for name, value in self.readings.items():
                    value[car] = other.readings[name][row]
            else:
                getattr(self, f.name)[car] = getattr(other, f.name)[row]

    def rows(self, cars: np.ndarray | list[int]) -> CarState:
        """A new state of the listed cars' rows (copies), in their order."""
        idx = np.asarray(cars, dtype=np.int64)
        values = {f.name: getattr(self, f.name)[idx] for f in fields(self)
                  if f.name != "readings"}
        return CarState(**values, readings={k: v[idx] for k, v in self.readings.items()})

    @classmethod
    def stack(cls, states: list[CarState]) -> CarState:
        """One state of every row of ``states``, in order (a row of single envs as one)."""
        values = {f.name: np.concatenate([getattr(s, f.name) for s in states])
                  for f in fields(cls) if f.name != "readings"}
        names = states[0].readings if states else {}
        return cls(**values, readings={k: np.concatenate([s.readings[k] for s in states])
                                       for k in names})


def car_values(array: np.ndarray) -> Any:
    """Car 0's value of a per-car array, as a single env hands it to ``one_or_many`` hooks: a
    Python number of an (N,) array, a numpy row of an (N, k) one."""
    return array.item(0) if array.ndim == 1 else array[0]


def split(value: Any) -> Any:
    """The k columns of a per-car (N, k) field as ``Cars.values`` gives it: k (N,) arrays, or
    one car's k numbers (Python floats) from its row."""
    return value.tolist() if value.ndim == 1 else value.T


def copied(value: Any) -> Any:
    """A hook's value to hand out (``info``): an array's copy; one car's number as it is."""
    return value.copy() if isinstance(value, np.ndarray) else value
