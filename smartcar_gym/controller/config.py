"""Load and validate the ArbotiX driver YAML (``controllers: {<name>: {type: diff_controller}}``).

The layout is the ArbotiX ROS driver's: driver-level keys at the top, one ``diff_controller``
under ``controllers``, with upstream's defaults and required keys. The plant, which upstream
leaves open, is configured in our own top-level ``smartcar_gym:`` section (``motor``,
``encoder``, ``board``); the real driver ignores that key.

Stricter than upstream where upstream fails silently: a key given twice in one mapping is an
error (YAML keeps the last), an unknown top-level key is warned about like an unknown
controller key, and a ``ticks_meter`` whose targets overflow the board's 16-bit ints is refused
(see ``config_values``).
"""

from __future__ import annotations

import difflib
import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from smartcar_gym.controller import config_values as v
from smartcar_gym.controller.config_values import (
    FRAMES_PER_S,
    INT16_MAX,
    PWM_ZERO_MODES,
    Checker,
    ControllerConfigError,
    close_hint,
    is_number,
)
from smartcar_gym.controller.config_yaml import (
    DEFAULT_CONFIG,
    default_config_path,
    parse_yaml,
    read_config_file,
)

__all__ = [
    "DEFAULT_CONFIG",
    "PWM_ZERO_MODES",
    "SUPPORTED_TYPE",
    "ArbotixConfig",
    "ControllerConfigError",
    "MotorConfig",
    "default_config_path",
    "load_controller_config",
    "parse_controller_config",
]

SUPPORTED_TYPE = "diff_controller"
# Other controller types the ArbotiX driver knows; ignored here (with a warning).
UPSTREAM_OTHER_TYPES = ("follow_controller", "omni_controller", "linear_controller")

_REQUIRED = object()


# YAML key -> (dataclass field, checker, default). Defaults are upstream's.
_DRIVER_KEYS: dict[str, tuple[str, Checker, Any]] = {
    "rate": ("driver_rate_hz", v.positive, 100.0),
    "read_rate": ("read_rate_hz", v.positive, 10.0),
    "write_rate": ("write_rate_hz", v.positive, 10.0),
    "sim": ("kinematic", v.flag, False),  # the driver's fake base, not the simulator
}
_CONTROLLER_KEYS: dict[str, tuple[str, Checker, Any]] = {
    "rate": ("rate_hz", v.positive, 10.0),
    "timeout": ("timeout_s", v.non_negative, 1.0),
    # upstream: float(rospy.get_param(...)), so "4100" is accepted as well
    "ticks_meter": ("ticks_meter", v.ticks_meter, _REQUIRED),
    "base_width": ("base_width_m", v.float_cast, _REQUIRED),
    "base_frame_id": ("base_frame_id", v.text, "base_link"),
    "odom_frame_id": ("odom_frame_id", v.text, "odom"),
    "Kp": ("kp", v.gain, 5),
    "Kd": ("kd", v.gain, 1),
    "Ki": ("ki", v.gain, 0),
    "Ko": ("ko", v.ko, 50),
    "accel_limit": ("accel_limit", v.non_negative, 0.1),
}
_REQUIRED_HELP = {
    "ticks_meter": "encoder ticks per metre of wheel travel",
    "base_width": "track width in metres",
}
# Our section: subsection -> YAML key -> (dataclass field, checker).
_OWN_KEYS: dict[str, dict[str, tuple[str, Checker]]] = {
    "motor": {
        "stall_torque": ("stall_torque_nm", v.positive),
        "no_load_speed": ("no_load_speed_rad_s", v.positive),
        "reflected_inertia": ("reflected_inertia_kg_m2", v.non_negative),
        "friction_torque": ("friction_torque_nm", v.non_negative),
    },
    "encoder": {"left": ("encoder_left", v.text), "right": ("encoder_right", v.text)},
    "board": {"frame_ms": ("frame_ms", v.frame_ms), "pwm_zero": ("pwm_zero", v.pwm_zero)},
}
# The other top-level keys arbotix_python's driver (arbotix_driver and the publishers and servo
# controller it starts) reads as private parameters; tolerated, unused. `dynamixels` and `servos`
# are the names older releases gave `joints`. Any other top-level key is warned about.
_DRIVER_OTHER_KEYS = (
    "port", "baud", "timeout", "sync_read", "sync_write", "diagnostic_rate", "controllers",
    "joints", "dynamixels", "servos", "digital_servos", "digital_sensors", "analog_sensors",
    "smartcar_gym",
)


