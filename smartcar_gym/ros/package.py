"""The ROS package shipped with smartcar_gym: ``smartcar_gym_ros`` (launch files, rviz config).

With its folder on ``ROS_PACKAGE_PATH``, ``roslaunch smartcar_gym_ros ...`` finds it::

    export ROS_PACKAGE_PATH=$(smartcar-ros package):$ROS_PACKAGE_PATH

Only this package goes on the ROS path. The shipped ``smartcar_description`` beside it stays
off it: on it, it would shadow (or be shadowed by) the ``smartcar_description`` of a workspace
built from the tutorial, whichever comes first on ``ROS_PACKAGE_PATH``. The launch files find
the shipped model and controller YAML from their own folder (``$(dirname)``) instead.
"""

from __future__ import annotations

from pathlib import Path

from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS

PACKAGE_NAME = "smartcar_gym_ros"


def ros_package() -> Path:
    """The ``smartcar_gym_ros`` package itself."""
    return SHIPPED_DESCRIPTIONS / PACKAGE_NAME


def package_folder() -> Path:
    """The folder to put on ``ROS_PACKAGE_PATH``: the ``smartcar_gym_ros`` package alone."""
    return ros_package()
