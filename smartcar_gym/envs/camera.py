"""Where a single env's camera looks: the car and its goal (and, for a car with a laser, the
obstacles near the way between them), from the north."""

from __future__ import annotations

import numpy as np

from smartcar_gym.envs.world import World
from smartcar_gym.sim.contracts import window_of

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


def draw(world: World, goal: np.ndarray, mode: str, width: int, height: int
         ) -> np.ndarray | None:
    """The markers and scan drawn, then ``world``'s picture (``mode`` "rgb_array": an image)
    or its window pointed at the car and ``goal`` ("human": None)."""
    world.markers.draw()
    if world.scan_markers is not None:
        world.scan_markers.draw(world.laser.hit_points, world.laser.origin)
    target, distance, pitch = frame(world, goal)
    if mode == "human":
        window = window_of(world.sim)
        if window is not None:
            window.point_gui_camera(target, distance, yaw_deg=0.0, pitch_deg=pitch)
        return None
    return world.sim.render(width, height, target, distance, yaw_deg=0.0, pitch_deg=pitch)


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from ``point`` to the segment from ``a`` to ``b``."""
    ab = b - a
    length2 = float(ab @ ab)
    s = 0.0 if length2 == 0 else min(1.0, max(0.0, float((point - a) @ ab) / length2))
    return float(np.linalg.norm(point - (a + s * ab)))