@dataclass(frozen=True)
class MotorConfig:
    """A side's DC gearmotor, seen at the wheels it drives, and what the driver does at PWM 0.

    One motor per ArbotiX channel drives all wheels of its side through a 1:1 chain.
    ``pwm_zero`` comes from ``smartcar_gym.board.pwm_zero`` in the YAML.
    """

    stall_torque_nm: float = 0.34  # at the wheels, PWM 255
    no_load_speed_rad_s: float = 33.5  # at the wheels, PWM 255
    pwm_zero: str = "coast"  # "coast": output disconnected at PWM 0; "brake": shorted
    # Rotor inertia seen at the wheel (x gear ratio squared), added to the wheel's spin inertia
    reflected_inertia_kg_m2: float = 1.8e-3
    # Coulomb friction of the gearbox, seen at the wheels: what stops a coasting car
    friction_torque_nm: float = 0.03

    def __post_init__(self) -> None:
        v.positive(self.stall_torque_nm, "MotorConfig.stall_torque_nm")
        v.non_negative(self.reflected_inertia_kg_m2, "MotorConfig.reflected_inertia_kg_m2")
        v.non_negative(self.friction_torque_nm, "MotorConfig.friction_torque_nm")
        v.positive(self.no_load_speed_rad_s, "MotorConfig.no_load_speed_rad_s")
        v.pwm_zero(self.pwm_zero, "MotorConfig.pwm_zero")


@dataclass(frozen=True)
class ArbotixConfig:
    """The ArbotiX driver, its one ``diff_controller``, and our plant settings.

    Units are in the field names; ``ticks_meter`` is ticks per metre; ``accel_limit`` is upstream's
    (nominally m/s^2; see ``max_accel``). Gains are the firmware's 0..255 integers.
    """

    ticks_meter: float
    base_width_m: float
    rate_hz: float = 10.0
    timeout_s: float = 1.0
    kp: int = 5
    kd: int = 1
    ki: int = 0
    ko: int = 50
    accel_limit: float = 0.1
    base_frame_id: str = "base_link"
    odom_frame_id: str = "odom"
    name: str = "base_controller"
    driver_rate_hz: float = 100.0
    read_rate_hz: float = 10.0
    write_rate_hz: float = 10.0
    kinematic: bool = False  # the driver's `sim: true`: the base follows cmd_vel, no PID
    motor: MotorConfig = field(default_factory=MotorConfig)
    encoder_left: str = "auto"
    encoder_right: str = "auto"
    frame_ms: int = 33
    source: str = "<ArbotixConfig>"

    def __post_init__(self) -> None:
        where = f"{self.source}: controllers.{self.name}"
        for key, (attr, check, _) in _CONTROLLER_KEYS.items():
            object.__setattr__(self, attr, check(getattr(self, attr), f"{where}.{key}"))
        for key, (attr, check, _) in _DRIVER_KEYS.items():
            object.__setattr__(self, attr, check(getattr(self, attr), f"{self.source}: {key}"))
        own = f"{self.source}: smartcar_gym"
        v.text(self.encoder_left, f"{own}.encoder.left")
        v.text(self.encoder_right, f"{own}.encoder.right")
        v.frame_ms(self.frame_ms, f"{own}.board.frame_ms")
        if not isinstance(self.motor, MotorConfig):
            raise ControllerConfigError(f"{own}.motor: expected a MotorConfig, got {self.motor!r}")
        if not math.isfinite(self.accel_limit * self.ticks_meter / self.rate_hz):
            raise ControllerConfigError(
                f"{where}.accel_limit: {self.accel_limit!r} makes the ramp step "
                "int(accel_limit*ticks_meter/rate) infinite; expected a finite step"
            )

    @property
    def max_accel(self) -> int:
        """Upstream's ramp step in ticks/frame per update: ``int(accel_limit*ticks_meter/rate)``."""
        return int(self.accel_limit * self.ticks_meter / self.rate_hz)

    @property
    def max_target_speed_m_s(self) -> float:
        """The fastest wheel-surface speed (m/s) the board can be told: ``32767*30/ticks_meter``.

        Upstream sends a wheel's target as ``int(speed*ticks_meter/30)`` ticks per frame in a
        16-bit int (at most 32767); a faster one wraps on the board, e.g. to full reverse. A
        twist (v, omega) fits if ``|v| + |omega|*base_width_m/2`` is at most this. 239.8 m/s
        for the tutorial's 4100 ticks/m.
        """
        return INT16_MAX * FRAMES_PER_S / self.ticks_meter

    @property
    def pwm_zero(self) -> str:
        """What PWM 0 does to the motors (``smartcar_gym.board.pwm_zero``)."""
        return self.motor.pwm_zero

    @property
    def gains(self) -> tuple[int, int, int, int]:
        """``(Kp, Kd, Ki, Ko)`` as sent to the board by the setup packet."""
        return self.kp, self.kd, self.ki, self.ko


