"""Visual-only markers: the goal and the odometry trail (as the seed's rviz config shows it).

rviz's Odometry display keeps the last 100 ``/odom`` poses as arrows; we keep a pool of 100 thin
arrow bodies and move them, which the headless TinyRenderer draws like any other body (debug
lines are GUI-only). Nothing here exists unless the env renders.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable

import numpy as np

from smartcar_gym._bullet import pybullet
from smartcar_gym.sim.simulator import Simulator

TRAIL_COLOR = (221 / 255, 200 / 255, 14 / 255, 1.0)  # the seed's rviz Odometry colour
GOAL_COLOR = (0.1, 0.8, 0.2, 0.6)
_HIDDEN = (0.0, 0.0, -10.0)


class SceneMarkers:
    """The goal disc and a trail of ``keep`` odometry arrows in a ``Simulator``."""

    def __init__(
        self,
        sim: Simulator,
        goal_radius_m: float,
        keep: int = 100,
        arrow_length_m: float = 0.08,
    ) -> None:
        self.sim = sim
        self.keep = keep
        self.arrow_length_m = arrow_length_m
        self.goal_radius_m = goal_radius_m
        self.trail: deque[tuple[float, float, float]] = deque(maxlen=keep)
        self._arrows: list[int] = []
        self._goal = -1

    def create(self, goal_xy: np.ndarray) -> None:
        """Add the markers to a freshly reset world and clear the trail."""
        c = self.sim.client
        self._goal = self.sim.add_visual(
            "goal", "cylinder", (self.goal_radius_m, 0.004), GOAL_COLOR,
            (float(goal_xy[0]), float(goal_xy[1]), 0.002),
        )
        length = self.arrow_length_m
        head = length * 0.35
        barb = (0.0, 0.0, math.sin(math.radians(150) / 2), math.cos(math.radians(150) / 2))
        barb_r = (0.0, 0.0, -barb[2], barb[3])
        # an arrow: a shaft along +x from the pose and two barbs at its tip
        shaft = c.createVisualShapeArray(
            shapeTypes=[pybullet.GEOM_BOX] * 3,
            halfExtents=[[length / 2, 0.003, 0.002], [head / 2, 0.003, 0.002],
                         [head / 2, 0.003, 0.002]],
            rgbaColors=[TRAIL_COLOR] * 3,
            visualFramePositions=[
                [length / 2, 0.0, 0.0],
                [length + head / 2 * math.cos(math.radians(150)),
                 head / 2 * math.sin(math.radians(150)), 0.0],
                [length + head / 2 * math.cos(math.radians(150)),
                 -head / 2 * math.sin(math.radians(150)), 0.0],
            ],
            visualFrameOrientations=[[0.0, 0.0, 0.0, 1.0], list(barb), list(barb_r)],
        )
        ids = c.createMultiBody(
            baseMass=0.0, baseVisualShapeIndex=shaft,
            batchPositions=[list(_HIDDEN)] * self.keep,
        )
        self._arrows = list(ids) if isinstance(ids, (list, tuple)) else [ids]
        self.trail.clear()

    def add_pose(self, x: float, y: float, theta: float) -> None:
        """Record one odometry pose (odom frame = world frame at reset)."""
        self.trail.append((x, y, theta))

    def draw(self) -> None:
        """Move the arrow pool onto the recorded trail."""
        c = self.sim.client
        poses: Iterable = list(self.trail)
        for body, (x, y, theta) in zip(self._arrows, poses, strict=False):
            c.resetBasePositionAndOrientation(
                body, (x, y, 0.006), (0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2))
            )
