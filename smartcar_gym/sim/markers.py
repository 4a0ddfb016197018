"""Visual-only markers: the goal and the odometry trail (as the seed's rviz config shows it).

rviz's Odometry display keeps the last 100 ``/odom`` poses as arrows; we keep a pool of 100 thin
arrow bodies and move them, which the headless TinyRenderer draws like any other body (debug
lines are GUI-only). Nothing here exists unless the env renders.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from smartcar_gym.sim.contracts import Body, BoxPart, Simulator

TRAIL_COLOR = (221 / 255, 200 / 255, 14 / 255, 1.0)  # the seed's rviz Odometry colour
GOAL_COLOR = (0.1, 0.8, 0.2, 0.6)
_HIDDEN = (0.0, 0.0, -10.0)


def arrow_parts(length: float) -> list[BoxPart]:
    """An arrow along +x from the origin: a shaft and two barbs at its tip."""
    head = length * 0.35
    barb = math.radians(150)
    tip_x = length + head / 2 * math.cos(barb)
    tip_y = head / 2 * math.sin(barb)
    quat = (0.0, 0.0, math.sin(barb / 2), math.cos(barb / 2))
    quat_r = (0.0, 0.0, -quat[2], quat[3])
    return [
        BoxPart((length / 2, 0.003, 0.002), (length / 2, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0),
                TRAIL_COLOR),
        BoxPart((head / 2, 0.003, 0.002), (tip_x, tip_y, 0.0), quat, TRAIL_COLOR),
        BoxPart((head / 2, 0.003, 0.002), (tip_x, -tip_y, 0.0), quat_r, TRAIL_COLOR),
    ]


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
        self._arrows: list[Body] = []
        self._goal: Body | None = None

    def create(self, goal_xy: np.ndarray) -> None:
        """Add the markers to a freshly reset world and clear the trail."""
        self._goal = self.sim.add_visual(
            "goal", "cylinder", (self.goal_radius_m, 0.004), GOAL_COLOR,
            (float(goal_xy[0]), float(goal_xy[1]), 0.002),
        )
        self._arrows = self.sim.add_visual_copies(
            "odom_arrow_", arrow_parts(self.arrow_length_m), self.keep, _HIDDEN
        )
        self.trail.clear()

    def add_pose(self, x: float, y: float, theta: float) -> None:
        """Record one odometry pose (odom frame = world frame at reset)."""
        self.trail.append((x, y, theta))

    def draw(self) -> None:
        """Move the arrow pool onto the recorded trail."""
        for body, (x, y, theta) in zip(self._arrows, list(self.trail), strict=False):
            body.set_com_pose((x, y, 0.006), (0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2)))