# -- loading -----------------------------------------------------------------------------------
def load_controller_config(path: str | os.PathLike[str] | None = None) -> ArbotixConfig:
    """Read an ArbotiX driver YAML (``None``: the shipped one) into an ``ArbotixConfig``.

    A key given twice in one mapping is an error naming both lines (YAML would keep the last).
    """
    text, source = read_config_file(path)
    data = parse_yaml(text, source)
    if data is None:
        raise ControllerConfigError(f"{source}: the file is empty")
    return parse_controller_config(data, source)


def parse_controller_config(data: dict, source: str) -> ArbotixConfig:
    """Validate a parsed ArbotiX driver YAML; ``source`` names it in error messages."""
    if not isinstance(data, Mapping):
        raise ControllerConfigError(
            f"{source}: expected a mapping of driver parameters, got {type(data).__name__}"
        )
    kwargs: dict[str, Any] = {"source": source}
    for key, (attr, check, default) in _DRIVER_KEYS.items():
        kwargs[attr] = check(data.get(key, default), f"{source}: {key}")
    name, controller = _pick_diff_controller(data.get("controllers"), source)
    kwargs["name"] = name
    _warn_unknown_top_level(data, source, name)
    kwargs.update(_parse_controller(controller, f"{source}: controllers.{name}"))
    kwargs.update(_parse_own_section(data.get("smartcar_gym", {}), source))
    motor_keys = (
        "stall_torque_nm", "no_load_speed_rad_s", "pwm_zero", "reflected_inertia_kg_m2",
        "friction_torque_nm",
    )
    kwargs["motor"] = MotorConfig(**{k: kwargs.pop(k) for k in motor_keys if k in kwargs})
    config = ArbotixConfig(**kwargs)
    if config.max_accel == 0:
        warnings.warn(
            f"{source}: controllers.{name}: max_accel = int(accel_limit*ticks_meter/rate) = 0, "
            "so the base can never move in hardware mode (as upstream)",
            stacklevel=2,
        )
    return config


def _warn_unknown_top_level(data: Mapping, source: str, name: str) -> None:
    known = set(_DRIVER_KEYS) | set(_DRIVER_OTHER_KEYS)
    for key in data:
        if key in known:
            continue
        hint = close_hint(str(key), known)
        if key in _CONTROLLER_KEYS:
            hint = f" (a {SUPPORTED_TYPE} key: it belongs under controllers.{name})"
        warnings.warn(f"{source}: unknown top-level key {key!r} ignored{hint}", stacklevel=3)


def _pick_diff_controller(controllers: Any, source: str) -> tuple[str, Mapping]:
    example = f"controllers: {{base_controller: {{type: {SUPPORTED_TYPE}, ...}}}}"
    if controllers is None:
        raise ControllerConfigError(f"{source}: no 'controllers' section; expected {example}")
    if not isinstance(controllers, Mapping):
        raise ControllerConfigError(f"{source}: 'controllers' must be a mapping like {example}")
    found = []
    for name, params in controllers.items():
        where = f"{source}: controllers.{name}"
        if not isinstance(params, Mapping):
            raise ControllerConfigError(
                f"{where}: expected a mapping with a 'type', got {params!r}"
            )
        kind = params.get("type")
        if kind == SUPPORTED_TYPE:
            found.append((str(name), params))
        elif kind in UPSTREAM_OTHER_TYPES:
            warnings.warn(f"{where}: type {kind!r} is not emulated; ignored", stacklevel=3)
        elif kind is None:
            raise ControllerConfigError(f"{where}: no 'type'; expected type: {SUPPORTED_TYPE}")
        else:
            raise ControllerConfigError(
                f"{where}: unknown controller type {kind!r}; smartcar_gym emulates only "
                f"{SUPPORTED_TYPE!r}"
            )
    if not found:
        raise ControllerConfigError(f"{source}: no {SUPPORTED_TYPE} in 'controllers'; expected "
                                    f"{example}")
    if len(found) > 1:
        names = [name for name, _ in found]
        raise ControllerConfigError(f"{source}: more than one {SUPPORTED_TYPE}: {names}; keep one")
    return found[0]


