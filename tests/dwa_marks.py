"""What a DWA driver's obstacle layer holds, for the tests of its footprint clearing."""

from __future__ import annotations

import numpy as np

from smartcar_gym.bench.dwa import DWADriver
from smartcar_gym.navigation.obstacles import to_base


def marks_inside_footprint(driver: DWADriver, pose: np.ndarray, car: int = 0) -> int:
    """How many of car ``car``'s marked points lie inside the driver's padded footprint at
    ``pose`` (x, y, theta, odom frame)."""
    half_x, half_y = driver.planner.config.padded
    points = to_base(driver.layers.points_of(car), np.asarray(pose, dtype=float))
    return int(((np.abs(points[:, 0]) < half_x) & (np.abs(points[:, 1]) < half_y)).sum())
