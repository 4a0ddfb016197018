"""A stand-in for the env a task runs in (``envs.tasks.base.Cars``), for tests of a task alone."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from smartcar_gym.envs.state import CarState, car_values


class StubCars:
    """``num`` cars at rest at the origin with ``wheels`` wheel joints each: their state, a
    generator each (car i seeded ``seed + i``), and each car ``clearance`` m from its nearest
    obstacle (None: no obstacles, every car as far as asked)."""

    threads = 1

    def __init__(self, num: int, wheels: int = 4, seed: int = 0,
                 clearance: Sequence[float] | None = None) -> None:
        self.state = CarState.zeros(num, wheels)
        self.rngs = [np.random.default_rng(seed + i) for i in range(num)]
        self.clearance = None if clearance is None else np.asarray(clearance, dtype=float)

    @staticmethod
    def values(array: np.ndarray) -> np.ndarray:
        return array

    def rng(self, car: int) -> np.random.Generator:
        return self.rngs[car]

    def clearances(self, cars: np.ndarray, max_distance_m: float) -> np.ndarray:
        if self.clearance is None:
            return np.full(len(cars), max_distance_m)
        return np.minimum(self.clearance[cars], max_distance_m)

    def place_obstacles(self, car: int, obstacles: object, pillars: bool) -> None:
        raise AssertionError("the stub cars take no obstacles")


class OneCar(StubCars):
    """One car whose step hooks get its values as a single env hands them (``car_values``:
    Python numbers and rows), not one-row arrays."""

    def __init__(self, wheels: int = 4, seed: int = 0) -> None:
        super().__init__(1, wheels, seed)

    @staticmethod
    def values(array: np.ndarray):
        return car_values(array)
