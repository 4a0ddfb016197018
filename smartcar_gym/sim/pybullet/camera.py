"""Rendering and visual-only shapes: pybullet's cameras and collision-free marker bodies."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from smartcar_gym.sim.contracts import BoxPart
from smartcar_gym.sim.pybullet.bullet import bullet_client, pybullet

__all__ = ["BoxPart", "model_image", "orbit_image", "visual_batch", "visual_body"]


def visual_body(client: bullet_client.BulletClient, shape: str, size: Sequence[float],
                rgba: Sequence[float], position: Sequence[float]) -> int:
    """A massless, collision-free body of one 'sphere', 'cylinder' or 'box' shape."""
    if shape == "sphere":
        vis = client.createVisualShape(pybullet.GEOM_SPHERE, radius=size[0], rgbaColor=rgba)
    elif shape == "cylinder":
        vis = client.createVisualShape(
            pybullet.GEOM_CYLINDER, radius=size[0], length=size[1], rgbaColor=rgba
        )
    elif shape == "box":
        vis = client.createVisualShape(pybullet.GEOM_BOX, halfExtents=list(size), rgbaColor=rgba)
    else:
        raise ValueError(f"unknown marker shape {shape!r}: expected sphere, cylinder or box")
    return client.createMultiBody(baseMass=0.0, baseVisualShapeIndex=vis,
                                  basePosition=list(position))


def visual_batch(client: bullet_client.BulletClient, parts: Sequence[BoxPart], count: int,
                 position: Sequence[float]) -> list[int]:
    """``count`` massless, collision-free bodies of one shape made of boxes, in one call."""
    shape = client.createVisualShapeArray(
        shapeTypes=[pybullet.GEOM_BOX] * len(parts),
        halfExtents=[list(p.half_extents) for p in parts],
        rgbaColors=[list(p.rgba) for p in parts],
        visualFramePositions=[list(p.position) for p in parts],
        visualFrameOrientations=[list(p.orientation) for p in parts],
    )
    ids = client.createMultiBody(baseMass=0.0, baseVisualShapeIndex=shape,
                                 batchPositions=[list(position)] * count)
    return list(ids) if isinstance(ids, list | tuple) else [ids]


def orbit_image(client: bullet_client.BulletClient, width: int, height: int,
                target: Sequence[float], distance: float, yaw_deg: float, pitch_deg: float,
                fov_deg: float = 50.0, opengl: bool = False) -> np.ndarray:
    """An RGB image (height, width, 3) uint8 from a camera orbiting ``target``."""
    view = client.computeViewMatrixFromYawPitchRoll(
        cameraTargetPosition=list(target), distance=distance, yaw=yaw_deg, pitch=pitch_deg,
        roll=0.0, upAxisIndex=2,
    )
    proj = client.computeProjectionMatrixFOV(
        fov=fov_deg, aspect=width / height, nearVal=0.02, farVal=100.0
    )
    renderer = pybullet.ER_BULLET_HARDWARE_OPENGL if opengl else pybullet.ER_TINY_RENDERER
    _, _, rgba, _, _ = client.getCameraImage(
        width, height, viewMatrix=view, projectionMatrix=proj, renderer=renderer
    )
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()


def model_image(client: bullet_client.BulletClient, body: int, width: int, height: int,
                yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """An RGB image framing the whole of ``body`` (all its links), with shadows."""
    low, high = (np.array(c) for c in client.getAABB(body))
    for link in range(client.getNumJoints(body)):
        lo, hi = client.getAABB(body, link)
        low, high = np.minimum(low, lo), np.maximum(high, hi)
    size = float(np.linalg.norm(high - low))
    view = client.computeViewMatrixFromYawPitchRoll(
        cameraTargetPosition=((low + high) / 2).tolist(), distance=1.6 * size,
        yaw=yaw_deg, pitch=pitch_deg, roll=0.0, upAxisIndex=2)
    projection = client.computeProjectionMatrixFOV(
        fov=40.0, aspect=width / height, nearVal=0.01, farVal=20.0 * size)
    _, _, rgba, _, _ = client.getCameraImage(
        width, height, view, projection, shadow=1, lightDirection=[1.0, 1.0, 2.0],
        renderer=pybullet.ER_TINY_RENDERER)
    return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3]
