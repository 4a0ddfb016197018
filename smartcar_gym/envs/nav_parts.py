"""The parts SmartCarNav-v0 is made of, from its arguments: the laser's settings, the robot
model with its laser, and the car's footprint (for obstacle clearances)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from smartcar_gym import checks
from smartcar_gym.envs.sensors.scan import LaserConfig
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.model.kinematics import link_frames, transform
from smartcar_gym.model.urdf import UrdfRobot


def laser_config(laser: Mapping[str, Any] | LaserConfig | None) -> LaserConfig:
    """The ``laser`` argument as a ``LaserConfig``: None (the defaults), a config, or a dict of
    the fields to change; an error naming an unknown field or a bad value."""
    if laser is None or isinstance(laser, LaserConfig):
        return laser or LaserConfig()
    if not isinstance(laser, Mapping):
        raise TypeError(f"laser must be a dict of LaserConfig fields or a LaserConfig, got "
                        f"{type(laser).__name__}: {laser!r}")
    fields = [f.name for f in dataclasses.fields(LaserConfig)]
    unknown = sorted(set(map(str, laser)) - set(fields))
    if unknown:
        raise ValueError(f"laser: unknown field(s) {unknown}; LaserConfig has "
                         f"{', '.join(fields)}")
    return LaserConfig(**laser)


def nav_model(model: Any, model_args: Mapping[str, Any] | None,
               kwargs: dict[str, Any]) -> Any:
    """The shipped car with ``laser:=true`` by default; a path loaded with ``model_args``."""
    if model_args is not None and not isinstance(model_args, Mapping):
        raise TypeError(f"model_args must be a dict of xacro arguments, got {model_args!r}")
    if model is None:
        model_args = {"laser": "true", **(model_args or {})}
    elif isinstance(model, RobotModel) or model_args is None:
        return model
    checks.source("model", model, RobotModel)
    return load_model(model, mappings=model_args, package_path=kwargs.pop("package_path", None),
                      wheels=kwargs.pop("wheels", None))


def footprint_radius(model: RobotModel) -> float:
    """Radius (m) of the smallest circle about base_link (in x-y) that holds every collision
    shape of the model: the car's footprint for obstacle clearances."""
    robot = UrdfRobot(model.name, model.links, model.joints, model.base_link)
    frames = link_frames(robot)
    radius = 0.0
    for name, link in model.links.items():
        for shape in link.collisions:
            centre = (frames[name] @ transform(shape.origin))[:2, 3]
            geometry = shape.geometry
            if geometry.type == "box":
                extent = float(np.linalg.norm(geometry.size)) / 2.0
            elif geometry.type == "cylinder":
                extent = math.hypot(geometry.size[0], geometry.size[1] / 2.0)
            elif geometry.type == "sphere":
                extent = geometry.size[0]
            else:  # a mesh: the link origin only
                extent = 0.0
            radius = max(radius, float(np.linalg.norm(centre)) + extent)
    return radius
