"""What base_local_planner's TrajectoryPlanner does around its samples' scores, for N robots:
which in-place turn it takes, the flags that keep it from turning back and forth in place,
and its escape (backing up). ROS navigation, noetic-devel,
``base_local_planner/src/trajectory_planner.cpp``: ``createTrajectories``.

Per control cycle, from the samples' validity and cost (``DWAPlanner.score``):

* unless escaping, the cheapest valid forward sample is the best so far;
* each in-place turn, from the most negative rate up, valid and no dearer than the best so far
  (or there is none), is taken if the point ``heading_lookahead`` ahead of its end heading is
  nearer the local goal than that of every turn taken before, and its direction is not
  stuck; as the source has it, a negative rate is barred by ``stuck_left`` and a positive one
  by ``stuck_right``;
* with a best sample: if it does not drive forward, a turn to the right (negative) sets
  ``stuck_right`` if ``rotating_right`` was set, then sets ``rotating_right`` (left alike),
  and the position is kept; every flag clears once the robot is ``oscillation_reset_dist``
  from that position; the escape ends once the robot is ``escape_reset_dist`` from where it
  began or has turned ``escape_reset_theta`` from its heading there;
* with none: it backs up at ``escape_vel`` (even where the footprint would touch: "we'll
  allow moving backwards slowly even when the static map shows it as blocked"), and escaping
  begins there unless it already had; while escaping no forward sample is tried.

So the planner never answers "nothing valid" to move_base: its controller always has a
command, and move_base's recoveries start only from the planner's side (``planner_patience``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from smartcar_gym import checks


@dataclass(frozen=True)
class OscillationConfig:
    """TrajectoryPlannerROS's parameters (m, rad), its defaults (the challenge sets none)."""

    heading_lookahead: float = 0.325
    oscillation_reset_dist: float = 0.05
    escape_reset_dist: float = 0.10
    escape_reset_theta: float = math.pi / 4

    def __post_init__(self) -> None:
        for name in ("heading_lookahead", "oscillation_reset_dist", "escape_reset_dist",
                     "escape_reset_theta"):
            checks.positive_number(f"oscillation {name}", getattr(self, name))

    @classmethod
    def challenge(cls, scale: float) -> OscillationConfig:
        """The defaults for a robot ``scale`` times the Jackal's size: lengths x scale."""
        checks.positive_number("oscillation scale", scale)
        base = cls()
        return replace(base, heading_lookahead=base.heading_lookahead * scale,
                       oscillation_reset_dist=base.oscillation_reset_dist * scale,
                       escape_reset_dist=base.escape_reset_dist * scale)


class Oscillation:
    """N robots' TrajectoryPlanner flags and escape (module docstring): ``reset(i, pose)`` when
    robot i starts, ``choose`` each control cycle."""

    def __init__(self, n: int, config: OscillationConfig) -> None:
        self.config = config
        self.rotating = np.zeros((n, 2), dtype=bool)  # (left, right)
        self.stuck = np.zeros((n, 2), dtype=bool)  # (left, right)
        self.previous = np.zeros((n, 2))  # where the last in-place sample was taken
        self.escaping = np.zeros(n, dtype=bool)
        self.escape_pose = np.zeros((n, 3))

    def reset(self, i: int, pose: np.ndarray) -> None:
        """Robot ``i`` starts at ``pose`` (x, y, theta): no flags, not escaping."""
        self.rotating[i] = self.stuck[i] = False
        self.previous[i] = pose[:2]
        self.escaping[i] = False
        self.escape_pose[i] = pose[:3]

    def choose(self, rows: list[int], poses: np.ndarray, samples: np.ndarray,
               valid: np.ndarray, cost: np.ndarray, goals: np.ndarray, forward: int,
               sim_time: float) -> np.ndarray:
        """The commands (K, 2) of robots ``rows`` at ``poses`` (K, 3, odom frame) from their
        ``samples`` (K, C, 2: the first ``forward`` driving forward, then the in-place turns,
        the escape last), whether each is ``valid`` and its ``cost`` (K, C), the local goals
        (K, 2, base frame) and the rollouts' ``sim_time`` (s)."""
        c = self.config
        out = np.empty((len(rows), 2))
        turns = forward + np.argsort(samples[0, forward:-1, 1], kind="stable")
        # each robot's cheapest valid forward sample (-1: none, or escaping), all at once
        cheapest = np.full(len(rows), -1)
        driving = ~self.escaping[rows] & valid[:, :forward].any(axis=1)
        if driving.any():
            cheapest[driving] = np.nanargmin(np.where(valid[driving, :forward],
                                                      cost[driving, :forward], np.nan), axis=1)
        for k, i in enumerate(rows):
            best, best_cost = int(cheapest[k]), math.inf
            if best >= 0:
                best_cost = float(cost[k, best])
            heading = math.inf
            for j in turns.tolist():
                w = float(samples[k, j, 1])
                if not valid[k, j] or (best >= 0 and not cost[k, j] <= best_cost):
                    continue
                end = w * sim_time
                ahead = math.hypot(c.heading_lookahead * math.cos(end) - goals[k, 0],
                                   c.heading_lookahead * math.sin(end) - goals[k, 1])
                if ahead < heading and ((w < 0 and not self.stuck[i, 0])
                                        or (w > 0 and not self.stuck[i, 1])):
                    best, best_cost, heading = j, float(cost[k, j]), ahead
            x, y, theta = poses[k]
            if best >= 0:
                v, w = samples[k, best]
                if not v > 0:
                    side = 1 if w < 0 else 0 if w > 0 else -1  # right, left
                    if side >= 0:
                        self.stuck[i, side] |= self.rotating[i, side]
                        self.rotating[i, side] = True
                    self.previous[i] = (x, y)
                out[k] = samples[k, best]
            else:  # the escape, even where its footprint would touch (module docstring)
                out[k] = samples[k, -1]
            if math.hypot(x - self.previous[i, 0], y - self.previous[i, 1]) > \
                    c.oscillation_reset_dist:
                self.rotating[i] = self.stuck[i] = False
            if best < 0 and not self.escaping[i]:
                self.escaping[i] = True
                self.escape_pose[i] = (x, y, theta)
            ex, ey, eth = self.escape_pose[i]
            turned = abs(math.remainder(theta - eth, 2.0 * math.pi))
            if math.hypot(x - ex, y - ey) > c.escape_reset_dist or turned > c.escape_reset_theta:
                self.escaping[i] = False
        return out
