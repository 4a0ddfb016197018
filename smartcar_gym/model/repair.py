"""Repair the two defects that make a model undrivable, on the URDF text itself.

1. A collision/inertial/visual origin that repeats the joint origin is moved to the link
   origin (its rpy too, when it repeats the joint rpy).
2. An implausible, non-positive-definite or non-physical inertia is replaced by the one computed
   from the link's mass and collision primitive.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

from smartcar_gym.model.defects import (
    DUPLICATED_ORIGIN,
    duplicated_origins,
    fmt,
    inertia_problem,
    same_rpy,
)
from smartcar_gym.model.urdf import (
    INERTIA_ATTRS,
    UrdfRobot,
    parse_urdf,
    parse_xml,
    serialize_xml,
)


@dataclass(frozen=True)
class Repair:
    """One change made to the URDF: defect ``kind``, model ``element``, what changed."""

    kind: str
    element: str
    message: str

    def __str__(self) -> str:
        return f"repaired {self.kind}: {self.element}: {self.message}"


def _part(root: ET.Element, path: str) -> ET.Element:
    """The <inertial>/<collision>/<visual> element at ``link/part[index]``."""
    link_name, part = path.split("/")
    link = next(e for e in root.findall("link") if e.get("name") == link_name)
    tag, _, index = part.partition("[")
    return link.findall(tag)[int(index.rstrip("]") or 0)]


def _repair_origins(root: ET.Element, robot: UrdfRobot) -> list[Repair]:
    repairs = []
    for path, origin, joint in duplicated_origins(robot):
        element = _part(root, path).find("origin")
        element.set("xyz", "0 0 0")
        if same_rpy(origin, joint.origin):
            element.set("rpy", "0 0 0")
        rpy = element.get("rpy", "0 0 0")
        repairs.append(Repair(DUPLICATED_ORIGIN, path, (
            f"origin xyz {fmt(origin.xyz)} rpy {fmt(origin.rpy)} -> xyz 0 0 0 rpy {rpy} "
            f"(it repeated joint '{joint.name}')"
        )))
    return repairs


def _repair_inertias(root: ET.Element, robot: UrdfRobot) -> list[Repair]:
    repairs = []
    for link in robot.links.values():
        problem = inertia_problem(link)
        if problem is None or problem[2] is None:
            continue
        kind, _, computed = problem
        element = _part(root, f"{link.name}/inertial").find("inertia")
        index = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2),
                 "izz": (2, 2)}
        before = " ".join(f"{a}={element.get(a)}" for a in ("ixx", "iyy", "izz"))
        for attr in INERTIA_ATTRS:
            element.set(attr, f"{computed[index[attr]]:.10g}")
        after = " ".join(f"{a}={computed[index[a]]:.4g}" for a in ("ixx", "iyy", "izz"))
        shape = link.collisions[0].geometry
        repairs.append(Repair(kind, f"{link.name}/inertia", (
            f"{before} -> {after} kg m^2 (solid {shape.type} {fmt(shape.size)} m, "
            f"{link.inertial.mass:g} kg)"
        )))
    return repairs


def repair_urdf(text: str, robot: UrdfRobot, source: str) -> tuple[str, tuple[Repair, ...]]:
    """Repaired URDF text (unchanged if nothing to repair) and the repairs made."""
    root = parse_xml(text, source)
    repairs = _repair_origins(root, robot)
    if repairs:  # inertias are computed in the repaired frames
        text = serialize_xml(root)
        robot = parse_urdf(text, source)
        root = parse_xml(text, source)
    inertia_repairs = _repair_inertias(root, robot)
    if inertia_repairs:
        text = serialize_xml(root)
    return text, tuple(repairs + inertia_repairs)
