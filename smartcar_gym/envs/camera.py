"""Where a single env's camera looks: the car and its goal (and, for a car with a laser, the
obstacles near the way between them), from the north."""

from __future__ import annotations

import numpy as np

from smartcar_gym.envs.world import World

CAMERA_PITCH_DEG = -60.0
#: a car with a laser is framed from higher up, with the obstacles near its way
LASER_CAMERA_PITCH_DEG = -75.0
CAMERA_MARGIN_M = 0.6  # obstacles this close to the way from the car to the goal are framed


def frame(world: World, goal: np.ndarray) -> tuple[tuple[float, float, float], float, float]:
    """The camera's target, distance (m) and pitch (degrees) for ``world``'s car and ``goal``."""
    pose = world.robot.pose()
    car = np.array([pose.x, pose.y])
    if world.laser is None:
        target = (car + goal) / 2.0
        span = float(np.linalg.norm(goal - car))
        return ((float(target[0]), float(target[1]), 0.0), max(0.9, 1.1 * span + 0.5),
                CAMERA_PITCH_DEG)
    points = [car, goal]
    for obstacle in world.obstacles:
        centre = np.asarray(obstacle.position)
        if _segment_distance(centre, car, goal) - obstacle.radius < CAMERA_MARGIN_M:
            points.append(centre)
    low, high = np.min(points, axis=0), np.max(points, axis=0)
    centre = (low + high) / 2.0
    span = float(np.linalg.norm(high - low))
    return ((float(centre[0]), float(centre[1]), 0.0), max(1.2, 1.1 * span + 0.6),
            LASER_CAMERA_PITCH_DEG)


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from ``point`` to the segment from ``a`` to ``b``."""
    ab = b - a
    length2 = float(ab @ ab)
    s = 0.0 if length2 == 0 else min(1.0, max(0.0, float((point - a) @ ab) / length2))
    return float(np.linalg.norm(point - (a + s * ab)))
