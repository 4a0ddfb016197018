"""Ray casts in one MuJoCo world: ``MujocoSimulator.ray_batch`` and ``CarBatch.cast`` (each
car's world of the batched MuJoCo envs) share this arithmetic, so a batched car's scan is its
single env's bit for bit."""

from __future__ import annotations

import mujoco
import numpy as np

from smartcar_gym.sim.rays import RayHits

#: the rays' geom groups: the world's and the robots' collision shapes (not hidden, visuals)
RAY_GROUPS = np.array([1, 1, 0, 0, 0, 0], dtype=np.uint8)
_RAY_NORMALS = "normal" in (mujoco.mj_multiRay.__doc__ or "")


def cast(m: mujoco.MjModel, d: mujoco.MjData, starts: np.ndarray, ends: np.ndarray) -> RayHits:
    """Rays from ``starts`` to ``ends`` ((N, 3) arrays) in the world of ``m`` and ``d`` (whose
    geom poses must be current: ``mj_kinematics``): ``mj_multiRay`` from a common start,
    ``mj_ray`` otherwise; geoms hidden from rays are passed through."""
    vec = ends - starts
    length = np.linalg.norm(vec, axis=1)
    unit = vec / np.where(length > 0, length, 1.0)[:, None]
    count = len(starts)
    geom = np.full(count, -1, dtype=np.int32)
    dist = np.full(count, -1.0)
    if np.all(starts == starts[0]):
        normals = (None,) if _RAY_NORMALS else ()  # an argument since MuJoCo 3.3.x
        mujoco.mj_multiRay(m, d, starts[0], unit.ravel(), RAY_GROUPS, 1, -1, geom, dist,
                           *normals, count, float(length.max()))
    else:
        one = np.zeros(1, dtype=np.int32)
        for i in range(count):
            dist[i] = mujoco.mj_ray(m, d, starts[i], unit[i], RAY_GROUPS, 1, -1, one)
            geom[i] = one[0]
    hit = (geom >= 0) & (dist >= 0) & (dist <= length)
    fraction = np.where(hit, dist / np.where(length > 0, length, 1.0), 1.0)
    body = np.where(hit, m.body_rootid[m.geom_bodyid[np.maximum(geom, 0)]], -1)
    point = starts + vec * fraction[:, None]
    return RayHits(fraction=fraction, body=body.astype(int), point=point)
