"""``load_model``: a URDF or xacro robot description as a checked, drivable ``RobotModel``."""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from smartcar_gym.model.defects import Defect, find_defects
from smartcar_gym.model.errors import ModelDefectWarning, ModelError
from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS, PackagePath
from smartcar_gym.model.repair import Repair, repair_urdf
from smartcar_gym.model.urdf import Joint, Link, parse_urdf
from smartcar_gym.model.wheels import Wheel, find_wheels
from smartcar_gym.model.xacro_runner import expand_xacro

SHIPPED_MODEL = SHIPPED_DESCRIPTIONS / "smartcar_description" / "urdf" / "smartcar.urdf.xacro"
RADIUS_TOLERANCE = 0.01  # drive wheels whose radii differ more than this have no common radius


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A loaded robot: final URDF text (after repairs), its tables, drive wheels and findings."""

    urdf: str
    source: Path
    name: str
    base_link: str
    links: dict[str, Link]
    joints: dict[str, Joint]
    wheels: tuple[Wheel, ...]
    defects: tuple[Defect, ...] = ()
    repairs: tuple[Repair, ...] = ()

    @property
    def left_wheels(self) -> tuple[Wheel, ...]:
        """Drive wheels on the left (+y) side."""
        return tuple(w for w in self.wheels if w.side == "left")

    @property
    def right_wheels(self) -> tuple[Wheel, ...]:
        """Drive wheels on the right (-y) side."""
        return tuple(w for w in self.wheels if w.side == "right")

    @property
    def wheel_radius_m(self) -> float:
        """The drive wheels' common radius; ModelError if they differ by more than 1 %."""
        radii = [w.radius_m for w in self.wheels]
        if max(radii) > min(radii) * (1 + RADIUS_TOLERANCE):
            listed = ", ".join(f"{w.joint} {w.radius_m:g} m" for w in self.wheels)
            raise ModelError(f"drive wheels have different radii ({listed}); expected one "
                             "common radius within 1 %", file=self.source)
        return sum(radii) / len(radii)

    @property
    def track_width_m(self) -> float:
        """Distance between the mean left and mean right wheel positions along y."""
        left = [w.position_m[1] for w in self.left_wheels]
        right = [w.position_m[1] for w in self.right_wheels]
        return abs(sum(left) / len(left) - sum(right) / len(right))

    def write_urdf(self, directory: str | os.PathLike) -> Path:
        """Write the final URDF as ``<directory>/<name>.urdf`` (pybullet loads files)."""
        path = Path(directory) / f"{self.name}.urdf"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.urdf, encoding="utf-8")
        return path


def is_xacro(path: Path) -> bool:
    """Whether ``path`` goes through xacro (anything but a ``.urdf`` file)."""
    return path.suffix.lower() != ".urdf"


def load_model(
    path: str | os.PathLike | None = None,
    *,
    package_path: PackagePath = None,
    mappings: Mapping[str, object] | None = None,
    wheels: Mapping[str, Sequence[str]] | None = None,
    strict: bool = False,
    repair: bool = True,
    legacy: bool = True,
) -> RobotModel:
    """Load, check and (by default) repair a URDF/xacro robot; ``path=None``: the shipped car.

    Args:
        path: a ``.urdf`` file (parsed as is) or a ``.xacro`` file (expanded by xacro).
        package_path: folders searched first for ``$(find pkg)`` (then ROS_PACKAGE_PATH).
        mappings: xacro arguments (``<xacro:arg>``), name -> value.
        wheels: drive wheel joints by side, ``{"left": [...], "right": [...]}``; default: found.
        strict: raise ModelError on any defect instead of warning.
        repair: fix duplicated joint origins and implausible inertias (each one warned).
        legacy: upgrade ROS-indigo xacro (unprefixed tags), with a LegacyXacroWarning.
    """
    source = Path(SHIPPED_MODEL if path is None else path).expanduser().resolve()
    if not source.is_file():
        raise FileNotFoundError(f"no such robot description: {source}")
    if is_xacro(source):
        text = expand_xacro(source, mappings=mappings, package_path=package_path, legacy=legacy)
        label = f"{source} (xacro output)"
    else:
        text = source.read_text(encoding="utf-8")
        label = str(source)
    robot = parse_urdf(text, label)
    defects = tuple(find_defects(robot))
    if strict and defects:
        listed = "; ".join(str(d) for d in defects)
        raise ModelError(f"{len(defects)} model defect(s) (strict=True): {listed}", file=source)
    repairs: tuple[Repair, ...] = ()
    if repair and defects:
        text, repairs = repair_urdf(text, robot, label)
        if repairs:
            robot = parse_urdf(text, label)
    repaired = {(r.kind, r.element): r.message for r in repairs}
    for defect in defects:
        fix = repaired.get((defect.kind, defect.element))
        note = f"; repaired: {fix}" if fix else ""
        warnings.warn(f"{source.name}: {defect}{note}", ModelDefectWarning, stacklevel=2)
    return RobotModel(
        urdf=text,
        source=source,
        name=robot.name,
        base_link=robot.base_link,
        links=robot.links,
        joints=robot.joints,
        wheels=find_wheels(robot, wheels),
        defects=defects,
        repairs=repairs,
    )
