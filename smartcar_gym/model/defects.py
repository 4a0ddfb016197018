"""Physical defects of a URDF model: misplaced shapes, implausible masses and inertias."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np

from smartcar_gym.model.inertia import expected_inertia, principal_moments
from smartcar_gym.model.kinematics import transform
from smartcar_gym.model.urdf import Joint, Link, Origin, UrdfRobot

DUPLICATED_ORIGIN = "duplicated joint origin"
IMPLAUSIBLE_INERTIA = "implausible inertia"
GEOMETRY_MISMATCH = "geometry mismatch"
NON_POSITIVE_MASS = "non-positive mass"
NOT_POSITIVE_DEFINITE = "non-positive-definite inertia"
NON_PHYSICAL_INERTIA = "non-physical inertia"
# Defects no body can have: a model with one of them left unrepaired is refused by load_model.
ERROR_KINDS = (NON_POSITIVE_MASS, NOT_POSITIVE_DEFINITE, NON_PHYSICAL_INERTIA)

ORIGIN_TOLERANCE_M = 1e-6
INERTIA_FACTOR = 10.0  # a principal moment this many times off the computed one is implausible
# Every body's principal moments obey a + b >= c; this much below c is still taken as rounding
# (a thin plate or disc sits exactly on a + b = c, and files round their numbers).
TRIANGLE_TOLERANCE = 0.01


@dataclass(frozen=True)
class Defect:
    """One finding: ``kind`` (the constants above), model ``element``, message, severity."""

    kind: str
    element: str
    message: str
    severity: Literal["warning", "error"] = "warning"

    def __str__(self) -> str:
        return f"{self.severity}: {self.kind}: {self.element}: {self.message}"


def fmt(values) -> str:
    """Numbers as a compact space-separated string."""
    return " ".join(f"{float(v):.6g}" for v in np.ravel(values))


def parent_joints(robot: UrdfRobot) -> dict[str, Joint]:
    """The joint each non-root link hangs from, by link name."""
    return {j.child: j for j in robot.joints.values()}


def link_origins(link: Link) -> Iterator[tuple[str, Origin]]:
    """(element path, origin) of the link's inertial, collisions and visuals."""
    if link.inertial is not None:
        yield f"{link.name}/inertial", link.inertial.origin
    for kind, shapes in (("collision", link.collisions), ("visual", link.visuals)):
        for i, shape in enumerate(shapes):
            suffix = f"[{i}]" if len(shapes) > 1 else ""
            yield f"{link.name}/{kind}{suffix}", shape.origin


def duplicated_origins(robot: UrdfRobot) -> Iterator[tuple[str, Origin, Joint]]:
    """(element path, origin, joint) where a link's shape repeats its joint's origin."""
    joints = parent_joints(robot)
    for link in robot.links.values():
        joint = joints.get(link.name)
        if joint is None or np.linalg.norm(joint.origin.xyz) <= ORIGIN_TOLERANCE_M:
            continue
        for path, origin in link_origins(link):
            if np.allclose(origin.xyz, joint.origin.xyz, atol=ORIGIN_TOLERANCE_M, rtol=0):
                yield path, origin, joint


def same_rpy(a: Origin, b: Origin) -> bool:
    """Whether two origins have the same rotation (compared as matrices)."""
    return bool(np.allclose(transform(a)[:3, :3], transform(b)[:3, :3], atol=1e-6))


def inertia_problem(link: Link) -> tuple[str, str, np.ndarray | None] | None:
    """(kind, message, computed inertia or None) if the link's inertia is wrong, else None."""
    if link.inertial is None or link.inertial.mass <= 0:
        return None
    given = np.array(link.inertial.inertia)
    moments = principal_moments(given)
    expected = expected_inertia(link)
    if moments[0] <= 0:
        return NOT_POSITIVE_DEFINITE, f"inertia principal moments {fmt(moments)} kg m^2; " \
            "expected all > 0", expected
    a, b, c = moments
    if a + b < c * (1 - TRIANGLE_TOLERANCE):
        return NON_PHYSICAL_INERTIA, (
            f"inertia principal moments {fmt(moments)} kg m^2: {a:.6g} + {b:.6g} < {c:.6g}, "
            "which no mass distribution has; expected each moment at most the sum of the "
            "other two"), expected
    if expected is None:
        return None
    reference = principal_moments(expected)
    ratio = moments / reference
    worst = float(max(ratio.max(), 1 / ratio.min()))
    if worst <= INERTIA_FACTOR:
        return None
    shape = link.collisions[0].geometry
    return IMPLAUSIBLE_INERTIA, (
        f"principal moments {fmt(moments)} kg m^2, but a solid {shape.type} of "
        f"{link.inertial.mass:g} kg with size {fmt(shape.size)} m has {fmt(reference)} "
        f"(up to {worst:.3g}x off, more than {INERTIA_FACTOR:g}x)"
    ), expected


def find_defects(robot: UrdfRobot) -> list[Defect]:
    """All defects of ``robot``, link by link in document order."""
    defects: list[Defect] = []
    duplicated = {}
    for path, origin, joint in duplicated_origins(robot):
        duplicated.setdefault(path.split("/")[0], []).append((path, origin, joint))
    for link in robot.links.values():
        for path, origin, joint in duplicated.get(link.name, []):
            placed = np.round((transform(joint.origin) @ transform(origin))[:3, 3], 4) + 0.0
            repeats_rpy = same_rpy(origin, joint.origin) and any(origin.rpy)
            rpy = f" rpy {fmt(origin.rpy)}" if repeats_rpy else ""
            defects.append(Defect(DUPLICATED_ORIGIN, path, (
                f"origin xyz {fmt(origin.xyz)}{rpy} repeats joint '{joint.name}' origin; the "
                f"link frame is already there, so this puts it at {fmt(placed)} in "
                f"'{joint.parent}' instead of {fmt(joint.origin.xyz)}; expected xyz 0 0 0"
            )))
        if link.inertial is not None and link.inertial.mass <= 0:
            defects.append(Defect(NON_POSITIVE_MASS, f"{link.name}/inertial",
                                  f"mass {link.inertial.mass:g} kg; expected > 0", "error"))
        problem = inertia_problem(link)
        if problem is not None:
            kind, message, _ = problem
            severity = "error" if kind in ERROR_KINDS else "warning"
            defects.append(Defect(kind, f"{link.name}/inertia", message, severity))
        mismatch = geometry_mismatch(link)
        if mismatch is not None:
            defects.append(Defect(GEOMETRY_MISMATCH, f"{link.name}/collision", mismatch))
    return defects


def geometry_mismatch(link: Link) -> str | None:
    """Why the link's collision shapes differ from its visual ones, or None.

    A mesh visual over primitive collisions is the usual, legitimate simplification.
    """
    visual = [s.geometry.type for s in link.visuals]
    collision = [s.geometry.type for s in link.collisions]
    if not visual or not collision or visual == collision or "mesh" in visual:
        return None
    return (f"collision geometry {', '.join(collision)} differs from visual geometry "
            f"{', '.join(visual)}; expected the same shape")
