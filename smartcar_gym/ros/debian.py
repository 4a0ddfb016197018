"""ROS 1 for this Python: Debian's rospy and message packages, which PyPI does not have.

Debian (bookworm) and Ubuntu ship ROS 1 as apt packages whose Python modules live in
``/usr/lib/python3/dist-packages``. A virtualenv does not see that folder, so when ``rospy`` is
not importable as is, the folder is **appended** to ``sys.path``, never prepended: the
virtualenv's own packages (numpy, PyYAML, ...) keep precedence and only what it lacks (rospy,
genpy, rosgraph, the message packages) comes from Debian. This works when this Python has the
minor version of Debian's ``python3`` (bookworm: 3.11), which the few compiled modules of that
folder were built for; rospy and the messages themselves are pure Python.

Nothing here runs on import: ``import_ros()`` does it, and says in one line which Debian
packages to install when something is missing.
"""

from __future__ import annotations

import importlib
import os
import sys
from types import ModuleType, SimpleNamespace

DEBIAN_DIST_PACKAGES = "/usr/lib/python3/dist-packages"
# Import name -> the Debian package that provides it.
MODULE_PACKAGES = {
    "rospy": "python3-rospy",
    "std_msgs": "python3-std-msgs",
    "geometry_msgs": "python3-geometry-msgs",
    "nav_msgs": "python3-nav-msgs",
    "sensor_msgs": "python3-sensor-msgs",
    "tf2_msgs": "python3-tf2-msgs",
    "rosgraph_msgs": "python3-rosgraph-msgs",
}
# ros-core: roscore and roslaunch. python3-nav-msgs does not pull python3-geometry-msgs.
DEBIAN_PACKAGES = ("ros-core", *MODULE_PACKAGES.values())
APT_LINE = "sudo apt-get install " + " ".join(DEBIAN_PACKAGES)


class RosUnavailable(ImportError):
    """ROS 1's Python modules cannot be imported; the message is one line naming the packages."""


def _import(name: str) -> ModuleType:
    try:
        return importlib.import_module(name)
    except ImportError:
        if not os.path.isdir(DEBIAN_DIST_PACKAGES) or DEBIAN_DIST_PACKAGES in sys.path:
            raise
    sys.path.append(DEBIAN_DIST_PACKAGES)  # after the virtualenv's folders: see the docstring
    importlib.invalidate_caches()
    return importlib.import_module(name)


def import_ros() -> SimpleNamespace:
    """rospy and the message modules the bridge uses, as a namespace.

    Attributes: ``rospy`` and ``std_msgs``, ``geometry_msgs``, ``nav_msgs``, ``sensor_msgs``,
    ``tf2_msgs``, ``rosgraph_msgs`` (their ``.msg`` modules). Raises ``RosUnavailable`` with one
    line naming the Debian packages to install.
    """
    modules = {}
    for name, package in MODULE_PACKAGES.items():
        target = name if name == "rospy" else f"{name}.msg"
        try:
            modules[name] = _import(target)
        except Exception as err:  # ImportError, or a compiled module built for another Python
            found = ("" if not os.path.isdir(DEBIAN_DIST_PACKAGES)
                     else f", Python {sys.version_info.major}.{sys.version_info.minor} looked in "
                          f"{DEBIAN_DIST_PACKAGES} too")
            raise RosUnavailable(
                f"cannot import {target} ({type(err).__name__}: {' '.join(str(err).split())}"
                f"{found}); smartcar-ros "
                f"needs ROS 1 from Debian/Ubuntu ({package}): {APT_LINE}"
            ) from err
    return SimpleNamespace(**modules)
