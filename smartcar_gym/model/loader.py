"""``load_model``: a URDF or xacro robot description as a checked, drivable ``RobotModel``."""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from smartcar_gym.model.defects import Defect, find_defects
from smartcar_gym.model.errors import ModelDefectWarning, ModelError, read_utf8
from smartcar_gym.model.meshes import Locator, resolve_meshes
from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS, PackagePath
from smartcar_gym.model.repair import Repair, repair_urdf
from smartcar_gym.model.urdf import Joint, Link, parse_urdf
from smartcar_gym.model.wheels import Wheel, find_wheels
from smartcar_gym.model.xacro_runner import Expansion, expand_xacro, locate_line

SHIPPED_MODEL = SHIPPED_DESCRIPTIONS / "smartcar_description" / "urdf" / "smartcar.urdf.xacro"
RADIUS_TOLERANCE = 0.01  # drive wheels whose radii differ more than this have no common radius


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A loaded robot: final URDF text (after repairs), its tables, drive wheels and findings.

    ``packages`` holds what each ``$(find pkg)`` and ``package://pkg`` resolved to.
    """

    urdf: str
    source: Path
    name: str
    base_link: str
    links: dict[str, Link]
    joints: dict[str, Joint]
    wheels: tuple[Wheel, ...]
    defects: tuple[Defect, ...] = ()
    repairs: tuple[Repair, ...] = ()
    packages: dict[str, Path] = field(default_factory=dict)

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

    def write_urdf(self, directory: str | os.PathLike, urdf: str | None = None) -> Path:
        """Write the final URDF as ``<directory>/<name>.urdf`` (pybullet loads files).

        ``urdf``: a variant of the text to write instead (see ``simulated_urdf``).
        """
        path = Path(directory) / f"{self.name}.urdf"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.urdf if urdf is None else urdf, encoding="utf-8")
        return path


def is_xacro(path: Path) -> bool:
    """Whether ``path`` goes through xacro (anything but a ``.urdf`` file)."""
    return path.suffix.lower() != ".urdf"


def _read(source: Path, *, mappings: Mapping[str, object] | None, package_path: PackagePath,
          legacy: bool) -> tuple[str, str, Expansion | None]:
    """(URDF text, label naming it in errors, xacro expansion or None for a .urdf file)."""
    if not is_xacro(source):
        return read_utf8(source), str(source), None
    expansion = expand_xacro(source, mappings=mappings, package_path=package_path,
                             legacy=legacy)
    return expansion.text, f"{source} (xacro output)", expansion


def _mesh_locator(label: str, expansion: Expansion | None) -> Locator:
    """Where a mesh filename is written: the xacro file holding it, else the URDF text line."""

    def locate(filename: str, line: int | None) -> tuple[str, int | None]:
        for file in expansion.files if expansion else ():
            found = locate_line(file, filename)
            if found is not None:
                return file, found
        return label, line

    return locate


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
        package_path: folders searched first for ``$(find pkg)`` and ``package://pkg``; then
            ROS_PACKAGE_PATH, the folders enclosing the asking file (closest first), and last
            the shipped descriptions.
        mappings: xacro arguments (``<xacro:arg>``), name -> value.
        wheels: drive wheel joints by side, ``{"left": [...], "right": [...]}``; default: found.
        strict: raise ModelError on any defect instead of warning.
        repair: fix duplicated joint origins and implausible inertias (each one warned).
        legacy: upgrade ROS-indigo xacro (unprefixed tags), with a LegacyXacroWarning.
    """
    source = Path(SHIPPED_MODEL if path is None else path).expanduser().resolve()
    if not source.is_file():
        raise FileNotFoundError(f"no such robot description: {source}")
    text, label, expansion = _read(source, mappings=mappings, package_path=package_path,
                                   legacy=legacy)
    robot = parse_urdf(text, label)
    resolved, mesh_packages = resolve_meshes(text, label, base_dir=source.parent,
                                             package_path=package_path,
                                             locate=_mesh_locator(label, expansion))
    if resolved != text:
        text, robot = resolved, parse_urdf(resolved, label)
    packages = dict(expansion.packages) if expansion else {}
    packages.update((k, v) for k, v in mesh_packages.items() if k not in packages)
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
        wheels=find_wheels(robot, wheels, source=label),
        defects=defects,
        repairs=repairs,
        packages=packages,
    )
