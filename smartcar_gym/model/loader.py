"""``load_model``: a URDF or xacro robot description as a checked, drivable ``RobotModel``."""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from smartcar_gym.model.defects import NON_POSITIVE_MASS, Defect, find_defects, inertia_problem
from smartcar_gym.model.errors import ModelDefectWarning, ModelError, read_utf8
from smartcar_gym.model.meshes import Locator, resolve_meshes
from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS, PackagePath, check_package_path
from smartcar_gym.model.repair import Repair, repair_urdf
from smartcar_gym.model.urdf import Joint, Link, UrdfRobot, parse_urdf
from smartcar_gym.model.wheels import (
    DriveKind,
    Wheel,
    check_wheel_overrides,
    drive_kind,
    find_wheels,
)
from smartcar_gym.model.xacro_runner import Expansion, expand_xacro, locate_line

SHIPPED_MODEL = SHIPPED_DESCRIPTIONS / "smartcar_description" / "urdf" / "smartcar.urdf.xacro"
RADIUS_TOLERANCE = 0.01  # drive wheels whose radii differ more than this have no common radius
EXPECTED_FILE = "a .urdf file, or a xacro file (.urdf.xacro, .xacro)"


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
    def errors(self) -> tuple[Defect, ...]:
        """Defects that make the model non-physical and were not repaired (``load_model``
        refuses a model with any; ``smartcar-model check`` calls it FAILED)."""
        repaired = {(r.kind, r.element) for r in self.repairs}
        return tuple(d for d in self.defects
                     if d.severity == "error" and (d.kind, d.element) not in repaired)

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
    def drive_kind(self) -> DriveKind:
        """``"differential"`` (one drive wheel per side) or ``"skid"`` (see ``drive_kind``)."""
        return drive_kind(self.wheels)

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


def _locator(label: str, expansion: Expansion | None) -> Locator:
    """Where a text (a mesh filename, a link tag) is written: the xacro file holding it, else
    the URDF text line."""

    def locate(needle: str, line: int | None) -> tuple[str, int | None]:
        for file in expansion.files if expansion else ():
            found = locate_line(file, needle)
            if found is not None:
                return file, found
        return label, line

    return locate


def _descriptions_in(folder: Path) -> list[str]:
    """The .urdf/.xacro files in ``folder`` and in its ``urdf/`` subfolder (a ROS package)."""
    found = []
    for sub in (folder, folder / "urdf"):
        if sub.is_dir():
            found += sorted(str(f.relative_to(folder)) for f in sub.iterdir()
                            if f.is_file() and f.name.lower().endswith((".urdf", ".xacro")))
    return found


def check_path(path: object) -> Path:
    """The description file ``path`` names (None: the shipped car), resolved; an error saying
    what was wrong otherwise: not a path, empty, a directory (listing what it holds), missing."""
    if path is None:
        return Path(SHIPPED_MODEL).resolve()
    if not isinstance(path, str | os.PathLike):
        raise TypeError(f"path={path!r}: expected the path (str or os.PathLike) of {EXPECTED_FILE}"
                        ", or None for the shipped smartcar")
    if not str(os.fspath(path)).strip():
        raise ModelError(f"robot description path is empty ({os.fspath(path)!r}); expected the "
                         f"path of {EXPECTED_FILE}, or None for the shipped smartcar")
    source = Path(path).expanduser().resolve()
    if source.is_dir():
        found = _descriptions_in(source)
        held = (f"it holds {', '.join(found[:8])}{', ...' if len(found) > 8 else ''}" if found
                else "it holds no .urdf or .xacro file"
                + (" (nor does its urdf/ folder)" if (source / "urdf").is_dir() else ""))
        raise IsADirectoryError(f"{source} is a directory, not a robot description; expected "
                                f"{EXPECTED_FILE}; {held}")
    if not source.is_file():
        raise FileNotFoundError(f"no such robot description: {source}")
    return source


