"""The ROS package shipped with smartcar_gym: ``smartcar_gym_ros`` (launch files, rviz config).

It lies beside the shipped ``smartcar_description`` in one folder; with that folder on
``ROS_PACKAGE_PATH``, ``roslaunch smartcar_gym_ros ...`` and ``$(find smartcar_description)``
find them::

    export ROS_PACKAGE_PATH=$(smartcar-ros package):$ROS_PACKAGE_PATH
"""

from __future__ import annotations

from pathlib import Path

from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS

PACKAGE_NAME = "smartcar_gym_ros"


def package_folder() -> Path:
    """The folder to put on ``ROS_PACKAGE_PATH`` (it holds both ROS packages)."""
    return SHIPPED_DESCRIPTIONS


def ros_package() -> Path:
    """The ``smartcar_gym_ros`` package itself."""
    return SHIPPED_DESCRIPTIONS / PACKAGE_NAME
