"""Localization on a known map of cylinders: the map -> odom correction from each laser scan.

On a known map a ROS robot runs amcl beside move_base: odometry drifts, and amcl publishes the
``map -> odom`` transform that puts the robot back where its scans say it is on the map; the
global plan (map frame) reaches the local planner through it. ``ScanMatcher`` is that
transform's estimate for a map of circles (the BARN worlds' cylinders): each scan's hits are
placed on the map through the current correction and the odometry pose, each is paired with
the nearest cylinder's outline, and a few Gauss-Newton steps move the correction to bring the
hits onto the outlines (the residual is a hit's distance from the circle, ``|p - c| - r``).
A hit further than ``gate_m`` from every outline is left out; with fewer than ``min_hits``
hits paired the correction stays as it is. No ground truth is read.

Poses and corrections are (x, y, yaw) tuples of floats; ``compose(a, b)`` is the pose ``b``
seen from the frame ``a`` (``map_pose = compose(correction, odom_pose)``), computed with
``math`` so that one car and a batch of them (one call per car) get the same bits.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

Pose = tuple[float, float, float]
IDENTITY: Pose = (0.0, 0.0, 0.0)
GATE_M = 0.02  # a hit this far from every outline is not a cylinder's (m)
MIN_HITS = 20  # fewer hits on the map than this: no correction from the scan
STEPS = 2  # Gauss-Newton steps per scan (the correction changes little between scans)


def compose(a: Pose, b: Pose) -> Pose:
    """The pose ``b`` (in frame ``a``) in the frame ``a`` is given in."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def beam_geometry(angles: np.ndarray, mount: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The laser's origin (2,) and its beams' unit directions (B, 2) in base_link's plane, for
    beams at ``angles`` (rad, laser frame) of a laser at ``mount`` (base_link -> laser, 4x4)."""
    mount = np.asarray(mount, dtype=float)
    local = np.stack([np.cos(angles), np.sin(angles), np.zeros(len(angles))], axis=1)
    directions = (local @ mount[:3, :3].T)[:, :2]
    return mount[:2, 3].copy(), directions


class ScanMatcher:
    """The map -> odom correction on a map of circles (``centres`` (M, 2), ``radii`` (M,), m).

    ``correct(correction, odom_pose, ranges, origin, directions)`` is the correction after one
    scan (``ranges`` (B,), REP 117: non-finite ranges hit nothing) taken at ``odom_pose``.
    """

    def __init__(self, centres: np.ndarray, radii: np.ndarray, gate_m: float = GATE_M,
                 min_hits: int = MIN_HITS, steps: int = STEPS) -> None:
        self.centres = np.asarray(centres, dtype=float).reshape(-1, 2)
        self.radii = np.broadcast_to(np.asarray(radii, dtype=float), (len(self.centres),))
        if len(self.centres) == 0:
            raise ValueError("a map with no cylinders gives no correction")
        self._tree = cKDTree(self.centres)
        self.gate_m, self.min_hits, self.steps = float(gate_m), int(min_hits), int(steps)
        self._k = min(4, len(self.centres))  # the nearest outline is among the nearest centres

    def correct(self, correction: Pose, odom_pose: Pose, ranges: np.ndarray,
                origin: np.ndarray, directions: np.ndarray) -> Pose:
        r = np.asarray(ranges, dtype=float)
        hit = np.isfinite(r)
        if hit.sum() < self.min_hits:
            return correction
        base = origin + r[hit, None] * directions[hit]
        c, s = math.cos(odom_pose[2]), math.sin(odom_pose[2])
        odom = np.stack([odom_pose[0] + c * base[:, 0] - s * base[:, 1],
                         odom_pose[1] + s * base[:, 0] + c * base[:, 1]], axis=1)
        for _ in range(self.steps):
            step = self._step(correction, odom, compose(correction, odom_pose))
            if step is None:
                break
            correction = step
        return correction

    def _step(self, correction: Pose, odom: np.ndarray, at: Pose) -> Pose | None:
        """One Gauss-Newton step of the correction (the turn about ``at``, the car on the map),
        or None when too few hits are near an outline."""
        c, s = math.cos(correction[2]), math.sin(correction[2])
        p = np.stack([correction[0] + c * odom[:, 0] - s * odom[:, 1],
                      correction[1] + s * odom[:, 0] + c * odom[:, 1]], axis=1)
        distance, index = self._tree.query(p, k=self._k)
        distance = distance.reshape(len(p), -1)
        index = index.reshape(len(p), -1)
        gap = distance - self.radii[index]
        best = np.argmin(gap, axis=1)
        rows = np.arange(len(p))
        gap, index, distance = gap[rows, best], index[rows, best], distance[rows, best]
        near = (np.abs(gap) < self.gate_m) & (distance > 0.0)
        if near.sum() < self.min_hits:
            return None
        q, e = p[near], gap[near]
        n = (q - self.centres[index[near]]) / distance[near, None]  # outward normals
        arm = q - np.array(at[:2])
        jacobian = np.column_stack([n[:, 0], n[:, 1], n[:, 1] * arm[:, 0] - n[:, 0] * arm[:, 1]])
        normal = jacobian.T @ jacobian + 1e-9 * np.eye(3)
        dx, dy, dyaw = np.linalg.solve(normal, -jacobian.T @ e).tolist()
        # the step turns the map about ``at`` by dyaw and moves it by (dx, dy)
        turn = (at[0] + dx - (math.cos(dyaw) * at[0] - math.sin(dyaw) * at[1]),
                at[1] + dy - (math.sin(dyaw) * at[0] + math.cos(dyaw) * at[1]), dyaw)
        return compose(turn, correction)

