"""What the tests that use Debian's ROS 1 need, and the Debian package that brings each.

A test that needs a ROS program, node or Python module that is missing is skipped, and the
reason names the Debian package to install (docs/ros.md lists them)::

    @ros_needs.needs("roslaunch", "robot_state_publisher")
    def test_...

``missing(...)`` is the reason (None: everything is there). Probes run once per process.
"""

from __future__ import annotations

import functools
import shutil
import subprocess
import sys

import pytest

#: programs on PATH -> the Debian package that installs them
PROGRAMS = {
    "roscore": "ros-core",
    "roslaunch": "ros-core",
    "rosbag": "python3-rosbag",
}
#: ROS nodes (package, executable) that roslaunch starts -> the Debian package
NODES = {
    "robot_state_publisher": (("robot_state_publisher", "robot_state_publisher"),
                              "ros-robot-state-publisher"),
}
#: rospy and the message modules of the bridge (smartcar_gym.ros.debian names their packages)
ROSPY = "rospy"
#: Debian's Python modules of rosbag, read by Debian's own python3
DEBIAN_ROSBAG = "rosbag (python)"
DEBIAN_PYTHON = "/usr/bin/python3"  # the interpreter of Debian's ROS programs

APT = "apt-get install"


@functools.cache
def _rospy_missing() -> str | None:
    """The bridge's one-line error when rospy or a message module cannot be imported."""
    check = subprocess.run(
        [sys.executable, "-c", "from smartcar_gym.ros.debian import import_ros; import_ros()"],
        capture_output=True, text=True, timeout=60)
    if check.returncode == 0:
        return None
    lines = check.stderr.strip().splitlines()
    return lines[-1] if lines else f"import_ros() exited with {check.returncode}"


@functools.cache
def _node_found(package: str, executable: str) -> bool:
    """Whether roslaunch would find ``<node pkg=package type=executable>`` (asked the way
    roslaunch asks: roslib.packages.find_node, under Debian's python3)."""
    code = ("import roslib.packages as p, sys; "
            f"sys.exit(0 if p.find_node({package!r}, {executable!r}) else 1)")
    try:
        check = subprocess.run([DEBIAN_PYTHON, "-c", code], capture_output=True, timeout=60)
    except OSError:
        return False
    return check.returncode == 0


@functools.cache
def _debian_module_found(module: str) -> bool:
    try:
        check = subprocess.run([DEBIAN_PYTHON, "-c", f"import {module}"], capture_output=True,
                               timeout=60)
    except OSError:
        return False
    return check.returncode == 0


def missing(*needs: str) -> str | None:
    """Why the tests needing ``needs`` cannot run, naming each Debian package; None if all
    are there. Names: keys of PROGRAMS and NODES, ROSPY, DEBIAN_ROSBAG."""
    reasons = []
    for need in needs:
        if need in PROGRAMS:
            if shutil.which(need) is None:
                reasons.append(f"{need} not found: {APT} {PROGRAMS[need]}")
        elif need in NODES:
            (package, executable), debian = NODES[need]
            if not _node_found(package, executable):
                reasons.append(f"ROS node {package}/{executable} not found (roslaunch starts "
                               f"it): {APT} {debian}")
        elif need == ROSPY:
            reason = _rospy_missing()
            if reason is not None:
                reasons.append(reason)
        elif need == DEBIAN_ROSBAG:
            if not _debian_module_found("rosbag"):
                reasons.append(f"Debian's python3 cannot import rosbag: {APT} python3-rosbag")
        else:
            raise ValueError(f"unknown ROS need {need!r}")
    return "; ".join(reasons) or None


def needs(*names: str) -> pytest.MarkDecorator:
    """A skipif mark: skip, naming the Debian packages, unless everything in ``names`` is
    there."""
    reason = missing(*names)
    return pytest.mark.skipif(reason is not None, reason=f"no ROS 1: {reason}")
