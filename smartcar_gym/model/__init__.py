"""Robot models: load a URDF/xacro description (ROS not needed) into a checked ``RobotModel``.

``load_model()`` expands xacro in-process (``$(find pkg)`` resolved by :func:`find_package`,
ROS-indigo unprefixed tags upgraded), parses the URDF into typed tables, makes mesh paths
absolute, finds the drive wheels, reports physical defects and repairs the ones that make the
car undrivable.
"""

from __future__ import annotations

from smartcar_gym.model.defects import Defect
from smartcar_gym.model.errors import (
    LegacyXacroWarning,
    ModelDefectWarning,
    ModelError,
    XacroWarning,
)
from smartcar_gym.model.loader import SHIPPED_MODEL, RobotModel, load_model
from smartcar_gym.model.packages import find_package
from smartcar_gym.model.repair import Repair
from smartcar_gym.model.urdf import Geometry, Inertial, Joint, Link, Origin, Shape
from smartcar_gym.model.wheels import Wheel

__all__ = [
    "SHIPPED_MODEL",
    "Defect",
    "Geometry",
    "Inertial",
    "Joint",
    "LegacyXacroWarning",
    "Link",
    "ModelDefectWarning",
    "ModelError",
    "Origin",
    "Repair",
    "RobotModel",
    "Shape",
    "Wheel",
    "XacroWarning",
    "find_package",
    "load_model",
]
