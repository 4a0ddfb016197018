"""The bringup node's ArbotiX configuration: its private ROS parameters, else a file.

``arbotix_driver`` reads everything from its private namespace (``~rate``, ``~sim``,
``~controllers/<name>/ticks_meter``, ...): the tutorial's launch file loads
``smartcar_arbotix.yaml`` there with ``<rosparam command="load">``. The bringup node does the
same, through the parser of ``smartcar_gym.controller.config`` (same keys, defaults and errors):

* if ``~controllers`` is on the parameter server, the whole configuration comes from the private
  namespace, as upstream reads it (keys that are not there take upstream's defaults);
* otherwise the file (``--controller-config``, default the shipped ``smartcar_arbotix.yaml``) is
  read, and private parameters that are set (``_sim:=true`` on the command line, a ``<param>``
  in the launch file) replace its top-level keys.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from smartcar_gym.controller import ArbotixConfig, parse_controller_config
from smartcar_gym.controller.config_values import ControllerConfigError
from smartcar_gym.controller.config_yaml import parse_yaml, read_config_file


def controller_config(
    params: Mapping[str, Any] | None,
    namespace: str,
    fallback: str | os.PathLike[str] | None = None,
) -> tuple[ArbotixConfig, str]:
    """The configuration and where it came from (a sentence for the log).

    ``params`` is the node's private namespace as ``rospy.get_param("~")`` returns it (None or
    empty if nothing is set) and ``namespace`` its name (``/arbotix``), which error messages
    name as the source. ``fallback`` is the file read when the server has no ``controllers``.
    """
    params = dict(params or {})
    if "controllers" in params:
        source = f"ROS parameter server {namespace}"
        return parse_controller_config(params, source), f"the {source}"
    text, path = read_config_file(fallback)
    data = parse_yaml(text, path)
    if not isinstance(data, Mapping):
        raise ControllerConfigError(
            f"{path}: expected a mapping of driver parameters, got "
            f"{'an empty file' if data is None else type(data).__name__}")
    if not params:
        return parse_controller_config(data, path), path
    keys = ", ".join(sorted(params))
    source = f"{path} with {namespace} parameters {keys}"
    return parse_controller_config({**data, **params}, source), source


def describe(config: ArbotixConfig) -> str:
    """One line with the values that shape the robot's behaviour (logged at startup)."""
    return (
        f"{config.name}: rate {config.rate_hz:g} Hz, timeout {config.timeout_s:g} s, "
        f"ticks_meter {config.ticks_meter:g}, base_width {config.base_width_m:g} m, "
        f"Kp/Kd/Ki/Ko {config.kp}/{config.kd}/{config.ki}/{config.ko}, "
        f"accel_limit {config.accel_limit:g}, frames {config.odom_frame_id} -> "
        f"{config.base_frame_id}, read_rate {config.read_rate_hz:g} Hz, sim {config.kinematic}"
    )
