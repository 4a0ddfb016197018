"""Headless picture of a robot model on a ground plane (``smartcar-model show``)."""

from __future__ import annotations

import os
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from smartcar_gym.model.loader import RobotModel
from smartcar_gym.sim.pybullet.camera import model_image
from smartcar_gym.sim.pybullet.simulator import Simulator

SETTLE_SUBSTEP_S = 1 / 240


def render_image(model: RobotModel, *, width: int = 640, height: int = 480,
                 settle_s: float = 0.0, yaw_deg: float = 135.0,
                 pitch_deg: float = -25.0) -> np.ndarray:
    """RGB image (height x width x 3, uint8) of the model from a 3/4 front-left view.

    The model is placed with its wheels on the plane; ``settle_s`` > 0 first lets it fall
    and settle under gravity (shows what a simulator does with it).
    """
    sim = Simulator(max_substep_s=SETTLE_SUBSTEP_S)
    try:
        spawn_z = max((w.radius_m - w.position_m[2] for w in model.wheels), default=0.0)
        body = sim.load_urdf("robot", model.write_urdf(sim.scratch_dir), (0.0, 0.0, spawn_z))
        if settle_s > 0:
            sim.settle(settle_s)
        return model_image(sim.client, body.uid, width, height, yaw_deg, pitch_deg)
    finally:
        sim.close()


def write_png(model: RobotModel, path: str | os.PathLike, **options) -> Path:
    """Render the model (see :func:`render_image`) into a PNG file."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(target, render_image(model, **options), extension=".png")
    return target
