"""How the drive wheels touch the ground in the simulator: the URDF's shapes or spheres.

A wheel of radius r standing on flat ground touches it at one point, r below its axle, whether
its collision shape is a cylinder or a sphere of radius r. pybullet's cylinder-on-box contact
keeps a manifold of up to four points per wheel (across the tyre's width) and makes a step
about 1.5 times as expensive as one point per wheel, for a car that only ever drives on the
ground plane. ``"sphere"`` swaps each drive wheel's round collision shape for a sphere of the
same radius at the same place; ``"urdf"`` keeps the model's shapes as written.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Literal
from xml.etree import ElementTree

from smartcar_gym.model.loader import RobotModel
from smartcar_gym.model.urdf import parse_xml, serialize_xml

WheelContact = Literal["sphere", "urdf"]
WHEEL_CONTACTS: tuple[str, ...] = ("sphere", "urdf")
#: pybullet's lateral friction of a URDF link that names none
DEFAULT_FRICTION = 0.5


def check_wheel_contact(value: object) -> WheelContact:
    """``value`` if it names a wheel contact model; ValueError naming the choices otherwise."""
    if value not in WHEEL_CONTACTS:
        raise ValueError(f"wheel_contact must be one of {WHEEL_CONTACTS}, got {value!r}")
    return value  # type: ignore[return-value]


def simulated_urdf(model: RobotModel, wheel_contact: WheelContact = "sphere") -> str:
    """The URDF text pybullet loads: ``model.urdf``, with sphere wheels for ``"sphere"``.

    In each drive wheel link the first ``<collision>`` whose shape is a cylinder (the one that
    gave the wheel its radius) becomes a sphere of that radius; its origin, the wheel's other
    collision shapes, its visuals and its inertia are kept.
    """
    check_wheel_contact(wheel_contact)
    if wheel_contact == "urdf":
        return model.urdf
    root = parse_xml(model.urdf, str(model.source))
    changed = False
    for shape in round_wheel_shapes(root, model):
        if shape.tag == "cylinder":
            shape.tag = "sphere"
            shape.attrib = {"radius": shape.get("radius", "")}
            changed = True
    return serialize_xml(root) if changed else model.urdf


def round_wheel_shapes(root: ElementTree.Element,
                       model: RobotModel) -> Iterator[ElementTree.Element]:
    """In each drive wheel link of the parsed URDF ``root``, the shape element (``cylinder`` or
    ``sphere``) of its first round ``<collision>``: the one that gives the wheel its radius."""
    wheel_links = {w.link for w in model.wheels}
    for link in root.findall("link"):
        if link.get("name") not in wheel_links:
            continue
        for collision in link.findall("collision"):
            geometry = collision.find("geometry")
            shape = None if geometry is None else next(iter(geometry), None)
            if shape is not None and shape.tag in ("cylinder", "sphere"):
                yield shape
                break


def link_frictions(text: str, source: str) -> dict[str, float]:
    """Each link's lateral friction coefficient in URDF ``text`` as pybullet reads it: the
    link's ``<contact><lateral_friction value=.../>``, or pybullet's default
    ``DEFAULT_FRICTION``; a contact multiplies the two bodies' coefficients."""
    frictions = {}
    for link in parse_xml(text, source).findall("link"):
        element = link.find("contact/lateral_friction")
        value = DEFAULT_FRICTION if element is None else float(element.get("value", "0.5"))
        frictions[link.get("name", "")] = value
    return frictions
