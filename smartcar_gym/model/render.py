"""Headless picture of a robot model on a ground plane (pybullet TinyRenderer)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from smartcar_gym._bullet import connect
from smartcar_gym.model.bodies import load_body
from smartcar_gym.model.loader import RobotModel

PHYSICS_HZ = 240


def render_image(model: RobotModel, *, width: int = 640, height: int = 480,
                 settle_s: float = 0.0, yaw_deg: float = 135.0,
                 pitch_deg: float = -25.0) -> np.ndarray:
    """RGB image (height x width x 3, uint8) of the model from a 3/4 front-left view.

    The model is placed with its wheels on the plane; ``settle_s`` > 0 first lets it fall
    and settle under gravity (shows what a simulator does with it).
    """
    client = connect()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            client.loadURDF("plane.urdf")
            spawn_z = max((w.radius_m - w.position_m[2] for w in model.wheels), default=0.0)
            body = load_body(client, model.write_urdf(tmp), [0.0, 0.0, spawn_z],
                             flags=client.URDF_USE_INERTIA_FROM_FILE)
        if settle_s > 0:
            client.setGravity(0.0, 0.0, -9.81)
            for _ in range(int(settle_s * PHYSICS_HZ)):
                client.stepSimulation()
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
            renderer=client.ER_TINY_RENDERER)
    finally:
        client.disconnect()
    return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3]


def write_png(model: RobotModel, path: str | os.PathLike, **options) -> Path:
    """Render the model (see :func:`render_image`) into a PNG file."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(target, render_image(model, **options), extension=".png")
    return target
