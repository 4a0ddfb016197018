"""A dynamic-window local planner: ROS base_local_planner's TrajectoryPlanner with ``dwa: true``.

Every control period it samples (v, w) in the dynamic window (the velocities reachable from
the current ones within ``acc_lim * sim_period``, capped by the limits), rolls each out at
constant velocity for ``sim_time``, drops those whose footprint would touch a scan point,
and scores the rest as base_local_planner does::

    pdist_scale * path_dist + gdist_scale * goal_dist + occdist_scale * occ_cost

path_dist: the end point's distance to the global path; goal_dist: its distance to the local
goal (the path's point ``local_goal_m`` ahead); both in costmap cells (``meter_scoring``:
metres); occ_cost: the highest inflation cost (0-252, the costmap's) on the way. In-place
turns are sampled too; when nothing is free it backs up at ``escape_vel``, and when that is
blocked as well it stops (move_base would start its recovery behaviours).

``DWAConfig.challenge(scale, speed_scale)`` is the BARN challenge's parameter set for a robot
``scale`` times the Jackal's size and ``speed_scale`` times its speed. ``DWAPlanner.plan`` is
batched: N robots' velocities, obstacle points, path windows and local goals, each in its own
base frame, in numpy arrays.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from smartcar_gym.navigation.footprint import COMPILED as FOOTPRINT_COMPILED
from smartcar_gym.navigation.footprint import footprint_check, to_nearest, window_check

LETHAL_COST = 252.0


@dataclass(frozen=True)
class DWAConfig:
    """base_local_planner's parameters (m, s, rad), the footprint and the costmap's; the
    defaults are the BARN challenge's move_base set for the Jackal."""

    # the limits (m/s, rad/s, m/s^2, rad/s^2)
    max_vel_x: float = 0.5
    min_vel_x: float = 0.1
    max_vel_theta: float = 1.57
    min_in_place_vel_theta: float = 0.4
    acc_lim_x: float = 10.0
    acc_lim_theta: float = 20.0
    escape_vel: float = -0.1
    # the rollouts: seconds ahead, the control period, poses along each, samples
    sim_time: float = 2.0
    sim_period: float = 0.1
    sim_steps: int = 20
    vx_samples: int = 6
    vtheta_samples: int = 20
    # the scoring
    pdist_scale: float = 0.75
    gdist_scale: float = 1.0
    occdist_scale: float = 0.1
    meter_scoring: bool = False
    local_goal_m: float = 1.5
    # the footprint, a rectangle about base_link, and the costmap around it
    half_length: float = 0.254
    half_width: float = 0.215
    footprint_padding: float = 0.02
    resolution: float = 0.05  # costmap cells (m), the unit of path_dist and goal_dist
    inflation_radius: float = 0.5
    cost_scaling_factor: float = 10.0  # 1/m

    @classmethod
    def challenge(cls, scale: float, speed_scale: float, sim_period: float = 0.1,
                  half_length: float | None = None, half_width: float | None = None
                  ) -> DWAConfig:
        """The BARN challenge's set (the Jackal's) for a robot ``scale`` times as big and
        ``speed_scale`` times as fast: lengths x scale, speeds x speed_scale, times x
        scale / speed_scale (so that every manoeuvre takes the same share of a run)."""
        base = cls()
        rate = speed_scale / scale  # angular rates and 1 / times
        config = replace(
            base, max_vel_x=base.max_vel_x * speed_scale,
            min_vel_x=base.min_vel_x * speed_scale,
            max_vel_theta=base.max_vel_theta * rate,
            min_in_place_vel_theta=base.min_in_place_vel_theta * rate,
            acc_lim_x=base.acc_lim_x * speed_scale * rate,
            acc_lim_theta=base.acc_lim_theta * rate * rate,
            sim_time=base.sim_time / rate, sim_period=sim_period,
            escape_vel=base.escape_vel * speed_scale,
            half_length=base.half_length * scale, half_width=base.half_width * scale,
            footprint_padding=base.footprint_padding * scale,
            resolution=base.resolution * scale,
            inflation_radius=base.inflation_radius * scale,
            cost_scaling_factor=base.cost_scaling_factor / scale,
            local_goal_m=base.local_goal_m * scale,
        )
        if half_length is not None or half_width is not None:
            config = replace(config, half_length=half_length or config.half_length,
                             half_width=half_width or config.half_width)
        return config

    @property
    def padded(self) -> tuple[float, float]:
        """The footprint rectangle's half extents with the padding (m): along x, along y."""
        return self.half_length + self.footprint_padding, self.half_width + self.footprint_padding

    @property
    def reach_m(self) -> float:
        """How far from base_link a rollout's footprint can reach."""
        return (max(self.max_vel_x, abs(self.escape_vel)) * self.sim_time
                + math.hypot(self.half_length, self.half_width) + self.footprint_padding)


