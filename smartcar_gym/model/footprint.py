"""A robot's footprint on the ground, from its collision shapes: the circle and the box about
base_link that hold it, and its width (what BARN scales its worlds by)."""

from __future__ import annotations

import math

import numpy as np

from smartcar_gym.model.kinematics import link_frames, transform
from smartcar_gym.model.loader import RobotModel
from smartcar_gym.model.urdf import UrdfRobot


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


def footprint_half_extents(model: RobotModel, wheel_contact: str = "urdf"
                           ) -> tuple[float, float]:
    """Half the length (along base_link x) and half the width (y) of the box about base_link
    that holds the model's collision shapes' bounding boxes (a mesh counts as its origin);
    with ``wheel_contact="sphere"`` the drive wheels as the simulator has them, spheres of
    their radius."""
    robot = UrdfRobot(model.name, model.links, model.joints, model.base_link)
    frames = link_frames(robot)
    reach = np.zeros(2)
    for name, link in model.links.items():
        for shape in link.collisions:
            pose = frames[name] @ transform(shape.origin)
            g = shape.geometry
            half = {"box": lambda s: np.asarray(s) / 2.0,
                    "cylinder": lambda s: np.array([s[0], s[0], s[1] / 2.0]),
                    "sphere": lambda s: np.full(3, s[0])}.get(g.type, lambda s: np.zeros(3))(
                        g.size)
            # the shape's box's extent along base_link x and y: |t| + |R| . half
            reach = np.maximum(reach, np.abs(pose[:2, 3]) + np.abs(pose[:2, :3]) @ half)
    if wheel_contact == "sphere":
        for wheel in model.left_wheels + model.right_wheels:
            reach = np.maximum(reach, np.abs(wheel.position_m[:2]) + wheel.radius_m)
    return float(reach[0]), float(reach[1])


def car_width(model: RobotModel) -> float:
    """The model's width (m): ``footprint_half_extents``'s, doubled."""
    return 2.0 * footprint_half_extents(model)[1]