def _non_physical(errors: Sequence[Defect], robot: UrdfRobot, locate: Locator) -> ModelError:
    """The ModelError for a model with unrepaired error defects: each link, value, and why."""
    parts = []
    for defect in errors:
        link = robot.links[defect.element.split("/")[0]]
        note = ""
        if defect.kind != NON_POSITIVE_MASS:
            problem = inertia_problem(link)
            computable = problem is not None and problem[2] is not None
            note = (" (repair=True replaces it with the inertia of its collision shape)"
                    if computable else " (not repairable: an inertia is computed only for a "
                    "link with one box, cylinder or sphere collision)")
        parts.append(f"link '{link.name}': {defect.kind}: {defect.message}{note}")
    first = robot.links[errors[0].element.split("/")[0]]
    file, line = locate(f'<link name="{first.name}"', first.line)
    count = f"{len(errors)} errors" if len(errors) > 1 else "1 error"
    return ModelError(f"non-physical model, cannot be simulated ({count}; `smartcar-model "
                      f"check` lists every defect): {'; '.join(parts)}", file=file, line=line)


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
            the shipped descriptions (which a shipped file searches first: the shipped model's
            includes never come from ROS_PACKAGE_PATH).
        mappings: xacro arguments (``<xacro:arg>``), name -> value.
        wheels: drive wheel joints by side, ``{"left": [...], "right": [...]}``; default: found.
        strict: raise ModelError on any defect instead of warning.
        repair: fix duplicated joint origins and implausible inertias (each one warned).
        legacy: upgrade ROS-indigo xacro (unprefixed tags), with a LegacyXacroWarning.

    A non-physical model (a link's mass <= 0, an inertia that is not positive definite or
    breaks the triangle inequality, and not repaired) is a ModelError naming the file, the link
    and the value: simulated, it explodes. Other defects are warned (ModelDefectWarning).
    """
    return _load(path, package_path=package_path, mappings=mappings, wheels=wheels,
                 strict=strict, repair=repair, legacy=legacy, keep_errors=False)


def inspect_model(
    path: str | os.PathLike | None = None,
    *,
    package_path: PackagePath = None,
    mappings: Mapping[str, object] | None = None,
    wheels: Mapping[str, Sequence[str]] | None = None,
    repair: bool = True,
    legacy: bool = True,
) -> RobotModel:
    """``load_model`` that returns a non-physical model (see ``RobotModel.errors``) instead of
    raising, for reports (``smartcar-model``); do not simulate a model with errors."""
    return _load(path, package_path=package_path, mappings=mappings, wheels=wheels,
                 strict=False, repair=repair, legacy=legacy, keep_errors=True)


def _load(path: object, *, package_path: object, mappings: object, wheels: object,
          strict: bool, repair: bool, legacy: bool, keep_errors: bool) -> RobotModel:
    source = check_path(path)
    package_path = check_package_path(package_path)
    overrides = check_wheel_overrides(wheels)
    if mappings is not None and not isinstance(mappings, Mapping):
        raise ModelError(f"mappings={mappings!r}: expected a dict of xacro arguments "
                         "{name: value}, or None")
    text, label, expansion = _read(source, mappings=mappings, package_path=package_path,
                                   legacy=legacy)
    robot = parse_urdf(text, label)
    locate = _locator(label, expansion)
    resolved, mesh_packages = resolve_meshes(text, label, base_dir=source.parent,
                                             package_path=package_path, locate=locate)
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
    errors = [d for d in defects if d.severity == "error" and (d.kind, d.element) not in repaired]
    refused = errors and not keep_errors
    for defect in defects:
        if refused and defect in errors:
            continue  # said by the ModelError below
        fix = repaired.get((defect.kind, defect.element))
        note = f"; repaired: {fix}" if fix else ""
        warnings.warn(f"{source.name}: {defect}{note}", ModelDefectWarning, stacklevel=3)
    if refused:
        raise _non_physical(errors, robot, locate)
    return RobotModel(
        urdf=text,
        source=source,
        name=robot.name,
        base_link=robot.base_link,
        links=robot.links,
        joints=robot.joints,
        wheels=find_wheels(robot, overrides, source=label),
        defects=defects,
        repairs=repairs,
        packages=packages,
    )