def _parse_controller(params: Mapping, where: str) -> dict[str, Any]:
    for key, (_, _, default) in _CONTROLLER_KEYS.items():
        if default is _REQUIRED and key not in params:
            raise ControllerConfigError(_missing_message(key, params, where))
    known = set(_CONTROLLER_KEYS) | {"type"}
    for key, value in params.items():
        if value is None:
            raise ControllerConfigError(
                f"{where}.{key}: has no value (roslaunch cannot upload a null parameter)"
            )
        if key not in known:
            hint = close_hint(str(key), known)
            warnings.warn(f"{where}: unknown key {key!r} ignored{hint}", stacklevel=3)
    out = {}
    for key, (attr, check, default) in _CONTROLLER_KEYS.items():
        out[attr] = check(params[key], f"{where}.{key}") if key in params else default
    return out


def _missing_message(required: str, params: Mapping, where: str) -> str:
    """Say that ``required`` is missing; point at a key that looks like a mangled form of it."""
    message = (
        f"{where}: required key {required!r} is missing ({_REQUIRED_HELP[required]}; the "
        f"ArbotiX diff_controller has no default and does not start without it)"
    )
    suspect = _mangled_key(required, params)
    if suspect is None:
        return message
    key, value = suspect
    words = str(key).split()
    guess = words[-1] if len(words) > 1 and is_number(words[-1]) else value
    suggestion = f"{required}: {guess if guess is not None else '<value>'}"
    message += (
        f". The key {key!r} (value {value!r}) looks like a mangled {required!r}: did you mean "
        f"`{suggestion}`?"
    )
    if value is None and len(words) > 1:
        message += (
            f" YAML reads `{key}` (no ': ' separator) as one key with a null value; upstream's "
            "roslaunch refuses the null and, without it, the driver logs 'Unrecognized "
            "controller: diff_controller'."
        )
    return message


def _mangled_key(required: str, params: Mapping) -> tuple[Any, Any] | None:
    """The unknown key most likely meant as ``required``: a prefix, a close match or a null."""
    known = set(_CONTROLLER_KEYS) | {"type"}
    candidates = []
    for key, value in params.items():
        if key in known:
            continue
        text = str(key)
        head = text.split()[0] if text.split() else text
        score = 0
        if len(head) >= 3 and required.startswith(head.rstrip(":")):
            score += 2
        if difflib.get_close_matches(head, [required], n=1, cutoff=0.75):
            score += 2
        if value is None:
            score += 1
        if score:
            candidates.append((score, key, value))
    if not candidates:
        return None
    score, key, value = max(candidates, key=lambda item: item[0])
    if score == 1 and sum(1 for item in candidates if item[0] == 1) > 1:
        return None  # several null keys, nothing pointing at this one
    return key, value


def _parse_own_section(section: Any, source: str) -> dict[str, Any]:
    where = f"{source}: smartcar_gym"
    if section is None:
        return {}
    if not isinstance(section, Mapping):
        raise ControllerConfigError(f"{where}: expected a mapping, got {section!r}")
    out: dict[str, Any] = {}
    for name, sub in section.items():
        if name not in _OWN_KEYS:
            raise ControllerConfigError(
                f"{where}: unknown key {name!r}{close_hint(str(name), _OWN_KEYS)}; "
                f"expected some of {sorted(_OWN_KEYS)}"
            )
        keys = _OWN_KEYS[name]
        if sub is None:
            continue
        if not isinstance(sub, Mapping):
            raise ControllerConfigError(f"{where}.{name}: expected a mapping, got {sub!r}")
        for key, value in sub.items():
            if key not in keys:
                raise ControllerConfigError(
                    f"{where}.{name}: unknown key {key!r}{close_hint(str(key), keys)}; "
                    f"expected some of {sorted(keys)}"
                )
            attr, check = keys[key]
            out[attr] = check(value, f"{where}.{name}.{key}")
    return out
