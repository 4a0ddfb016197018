"""Emulation of the ArbotiX ROS ``diff_controller`` and its board firmware (no physics engine).

``ArbotixBase`` joins the host-side ``DiffController``, the board's ``ArbotixBoard`` PID, the
wheel encoders and the ``DCMotor`` model; the simulator plugs in through ``WheelDrive``.
"""

from __future__ import annotations

from smartcar_gym.controller.base import ArbotixBase, WheelDrive, board_millis
from smartcar_gym.controller.board import ArbotixBoard, WheelPID
from smartcar_gym.controller.config import (
    ArbotixConfig,
    ControllerConfigError,
    MotorConfig,
    default_config_path,
    load_controller_config,
    parse_controller_config,
)
from smartcar_gym.controller.diff_controller import (
    HARDWARE,
    KINEMATIC,
    MODES,
    DiffController,
    Mode,
    Odometry,
)
from smartcar_gym.controller.encoder import WheelEncoder, ticks_from_angle
from smartcar_gym.controller.motor import DCMotor, MotorOutput

__all__ = [
    "HARDWARE",
    "KINEMATIC",
    "MODES",
    "ArbotixBase",
    "ArbotixBoard",
    "ArbotixConfig",
    "ControllerConfigError",
    "DCMotor",
    "DiffController",
    "Mode",
    "MotorConfig",
    "MotorOutput",
    "Odometry",
    "WheelDrive",
    "WheelEncoder",
    "WheelPID",
    "board_millis",
    "default_config_path",
    "load_controller_config",
    "parse_controller_config",
    "ticks_from_angle",
]
