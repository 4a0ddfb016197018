"""A top-down picture of many cars at once, drawn in numpy (no engine, no GUI)."""

from __future__ import annotations

import math

import numpy as np

CAR_LENGTH_M, CAR_WIDTH_M = 0.25, 0.16  # the tutorial's base_link box
BACKGROUND = np.array([235, 235, 235], dtype=np.uint8)
OUTSIDE = np.array([150, 150, 150], dtype=np.uint8)
GOAL = np.array([40, 170, 60], dtype=np.uint8)
CAR = np.array([40, 80, 200], dtype=np.uint8)
NOSE = np.array([220, 60, 40], dtype=np.uint8)


def top_down_tiles(positions: np.ndarray, yaws: np.ndarray, goals: np.ndarray,
                   goal_radius_m: float, arena_half_m: float, width: int,
                   height: int) -> np.ndarray:
    """An ``(height, width, 3)`` uint8 image: one tile per car, its goal and the arena's edge.

    Each tile is centred between its car and goal and spans them with a margin, as
    SmartCar-v0's camera frames them; cars are boxes with their front half marked.
    """
    n = len(positions)
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    image = np.empty((height, width, 3), dtype=np.uint8)
    image[:] = OUTSIDE
    tw, th = width // cols, height // rows
    for k in range(n):
        r, c = divmod(k, cols)
        tile = image[r * th:(r + 1) * th, c * tw:(c + 1) * tw]
        _draw_tile(tile, positions[k], yaws[k], goals[k], goal_radius_m, arena_half_m)
    return image


def _draw_tile(tile: np.ndarray, position: np.ndarray, yaw: float, goal: np.ndarray,
               goal_radius_m: float, arena_half_m: float) -> None:
    h, w = tile.shape[:2]
    if h < 2 or w < 2:
        return
    centre = (np.asarray(position) + np.asarray(goal)) / 2.0
    span = max(1.0, 1.2 * float(np.linalg.norm(np.asarray(goal) - position)) + 0.6)
    scale = span / min(h, w)  # metres per pixel
    px = centre[0] + (np.arange(w) - w / 2.0 + 0.5) * scale
    py = centre[1] - (np.arange(h) - h / 2.0 + 0.5) * scale  # image rows go down, y goes up
    x, y = np.meshgrid(px, py)
    inside = (np.abs(x) <= arena_half_m) & (np.abs(y) <= arena_half_m)
    tile[:] = OUTSIDE
    tile[inside] = BACKGROUND
    tile[(x - goal[0]) ** 2 + (y - goal[1]) ** 2 <= goal_radius_m**2] = GOAL
    c, s = math.cos(yaw), math.sin(yaw)
    ahead = c * (x - position[0]) + s * (y - position[1])
    left = -s * (x - position[0]) + c * (y - position[1])
    body = (np.abs(ahead) <= CAR_LENGTH_M / 2) & (np.abs(left) <= CAR_WIDTH_M / 2)
    tile[body] = CAR
    tile[body & (ahead > CAR_LENGTH_M / 4)] = NOSE
