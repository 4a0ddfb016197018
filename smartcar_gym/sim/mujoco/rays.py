"""Ray casts in MuJoCo worlds: ``MujocoSimulator.ray_batch`` (one world) and
``CarBatch.scan`` (each car's world of the batched MuJoCo envs) share this arithmetic, so a
batched car's scan is its single env's bit for bit."""

from __future__ import annotations

import mujoco
import numpy as np

from smartcar_gym.sim.rays import RayHits

#: the rays' geom groups: the world's and the robots' collision shapes (not hidden, visuals)
RAY_GROUPS = np.array([1, 1, 0, 0, 0, 0], dtype=np.uint8)
_RAY_NORMALS = (None,) if "normal" in (mujoco.mj_multiRay.__doc__ or "") else ()


def unit_rays(starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each ray's vector, length and unit direction (``(..., 3)`` starts and ends)."""
    vec = ends - starts
    length = np.linalg.norm(vec, axis=-1)
    return vec, length, vec / np.where(length > 0, length, 1.0)[..., None]


def multi_ray(m: mujoco.MjModel, d: mujoco.MjData, start: np.ndarray, unit: np.ndarray,
              cutoff: float, geom: np.ndarray, dist: np.ndarray) -> None:
    """``mj_multiRay`` from ``start`` along ``unit`` ((B, 3)) up to ``cutoff`` m: the first geom
    each ray hits (-1: none) and its distance into ``geom`` and ``dist``."""
    mujoco.mj_multiRay(m, d, start, unit.ravel(), RAY_GROUPS, 1, -1, geom, dist,
                       *_RAY_NORMALS, len(unit), cutoff)  # normals: since MuJoCo 3.3.x


def hit_fraction(geom: np.ndarray, dist: np.ndarray,
                 length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which rays hit within their length, and how far along (1 where none)."""
    hit = (geom >= 0) & (dist >= 0) & (dist <= length)
    return hit, np.where(hit, dist / np.where(length > 0, length, 1.0), 1.0)


def cast(m: mujoco.MjModel, d: mujoco.MjData, starts: np.ndarray, ends: np.ndarray) -> RayHits:
    """Rays from ``starts`` to ``ends`` ((N, 3) arrays) in the world of ``m`` and ``d`` (whose
    geom poses must be current: ``mj_kinematics``): ``mj_multiRay`` from a common start,
    ``mj_ray`` otherwise; geoms hidden from rays are passed through."""
    vec, length, unit = unit_rays(starts, ends)
    count = len(starts)
    geom = np.full(count, -1, dtype=np.int32)
    dist = np.full(count, -1.0)
    if np.all(starts == starts[0]):
        multi_ray(m, d, starts[0], unit, float(length.max()), geom, dist)
    else:
        one = np.zeros(1, dtype=np.int32)
        for i in range(count):
            dist[i] = mujoco.mj_ray(m, d, starts[i], unit[i], RAY_GROUPS, 1, -1, one)
            geom[i] = one[0]
    hit, fraction = hit_fraction(geom, dist, length)
    body = np.where(hit, m.body_rootid[m.geom_bodyid[np.maximum(geom, 0)]], -1)
    point = starts + vec * fraction[:, None]
    return RayHits(fraction=fraction, body=body.astype(int), point=point)
