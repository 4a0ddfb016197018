"""Parse URDF XML into typed, validated tables of links and joints."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
import xml.parsers.expat
from dataclasses import dataclass, field

from smartcar_gym.model.errors import ModelError, xml_syntax_error
from smartcar_gym.model.legacy import is_call_candidate, legacy_tag_names

Vec3 = tuple[float, float, float]
Matrix3 = tuple[Vec3, Vec3, Vec3]

JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
GEOMETRY_SIZES = {"box": ("size",), "cylinder": ("radius", "length"), "sphere": ("radius",)}
INERTIA_ATTRS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


@dataclass(frozen=True)
class Origin:
    """An ``<origin>``: translation (m) and roll-pitch-yaw (rad)."""

    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Geometry:
    """A shape: box size (x, y, z), cylinder (radius, length), sphere (radius,), mesh scale."""

    type: str
    size: tuple[float, ...]
    filename: str | None = None

    @property
    def radius(self) -> float | None:
        """Radius of a cylinder or sphere, else None."""
        return self.size[0] if self.type in ("cylinder", "sphere") else None


@dataclass(frozen=True)
class Shape:
    """A ``<visual>`` or ``<collision>``: geometry placed by an origin in the link frame."""

    geometry: Geometry
    origin: Origin = Origin()


@dataclass(frozen=True)
class Inertial:
    """Mass (kg), centre-of-mass frame and inertia tensor (kg m^2) in that frame."""

    mass: float
    origin: Origin
    inertia: Matrix3


@dataclass(frozen=True)
class Link:
    """A ``<link>``."""

    name: str
    inertial: Inertial | None = None
    visuals: tuple[Shape, ...] = ()
    collisions: tuple[Shape, ...] = ()
    line: int | None = field(default=None, compare=False)

    @property
    def mass(self) -> float:
        """Mass in kg (0 without ``<inertial>``)."""
        return self.inertial.mass if self.inertial else 0.0


@dataclass(frozen=True)
class Joint:
    """A ``<joint>``; ``lower``/``upper`` are None when the limit does not give them."""

    name: str
    type: str
    parent: str
    child: str
    origin: Origin = Origin()
    axis: Vec3 = (1.0, 0.0, 0.0)
    lower: float | None = None
    upper: float | None = None
    line: int | None = field(default=None, compare=False)


@dataclass(frozen=True)
class UrdfRobot:
    """Links and joints by name (document order) and the single root link."""

    name: str
    links: dict[str, Link]
    joints: dict[str, Joint]
    base_link: str


class _Element(ET.Element):
    """Element that remembers its source line (C Element subclasses get a __dict__)."""

    line: int | None = None


def parse_xml(text: str, source: str) -> ET.Element:
    """Element tree of ``text`` whose elements carry ``.line``; ModelError on bad XML."""
    builder = ET.TreeBuilder(element_factory=_Element)
    parser = xml.parsers.expat.ParserCreate()
    parser.buffer_text = True

    def start(tag: str, attrs: dict[str, str]) -> None:
        builder.start(tag, attrs).line = parser.CurrentLineNumber

    parser.StartElementHandler = start
    parser.EndElementHandler = builder.end
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as exc:
        raise xml_syntax_error(exc, source) from None
    return builder.close()


def serialize_xml(root: ET.Element) -> str:
    """URDF text of an element tree (an XML declaration, the tree, a final newline)."""
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


class _Parser:
    """Reads one URDF document; every error names the source, line and expectation."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, element: ET.Element | None, message: str) -> ModelError:
        return ModelError(message, file=self.source, line=getattr(element, "line", None))

    def attr(self, element: ET.Element, name: str, what: str) -> str:
        value = element.get(name)
        if value is None or not value.strip():
            raise self.error(element, f"{what}: <{element.tag}> lacks required attribute '{name}'")
        return value.strip()

    def numbers(self, element: ET.Element, name: str, count: int, what: str,
                default: str | None = None) -> tuple[float, ...]:
        text = element.get(name, default)
        if text is None:
            raise self.error(element, f"{what}: <{element.tag}> lacks required attribute '{name}'")
        try:
            values = tuple(float(v) for v in text.split())
        except ValueError:
            values = ()
        if len(values) != count or not all(math.isfinite(v) for v in values):
            raise self.error(
                element, f"{what}: <{element.tag} {name}=\"{text}\">: expected {count} number(s)"
            )
        return values

    def origin(self, parent: ET.Element, what: str) -> Origin:
        element = parent.find("origin")
        if element is None:
            return Origin()
        xyz = self.numbers(element, "xyz", 3, what, "0 0 0")
        rpy = self.numbers(element, "rpy", 3, what, "0 0 0")
        return Origin(xyz, rpy)  # type: ignore[arg-type]

    def geometry(self, parent: ET.Element, what: str) -> Geometry:
        holder = parent.find("geometry")
        shapes = list(holder) if holder is not None else []
        if len(shapes) != 1:
            raise self.error(
                holder if holder is not None else parent,
                f"{what}: expected <geometry> with exactly one of <box>, <cylinder>, <sphere>, "
                f"<mesh>, found {len(shapes)}",
            )
        shape = shapes[0]
        if shape.tag == "mesh":
            scale = self.numbers(shape, "scale", 3, what, "1 1 1")
            return Geometry("mesh", scale, self.attr(shape, "filename", what))
        if shape.tag not in GEOMETRY_SIZES:
            raise self.error(shape, f"{what}: unknown geometry <{shape.tag}>; expected <box>, "
                                    "<cylinder>, <sphere> or <mesh>")
        if shape.tag == "box":
            size = self.numbers(shape, "size", 3, what)
        else:
            size = tuple(self.numbers(shape, a, 1, what)[0] for a in GEOMETRY_SIZES[shape.tag])
        if any(v <= 0 for v in size):
            raise self.error(shape, f"{what}: <{shape.tag}> dimensions {size}: expected > 0")
        return Geometry(shape.tag, size)

    def inertial(self, element: ET.Element, what: str) -> Inertial:
        mass = element.find("mass")
        inertia = element.find("inertia")
        if mass is None or inertia is None:
            raise self.error(element, f"{what}: <inertial> needs <mass value=...> and "
                                      "<inertia ixx=... izz=...>")
        value = self.numbers(mass, "value", 1, what)[0]
        i = dict(zip(INERTIA_ATTRS, (self.numbers(inertia, a, 1, what)[0] for a in INERTIA_ATTRS),
                     strict=True))
        tensor = ((i["ixx"], i["ixy"], i["ixz"]), (i["ixy"], i["iyy"], i["iyz"]),
                  (i["ixz"], i["iyz"], i["izz"]))
        return Inertial(value, self.origin(element, what), tensor)

    def link(self, element: ET.Element) -> Link:
        name = self.attr(element, "name", "link")
        what = f"link '{name}'"
        inertial = element.find("inertial")
        return Link(
            name=name,
            inertial=None if inertial is None else self.inertial(inertial, what),
            visuals=tuple(Shape(self.geometry(v, f"{what} <visual>"), self.origin(v, what))
                          for v in element.findall("visual")),
            collisions=tuple(Shape(self.geometry(c, f"{what} <collision>"), self.origin(c, what))
                             for c in element.findall("collision")),
            line=element.line,
        )

    def joint(self, element: ET.Element, links: dict[str, Link]) -> Joint:
        name = self.attr(element, "name", "joint")
        what = f"joint '{name}'"
        kind = self.attr(element, "type", what)
        if kind not in JOINT_TYPES:
            raise self.error(element, f"{what}: type '{kind}'; expected one of "
                                      f"{', '.join(JOINT_TYPES)}")
        ends = {}
        for end in ("parent", "child"):
            tag = element.find(end)
            if tag is None:
                raise self.error(element, f"{what}: missing <{end} link=...>")
            ends[end] = self.attr(tag, "link", what)
            if ends[end] not in links:
                raise self.error(tag, f"{what} names {end} link '{ends[end]}', which does not "
                                      f"exist; expected one of: {', '.join(links)}")
        axis_element = element.find("axis")
        axis = (1.0, 0.0, 0.0) if axis_element is None else self.numbers(
            axis_element, "xyz", 3, what)
        if kind != "fixed" and math.hypot(*axis) < 1e-12:
            raise self.error(axis_element, f"{what}: zero axis; expected a non-zero xyz")
        limit = element.find("limit")
        bounds = [None, None]
        if limit is not None:
            for k, key in enumerate(("lower", "upper")):
                if limit.get(key) is not None:
                    bounds[k] = self.numbers(limit, key, 1, what)[0]
        return Joint(name, kind, ends["parent"], ends["child"], self.origin(element, what),
                     tuple(axis), bounds[0], bounds[1], element.line)  # type: ignore[arg-type]

    def no_links(self, root: ET.Element) -> ModelError:
        tags = [e.tag for e in root.iter()]
        legacy = legacy_tag_names(tags)
        calls = list(dict.fromkeys(e.tag for e in root if is_call_candidate(e.tag)))
        if legacy or calls:
            found = " and ".join(part for part in (
                "unprefixed xacro tags " + ", ".join(f"<{t}>" for t in legacy) if legacy else "",
                "unprefixed macro calls " + ", ".join(f"<{c}/>" for c in calls) if calls else "",
            ) if part)
            return self.error(root, f"robot '{root.get('name', '')}' has no links: the file uses "
                                    f"{found} that today's xacro ignores; let them be upgraded "
                                    "(legacy=True, the default) or write them as <xacro:...>")
        if any(t.startswith("xacro:") for t in tags):
            return self.error(root, "robot has no links: the file holds unexpanded <xacro:...> "
                                    "tags; load it through xacro (a .xacro file name)")
        return self.error(root, "robot has no links: no <link> elements (after xacro "
                                "expansion); expected at least one <link name=...> in <robot>")

    def robot(self, root: ET.Element) -> UrdfRobot:
        if root.tag != "robot":
            raise self.error(root, f"root element is <{root.tag}>; expected <robot>")
        name = self.attr(root, "name", "robot")
        links: dict[str, Link] = {}
        for element in root.findall("link"):
            link = self.link(element)
            if link.name in links:
                raise self.error(element, f"link '{link.name}' is defined twice")
            links[link.name] = link
        if not links:
            raise self.no_links(root)
        joints: dict[str, Joint] = {}
        parents: dict[str, str] = {}
        for element in root.findall("joint"):
            joint = self.joint(element, links)
            if joint.name in joints:
                raise self.error(element, f"joint '{joint.name}' is defined twice")
            if joint.child in parents:
                raise self.error(element, f"link '{joint.child}' is the child of joints "
                                          f"'{parents[joint.child]}' and '{joint.name}'; "
                                          "expected a tree")
            joints[joint.name] = joint
            parents[joint.child] = joint.name
        roots = [n for n in links if n not in parents]
        if len(roots) != 1:
            raise self.error(root, f"expected exactly one root link (a link that is no joint's "
                                   f"child), found {len(roots)}: {', '.join(roots) or 'none'}")
        reached, pending = {roots[0]}, [roots[0]]
        while pending:
            parent = pending.pop()
            for joint in joints.values():
                if joint.parent == parent and joint.child not in reached:
                    reached.add(joint.child)
                    pending.append(joint.child)
        if len(reached) != len(links):
            loose = ", ".join(n for n in links if n not in reached)
            raise self.error(root, f"links {loose} are not connected to root link "
                                   f"'{roots[0]}' (the joints form a loop); expected a tree")
        return UrdfRobot(name, links, joints, roots[0])


def parse_urdf(text: str, source: str = "<string>") -> UrdfRobot:
    """Typed tables of a URDF document; ModelError (file, line, expectation) if invalid."""
    return _Parser(source).robot(parse_xml(text, source))