def arcs(v: np.ndarray, w: np.ndarray, duration: float, steps: int
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses (..., steps, 3) of constant-velocity arcs from the origin, at ``duration / steps``
    to ``duration``, for ``v`` and ``w`` broadcast together, with the cosine and sine of each
    pose's heading (``(..., steps)``). The heading depends on ``w`` alone: the sines and
    cosines are taken over ``w``'s shape, not the broadcast one (a dynamic window's
    ``vx_samples`` speeds share each turn rate)."""
    t = duration * np.arange(1, steps + 1) / steps
    v, w = np.asarray(v, dtype=float)[..., None], np.asarray(w, dtype=float)[..., None]
    theta = w * t
    sin, cos = np.sin(theta), np.cos(theta)
    straight = np.abs(w) < 1e-9
    safe_w = np.where(straight, 1.0, w)
    x = np.where(straight, v * t, v / safe_w * sin)
    y = np.where(straight, 0.0, v / safe_w * (1.0 - cos))
    shape = x.shape
    return (np.stack([x, y, theta * np.ones_like(x)], axis=-1), np.broadcast_to(cos, shape),
            np.broadcast_to(sin, shape))


class DWAPlanner:
    """Chooses cmd_vel (v, w) for N robots at once (``plan``)."""

    def __init__(self, config: DWAConfig, compiled: bool | None = None,
                 threads: int = 1) -> None:
        self.config = config
        self.compiled = compiled  # the footprint check: None, numba where installed
        self.threads = threads  # the compiled check's robots split over these
        c = config
        # beyond this, a point neither touches a footprint nor costs (inflation_cost's 0)
        self.cutoff_m = max(c.inflation_radius, math.hypot(*c.padded)
                            ) * (1.0 + 1e-9)

    def window(self, velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The dynamic window's samples for N robots at ``velocity`` (N, 2): speeds
        (N, vx_samples) and turn rates (N, vtheta_samples)."""
        c = self.config
        v, w = velocity[:, 0], velocity[:, 1]
        v_lo = np.clip(v - c.acc_lim_x * c.sim_period, c.min_vel_x, c.max_vel_x)
        v_hi = np.clip(v + c.acc_lim_x * c.sim_period, c.min_vel_x, c.max_vel_x)
        w_lo = np.clip(w - c.acc_lim_theta * c.sim_period, -c.max_vel_theta, c.max_vel_theta)
        w_hi = np.clip(w + c.acc_lim_theta * c.sim_period, -c.max_vel_theta, c.max_vel_theta)
        a = np.linspace(0.0, 1.0, c.vx_samples)
        b = np.linspace(0.0, 1.0, c.vtheta_samples)
        vs = v_lo[:, None] + (v_hi - v_lo)[:, None] * a  # (N, vx)
        ws = w_lo[:, None] + (w_hi - w_lo)[:, None] * b  # (N, vth)
        return vs, ws

    def fixed(self) -> np.ndarray:
        """(F, 2) the samples every robot has: the in-place turns, and last the escape."""
        c = self.config
        turns = np.linspace(c.min_in_place_vel_theta, c.max_vel_theta, c.vtheta_samples // 2)
        turns = np.concatenate([-turns, turns])
        return np.concatenate([np.stack([np.zeros_like(turns), turns], -1),
                               [[c.escape_vel, 0.0]]])

    def candidates(self, velocity: np.ndarray) -> np.ndarray:
        """(N, C, 2) velocity samples: the dynamic window's (vx_samples x vtheta_samples), the
        in-place turns, and last the escape (backing up)."""
        return self._candidates(*self.window(velocity))

    def _candidates(self, vs: np.ndarray, ws: np.ndarray) -> np.ndarray:
        """``candidates`` of the window's speeds ``vs`` and turn rates ``ws``."""
        moving = np.stack(np.broadcast_arrays(vs[:, :, None], ws[:, None, :]), -1)
        n = len(vs)
        fixed = self.fixed()
        return np.concatenate([moving.reshape(n, -1, 2),
                               np.broadcast_to(fixed, (n, *fixed.shape))], axis=1)

    def _rollouts(self, vs: np.ndarray, ws: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``arcs`` of the candidates of the window ``vs``, ``ws``: poses (N, C, T, 3) and
        their headings' cosines and sines (N, C, T); the fixed samples' made once."""
        c = self.config
        n = len(vs)
        moving = [a.reshape(n, vs.shape[1] * ws.shape[1], *a.shape[3:])
                  for a in arcs(vs[:, :, None], ws[:, None, :], c.sim_time, c.sim_steps)]
        return tuple(np.concatenate([m, np.broadcast_to(f, (n, *f.shape))], axis=1)
                     for m, f in zip(moving, self._fixed_arcs, strict=True))

    @functools.cached_property
    def _fixed_arcs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``arcs`` of ``fixed()``: every robot's, made once."""
        c, fixed = self.config, self.fixed()
        return arcs(fixed[:, 0], fixed[:, 1], c.sim_time, c.sim_steps)

    @functools.cached_property
    def _fixed_ways(self) -> np.ndarray:
        """``_fixed_arcs`` as ways (F, T, 4) of x, y, cos, sin, as ``window_check`` takes
        them."""
        poses, cos, sin = self._fixed_arcs
        return np.concatenate([poses[..., :2], cos[..., None], sin[..., None]], -1)

    def _check(self, vs: np.ndarray, ws: np.ndarray, obstacles: np.ndarray,
               counts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``footprint_check`` of every candidate's rollout, and the rollouts' end points
        (N, C, 2). Compiled, the window's rollouts are made inside the check
        (``window_check``), the same numbers without the (N, C, T) arrays."""
        c = self.config
        half_x, half_y = c.padded
        if not (FOOTPRINT_COMPILED if self.compiled is None else self.compiled):
            poses, cos, sin = self._rollouts(vs, ws)  # (N, C, T, 3), (N, C, T) twice
            valid, nearest = footprint_check(poses, cos, sin, obstacles, counts, half_x,
                                             half_y, self.cutoff_m, compiled=self.compiled)
            return valid, nearest, poses[:, :, -1, :2]
        t = c.sim_time * np.arange(1, c.sim_steps + 1) / c.sim_steps  # as arcs
        theta = ws[:, :, None] * t
        return window_check(vs, ws, np.cos(theta), np.sin(theta), t, self._fixed_ways,
                            obstacles, counts, half_x, half_y, self.cutoff_m,
                            threads=self.threads)

    def plan(self, velocity: np.ndarray, obstacles: np.ndarray, path: np.ndarray,
             goal: np.ndarray, counts: np.ndarray | None = None) -> np.ndarray:
        """cmd_vel (N, 2) for N robots with ``velocity`` (N, 2) (v, w), scan ``obstacles``
        (N, P, 2) of which the first ``counts[n]`` are robot n's (None: all; padding may lie
        anywhere), a window of the global ``path`` (N, Q, 2) (pad with far points) and the
        local ``goal`` (N, 2), all in each robot's base frame: the cheapest valid sample, the
        escape only when nothing else is valid, (0, 0) where nothing is."""
        cand, valid, cost = self.score(velocity, obstacles, path, goal, counts)
        n, count = cand.shape[:2]
        best = np.full(n, -1)
        free = np.any(valid[:, :-1], axis=1)  # the escape, last, only when nothing else is
        best[free] = np.nanargmin(cost[free][:, :-1], axis=1)
        best[~free & valid[:, -1]] = count - 1
        out = np.zeros((n, 2))
        chosen = best >= 0
        out[chosen] = cand[chosen, best[chosen]]
        return out

    def score(self, velocity: np.ndarray, obstacles: np.ndarray, path: np.ndarray,
              goal: np.ndarray, counts: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``plan``'s samples (N, C, 2: the window's, ``forward`` of them, the in-place turns,
        the escape last), whether each is valid (its footprint touches no point) and its cost
        (N, C; NaN where not valid), for ``plan``'s arguments."""
        c = self.config
        vs, ws = self.window(np.asarray(velocity, dtype=float))
        cand = self._candidates(vs, ws)  # (N, C, 2)
        n = cand.shape[0]
        obstacles = np.asarray(obstacles, dtype=float).reshape(n, -1, 2)
        if counts is None:
            counts = np.full(n, obstacles.shape[1])
        # does a footprint on the way touch a point, and how near does the way pass: the
        # inflation cost falls with distance, so the way's highest is its nearest pass's
        valid, nearest, end = self._check(vs, ws, obstacles, np.asarray(counts))
        occ = self.inflation_cost(nearest)  # (N, C)
        path = np.asarray(path, dtype=float)
        path_dist = to_nearest(end, path, compiled=self.compiled)
        goal_dist = np.linalg.norm(end - np.asarray(goal, dtype=float)[:, None], axis=-1)
        unit = 1.0 if c.meter_scoring else c.resolution
        cost = (c.pdist_scale * path_dist / unit + c.gdist_scale * goal_dist / unit
                + c.occdist_scale * occ)
        return cand, valid, np.where(valid, cost, np.nan)

    @property
    def forward(self) -> int:
        """How many of ``score``'s samples are the dynamic window's (driving forward)."""
        return self.config.vx_samples * self.config.vtheta_samples

    def inflation_cost(self, distance: np.ndarray) -> np.ndarray:
        """The costmap's inflation cost (0-252) at ``distance`` (m) from the nearest obstacle:
        lethal within the inscribed radius, decaying with ``cost_scaling_factor`` beyond, 0
        past ``inflation_radius``."""
        c = self.config
        inscribed = c.half_width
        cost = LETHAL_COST * np.exp(-c.cost_scaling_factor * np.maximum(distance - inscribed,
                                                                        0.0))
        return np.where(distance > c.inflation_radius, 0.0, cost)
