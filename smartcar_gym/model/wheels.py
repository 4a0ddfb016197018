"""Find the drive wheels of a URDF robot from its kinematics and collision shapes."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from smartcar_gym.model.errors import ModelError
from smartcar_gym.model.kinematics import link_frames
from smartcar_gym.model.urdf import Joint, UrdfRobot, Vec3

Side = Literal["left", "right"]
DriveKind = Literal["differential", "skid"]
LATERAL_MIN = 0.9  # |axis_y| in base_link above which a wheel axle counts as lateral


@dataclass(frozen=True)
class Wheel:
    """A drive wheel. Positive joint velocity times ``forward_sign`` rolls the robot forward."""

    joint: str
    link: str
    side: Side
    radius_m: float
    position_m: Vec3  # wheel (child link) origin in the base_link frame
    forward_sign: int


def _radius(robot: UrdfRobot, link: str) -> float | None:
    for shape in robot.links[link].collisions:
        if shape.geometry.radius is not None:
            return shape.geometry.radius
    return None


def _unlimited(joint: Joint) -> bool:
    if joint.type == "continuous":
        return True
    if joint.type != "revolute":
        return False
    return joint.lower is None or joint.upper is None or joint.lower >= joint.upper


def _assess(robot: UrdfRobot, joint: Joint, frames: dict[str, np.ndarray],
            side: Side | None = None) -> Wheel | str:
    """The Wheel on ``joint``, or why it is none (``side`` given: the user's choice)."""
    if not _unlimited(joint):
        limits = "with limits" if joint.type == "revolute" else "joint"
        return f"'{joint.name}' ({joint.type} {limits}; expected continuous or unlimited revolute)"
    frame = frames[joint.child]
    axis = frame[:3, :3] @ np.asarray(joint.axis, dtype=float)
    axis /= np.linalg.norm(axis)
    if abs(axis[1]) <= LATERAL_MIN:
        shown = "(" + ", ".join(f"{v:.3g}" for v in axis + 0.0) + ")"
        return f"'{joint.name}' (axis {shown} in {robot.base_link} is not lateral: |y| <= 0.9)"
    radius = _radius(robot, joint.child)
    if radius is None:
        return (f"'{joint.name}' (child link '{joint.child}' has no cylinder or sphere "
                "collision)")
    position = tuple(float(v) for v in frame[:3, 3])
    if side is None:
        if abs(position[1]) < 1e-9:
            return f"'{joint.name}' (on the centre line y = 0: neither left nor right)"
        side = "left" if position[1] > 0 else "right"
    return Wheel(joint.name, joint.child, side, float(radius), position,  # type: ignore[arg-type]
                 1 if axis[1] > 0 else -1)


OVERRIDES = "{'left': [joint, ...], 'right': [joint, ...]}"


def check_wheel_overrides(wheels: object, *, source: str | None = None,
                          ) -> dict[str, tuple[str, ...]] | None:
    """The ``wheels`` argument as ``{"left": (...), "right": (...)}`` (None stays None).

    ModelError naming the argument and the expected shape if it is anything else.
    """
    if wheels is None:
        return None
    if not isinstance(wheels, Mapping):
        raise ModelError(f"wheels={wheels!r}: expected a dict {OVERRIDES} naming the drive "
                         "wheel joints of each side, or None to find them", file=source)
    if set(wheels) - {"left", "right"} or not wheels.get("left") or not wheels.get("right"):
        raise ModelError(f"wheels={dict(wheels)!r}: expected {OVERRIDES} with at least one "
                         "joint per side", file=source)
    checked = {}
    for side in ("left", "right"):
        joints = wheels[side]
        if (isinstance(joints, str) or not isinstance(joints, Sequence)
                or not all(isinstance(j, str) for j in joints)):
            raise ModelError(f"wheels[{side!r}]={joints!r}: expected a list of joint names, "
                             f"as in {OVERRIDES}", file=source)
        checked[side] = tuple(joints)
    return checked


def _from_overrides(robot: UrdfRobot, wheels: Mapping[str, Sequence[str]],
                    frames: dict[str, np.ndarray], source: str | None) -> tuple[Wheel, ...]:
    overrides = check_wheel_overrides(wheels, source=source)
    names = [n for side in ("left", "right") for n in overrides[side]]
    unknown = [n for n in names if n not in robot.joints]
    if unknown:
        raise ModelError(f"wheels: unknown joint(s) {', '.join(unknown)}; the robot's joints "
                         f"are: {', '.join(robot.joints)}", file=source)
    result = []
    for side in ("left", "right"):
        for name in overrides[side]:
            joint = robot.joints[name]
            wheel = _assess(robot, joint, frames, side)  # type: ignore[arg-type]
            if isinstance(wheel, str):
                raise ModelError(f"wheels: joint {wheel} cannot be a drive wheel", file=source,
                                 line=joint.line)
            result.append(wheel)
    return tuple(result)


def find_wheels(robot: UrdfRobot, overrides: Mapping[str, Sequence[str]] | None = None, *,
                source: str | None = None) -> tuple[Wheel, ...]:
    """Drive wheels: lateral-axis continuous joints with a round collision, or the named ones.

    ``source`` names the URDF in errors; the line is the offending joint's when there is one.
    """
    frames = link_frames(robot)
    if overrides is not None:
        return _from_overrides(robot, overrides, frames, source)
    wheels, rejected, lines = [], [], []
    for joint in robot.joints.values():
        if joint.type == "fixed":
            continue
        found = _assess(robot, joint, frames)
        (rejected if isinstance(found, str) else wheels).append(found)
        if isinstance(found, str):
            lines.append(joint.line)
    sides = {s: [w.joint for w in wheels if w.side == s] for s in ("left", "right")}
    if not sides["left"] or not sides["right"]:
        raise ModelError(
            "no drivable wheels: expected at least one left and one right wheel (a continuous "
            f"or unlimited revolute joint whose axis is lateral in {robot.base_link} and whose "
            "child link has a cylinder or sphere collision); found left: "
            f"{', '.join(sides['left']) or 'none'}; right: {', '.join(sides['right']) or 'none'}"
            f"; rejected: {', '.join(rejected) or ('none' if wheels else 'no movable joints')}"
            "; name the wheel joints "
            "with wheels={'left': [...], 'right': [...]}",
            file=source,
            line=lines[0] if len(lines) == 1 else None,
        )
    return tuple(wheels)


def drive_kind(wheels: Sequence[Wheel]) -> DriveKind:
    """``"differential"``: one drive wheel per side (casters or skids carry the rest), so the
    robot turns freely with any speed difference between its sides; ``"skid"``: a side with two
    or more chained wheels, whose yaw the wheels' sideways friction resists (the smartcar).

    Engine-free, so every physics engine can act on it: a differential base feels a difference
    between its sides that a skid base shrugs off (docs/stepping.md, "Driving straight").
    """
    left = sum(w.side == "left" for w in wheels)
    right = len(wheels) - left
    return "differential" if left == 1 and right == 1 else "skid"
