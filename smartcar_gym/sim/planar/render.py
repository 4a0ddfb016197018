"""The planar engine's ``rgb_array`` picture: the world seen from straight above, in numpy.

The picture covers the ground an orbit camera at ``distance`` with field of view ``fov_deg``
would see around ``target`` (the envs' framing), north up: a grid every 0.5 m, the obstacles
(boxes and cylinders), each robot's collision shapes projected onto the ground (its base link
darker, the front half of the base marked), and the visual markers (the goal, the odometry
arrows, the laser's hit points), each a filled rectangle or disc.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

import numpy as np

from smartcar_gym.model.kinematics import quaternion_matrix
from smartcar_gym.sim.planar.projection import outline, placed_shapes
from smartcar_gym.sim.planar.shapes import CIRCLE

if TYPE_CHECKING:
    from smartcar_gym.sim.planar.body import PlanarBody
    from smartcar_gym.sim.planar.simulator import PlanarSimulator

GROUND = np.array([238, 238, 238], dtype=np.uint8)
GRID = np.array([205, 214, 228], dtype=np.uint8)
OBSTACLE = np.array([140, 140, 153], dtype=np.uint8)
BASE_COLOUR = np.array([40, 80, 200], dtype=np.uint8)
PART = np.array([30, 30, 30], dtype=np.uint8)
NOSE = np.array([220, 60, 40], dtype=np.uint8)
GRID_M = 0.5

# a primitive: ("rect", cx, cy, yaw, hx, hy) or ("disc", cx, cy, r)
Shape = tuple


def _colour(rgba: Sequence[float]) -> np.ndarray:
    return np.clip(np.round(np.asarray(rgba[:3], dtype=float) * 255), 0, 255).astype(np.uint8)


def robot_shapes(body: PlanarBody) -> Iterator[tuple[Shape, np.ndarray]]:
    """Every collision shape of a robot but its meshes, projected onto the ground at its pose
    (``projection.outline``, as its footprint), with a colour: the base link's in blue, the
    front half of its boxes marked, the others dark."""
    (x, y, _), q = body.link_pose()
    yaw = 2.0 * math.atan2(q[2], q[3])
    c, s = math.cos(yaw), math.sin(yaw)
    tables = body.tables
    for shape in placed_shapes(tables.robot, tables.frames):
        if shape.geometry.type == "mesh":  # a picture reads no mesh files
            continue
        kind, (cx, cy), turn, (hx, hy), _, _ = outline(shape)
        base = shape.link == tables.robot.base_link
        colour = BASE_COLOUR if base else PART
        wx, wy = x + c * cx - s * cy, y + s * cx + c * cy
        if kind == CIRCLE:
            yield ("disc", wx, wy, hx), colour
            continue
        turn += yaw
        yield ("rect", wx, wy, turn, hx, hy), colour
        if base and shape.geometry.type == "box":
            half = hx / 2.0
            yield (("rect", wx + math.cos(turn) * half, wy + math.sin(turn) * half, turn, half,
                    hy), NOSE)


def marker_shapes(marker) -> Iterator[tuple[Shape, np.ndarray]]:
    """A visual marker's shapes (``PlanarStatic`` of kind sphere, cylinder, box or parts)."""
    (x, y, _), q = marker.link_pose()
    if marker.kind in ("sphere", "cylinder"):
        yield ("disc", x, y, marker.size[0]), _colour(marker.rgba)
    elif marker.kind == "box":
        yaw = 2.0 * math.atan2(q[2], q[3])
        yield ("rect", x, y, yaw, marker.size[0], marker.size[1]), _colour(marker.rgba)
    elif marker.kind == "parts":
        rotation = quaternion_matrix(q)
        yaw = math.atan2(rotation[1, 0], rotation[0, 0])
        for part in marker.parts:
            px, py, _ = rotation @ np.asarray(part.position, float)
            part_yaw = yaw + 2.0 * math.atan2(part.orientation[2], part.orientation[3])
            yield (("rect", x + px, y + py, part_yaw, part.half_extents[0],
                    part.half_extents[1]), _colour(part.rgba))


def top_down(sim: PlanarSimulator, width: int, height: int, target: Sequence[float],
             distance: float, fov_deg: float = 50.0) -> np.ndarray:
    """An ``(height, width, 3)`` uint8 picture of ``sim``'s world from above."""
    span = 2.0 * distance * math.tan(math.radians(fov_deg) / 2.0)  # metres across the height
    scale = span / height
    px = target[0] + (np.arange(width) - width / 2.0 + 0.5) * scale
    py = target[1] - (np.arange(height) - height / 2.0 + 0.5) * scale
    gx, gy = np.meshgrid(px, py)
    image = np.empty((height, width, 3), dtype=np.uint8)
    image[:] = GROUND
    line = max(scale, 0.004)
    on_grid = ((np.abs(gx - np.round(gx / GRID_M) * GRID_M) < line / 2)
               | (np.abs(gy - np.round(gy / GRID_M) * GRID_M) < line / 2))
    image[on_grid] = GRID
    shapes: list[tuple[Shape, np.ndarray]] = []
    for obstacle in sim.statics():
        (x, y, _), _ = obstacle.link_pose()
        if obstacle.kind == "box":
            shapes.append((("rect", x, y, obstacle.yaw, obstacle.size[0], obstacle.size[1]),
                           OBSTACLE))
        else:
            shapes.append((("disc", x, y, obstacle.size[0]), OBSTACLE))
    markers = sim.markers()
    shapes += [item for m in markers if m.kind in ("sphere", "cylinder")
               for item in marker_shapes(m)]
    for robot in sim._robots:
        shapes += list(robot_shapes(robot))
    shapes += [item for m in markers if m.kind not in ("sphere", "cylinder")
               for item in marker_shapes(m)]
    for shape, colour in shapes:
        _fill(image, gx, gy, shape, colour, scale)
    return image


def _fill(image: np.ndarray, gx: np.ndarray, gy: np.ndarray, shape: Shape,
          colour: np.ndarray, scale: float) -> None:
    """Paint one primitive (at least one pixel wide, so that thin arrows stay visible), over
    the pixels of its bounding box only."""
    if shape[0] == "disc":
        _, cx, cy, r = shape
        reach = r = max(r, scale / 2)
    else:
        _, cx, cy, yaw, hx, hy = shape
        hx, hy = max(hx, scale / 2), max(hy, scale / 2)
        reach = math.hypot(hx, hy)
    x0, y0 = gx[0, 0], gy[0, 0]
    c0 = max(0, int((cx - reach - x0) / scale) - 1)
    c1 = min(gx.shape[1], int((cx + reach - x0) / scale) + 2)
    r0 = max(0, int((y0 - (cy + reach)) / scale) - 1)
    r1 = min(gx.shape[0], int((y0 - (cy - reach)) / scale) + 2)
    if c0 >= c1 or r0 >= r1:
        return
    x, y = gx[r0:r1, c0:c1], gy[r0:r1, c0:c1]
    if shape[0] == "disc":
        inside = (x - cx) ** 2 + (y - cy) ** 2 <= r * r
    else:
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = x - cx, y - cy
        inside = (np.abs(c * dx + s * dy) <= hx) & (np.abs(-s * dx + c * dy) <= hy)
    image[r0:r1, c0:c1][inside] = colour
