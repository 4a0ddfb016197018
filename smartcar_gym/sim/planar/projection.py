"""A robot's collision shapes on the ground: placed in base_link's frame, and projected.

The one place where the planar engine turns a URDF's collision shapes into ground geometry:

* ``placed_shapes`` / ``link_shapes``: every collision shape with the joints at zero, as a
  ``PlacedShape`` (its link, its geometry, its rotation and centre in base_link's frame);
* ``outline``: a placed shape projected onto the ground plane, a rectangle or a circle with
  its height range: ``footprint`` collects them for ``distance.clearance``, and
  ``render.robot_shapes`` draws them;
* ``support_points``: the points by which a placed shape can rest on the ground, of which
  ``model.build_car`` takes those on the ground as sliding contacts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from smartcar_gym.model.contact import simulated_urdf
from smartcar_gym.model.kinematics import link_frames, rpy_matrix
from smartcar_gym.model.loader import RobotModel
from smartcar_gym.model.urdf import UrdfRobot, parse_urdf
from smartcar_gym.sim.planar.shapes import BOX, CIRCLE, Shapes2D, checked_poses

#: a collision shape's axis counts as vertical / horizontal within this (unit vector component:
#: under a micrometre of difference for shapes under a metre; the projection stays conservative)
AXIS_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class PlacedShape:
    """One collision shape of a robot with its joints at zero: its ``link``, its ``geometry``
    (the URDF's: ``type``, ``size``, ``filename``), and its ``rotation`` (3x3) and ``centre``
    (3,) in base_link's frame (m)."""

    link: str
    geometry: Any
    rotation: np.ndarray
    centre: np.ndarray


def link_shapes(robot: UrdfRobot, frames: dict[str, np.ndarray], link: str) -> list[PlacedShape]:
    """The collision shapes of ``link``, placed with its frame in ``frames`` (``link_frames``)."""
    frame = frames[link]
    return [PlacedShape(link, shape.geometry, frame[:3, :3] @ rpy_matrix(shape.origin.rpy),
                        frame[:3, :3] @ np.asarray(shape.origin.xyz, float) + frame[:3, 3])
            for shape in robot.links[link].collisions]


def placed_shapes(robot: UrdfRobot,
                  frames: dict[str, np.ndarray] | None = None) -> list[PlacedShape]:
    """Every collision shape of ``robot``, link by link in document order (``frames``: its
    ``link_frames``, computed when not given)."""
    frames = link_frames(robot) if frames is None else frames
    return [shape for name in robot.links for shape in link_shapes(robot, frames, name)]


class Outline(NamedTuple):
    """A shape's projection onto the ground: ``kind`` (``BOX`` or ``CIRCLE``), ``centre`` (2,),
    ``yaw`` (rad) and ``half`` extents (a circle's: (r, r)) in base_link's frame (m),
    ``z_range``: its lowest and highest point, and whether it is ``exact`` (False: a bounding
    rectangle of a tilted shape or a mesh's bounding box)."""

    kind: int
    centre: np.ndarray
    yaw: float
    half: tuple[float, float]
    z_range: tuple[float, float]
    exact: bool


def outline(shape: PlacedShape) -> Outline:
    """``shape`` projected onto the ground plane: a sphere -> a circle; a cylinder with a
    vertical axis -> a circle, with a horizontal axis (a wheel) -> the rectangle of its side
    view; a box with a vertical axis -> its horizontal rectangle; a mesh -> its bounding box
    (OBJ and STL files, scaled), then as a box. A box or cylinder tilted otherwise -> the
    smallest rectangle about its projection along one of its projected axes (not ``exact``).
    ValueError naming the link for any other geometry or a mesh that cannot be read."""
    geometry, rotation, origin = shape.geometry, shape.rotation, shape.centre
    if geometry.type == "sphere":
        r = geometry.size[0]
        return Outline(CIRCLE, origin[:2], 0.0, (r, r), (origin[2] - r, origin[2] + r), True)
    if geometry.type == "cylinder":
        r, length = geometry.size
        axis = rotation[:, 2]
        flat = math.hypot(axis[0], axis[1])
        rise = abs(axis[2])
        z = length / 2.0 * rise + r * flat
        z_range = (origin[2] - z, origin[2] + z)
        if flat <= AXIS_TOLERANCE:
            r += length / 2.0 * flat
            return Outline(CIRCLE, origin[:2], 0.0, (r, r), z_range, True)
        along = length / 2.0 * flat + r * rise  # the exact support along the projected axis
        return Outline(BOX, origin[:2], math.atan2(axis[1], axis[0]), (along, r), z_range,
                       rise <= AXIS_TOLERANCE)
    if geometry.type == "box":
        return _outline_box(np.asarray(geometry.size) / 2.0, rotation, origin)
    if geometry.type == "mesh":
        from smartcar_gym.sim.planar.mesh_bounds import mesh_bounds

        low, high = mesh_bounds(geometry.filename, shape.link)
        low, high = low * np.asarray(geometry.size), high * np.asarray(geometry.size)
        low, high = np.minimum(low, high), np.maximum(low, high)  # negative scales
        box = _outline_box((high - low) / 2.0, rotation, origin + rotation @ ((low + high) / 2.0))
        return box._replace(exact=False)
    raise ValueError(f"link {shape.link!r}: collision geometry {geometry.type!r} has no "
                     "footprint")


def _outline_box(half: np.ndarray, rotation: np.ndarray, origin: np.ndarray) -> Outline:
    """A box of ``half`` extents turned by ``rotation``: its projection if one of its axes is
    vertical, else the smallest rectangle about its projection along a projected axis."""
    axes = rotation * half  # columns: the box's half axes
    z = float(np.abs(axes[2]).sum())
    z_range = (origin[2] - z, origin[2] + z)
    flat = np.hypot(rotation[0], rotation[1])
    vertical = flat <= AXIS_TOLERANCE
    best = None
    for i in np.flatnonzero(~vertical):  # the box's (at most three) axes, not cars or beams
        u = rotation[:2, i] / flat[i]
        extents = (float(np.abs(u @ axes[:2]).sum()),
                   float(np.abs(np.array([-u[1], u[0]]) @ axes[:2]).sum()))
        if best is None or extents[0] * extents[1] < best[1][0] * best[1][1] - 1e-15:
            best = (math.atan2(u[1], u[0]), extents)
    yaw, extents = best
    return Outline(BOX, origin[:2], yaw, extents, z_range, bool(vertical.any()))


def support_points(shape: PlacedShape) -> list[np.ndarray]:
    """The points (3,) by which ``shape`` can rest on the ground, base_link's frame: a sphere's
    lowest point, a box's eight corners, an upright cylinder's bottom disc (by its centre), a
    lying cylinder's bottom line (by its two ends); none for a mesh."""
    g, rotation, centre = shape.geometry, shape.rotation, shape.centre
    if g.type == "sphere":
        return [centre - np.array([0.0, 0.0, g.size[0]])]
    if g.type == "box":
        half = np.asarray(g.size, float) / 2.0
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                            for sz in (-1, 1)]) * half
        return list(centre + corners @ rotation.T)
    if g.type == "cylinder":
        radius, length = g.size
        axis = rotation[:, 2]
        ends = [centre + axis * length / 2.0, centre - axis * length / 2.0]
        if abs(axis[2]) > 0.99:  # upright: its bottom disc (by its centre)
            return [min(ends, key=lambda p: p[2])]
        down = np.array([0.0, 0.0, -1.0]) - axis * axis[2]  # lying: the bottom line
        down /= np.linalg.norm(down)
        return [e + down * radius for e in ends]
    return []  # meshes: the planar engine's contacts do not read them


# -- the car's footprint -----------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Footprint:
    """A robot's collision shapes projected onto the ground, in base_link's frame.

    ``shapes`` (N = 1, K shapes); ``links`` names each shape's link; ``z_range`` (K, 2) is each
    shape's lowest and highest point (m, base_link's z); ``exact`` is False where the
    projection is a bounding rectangle (a tilted shape, a mesh's bounding box). ``stack``
    makes one of N cars' footprints (their own wheels): ``shapes`` (N, K), ``z_range``
    (N, K, 2), placed one car per pose.
    """

    shapes: Shapes2D
    links: tuple[str, ...]
    z_range: np.ndarray
    exact: np.ndarray

    @property
    def radius(self) -> float:
        """Radius (m) of the circle about base_link's origin that holds the footprint (every
        car's, for a stack)."""
        local = self.shapes
        return float(np.max(np.hypot(local.centre[..., 0], local.centre[..., 1])
                            + local.bounding_radius()))

    @classmethod
    def stack(cls, footprints: Sequence[Footprint]) -> Footprint:
        """One footprint per car (each of N = 1, the same links in the same order)."""
        first = footprints[0]
        for other in footprints[1:]:
            if other.links != first.links:
                raise ValueError(f"footprints of different shapes ({first.links} and "
                                 f"{other.links}) cannot be stacked")
        s = [f.shapes for f in footprints]
        shapes = Shapes2D(*(np.concatenate([getattr(x, name) for x in s]) for name in
                            ("kind", "centre", "rotation", "half", "valid")))
        return cls(shapes, first.links, np.stack([f.z_range for f in footprints]),
                   np.logical_and.reduce([f.exact for f in footprints]))

    def place(self, poses: Any) -> Shapes2D:
        """``(N, K)``: the footprint with base_link at each of ``poses`` (``(N, 3)``: x, y, yaw
        in m, m, rad)."""
        poses = checked_poses(poses)
        c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
        local = self.shapes
        lx, ly = local.centre[..., 0], local.centre[..., 1]
        centre = np.stack([poses[:, :1] + c * lx - s * ly, poses[:, 1:2] + s * lx + c * ly], -1)
        rc, rs = local.rotation[..., 0], local.rotation[..., 1]
        rotation = np.stack([c * rc - s * rs, s * rc + c * rs], axis=-1)
        n = len(poses)
        return Shapes2D.derived(np.broadcast_to(local.kind, (n, local.num_shapes)), centre,
                                rotation, np.broadcast_to(local.half, (n, local.num_shapes, 2)),
                                np.broadcast_to(local.valid, (n, local.num_shapes)))

    def take(self, rows: np.ndarray) -> Footprint:
        """The footprints of cars ``rows`` of a stack (one footprint: itself)."""
        if self.shapes.num_cars == 1:
            return self
        return Footprint(self.shapes.take(rows, self.shapes.num_shapes), self.links,
                         self.z_range[rows], self.exact)


def footprint(robot: RobotModel | UrdfRobot | str, wheel_contact: str = "sphere") -> Footprint:
    """The footprint of ``robot``: a ``RobotModel`` (as simulated: drive wheels as spheres for
    ``wheel_contact="sphere"``, see ``model.contact.simulated_urdf``), a parsed ``UrdfRobot``,
    or URDF text (mesh file names as the model resolved them); ``wheel_contact`` applies to a
    ``RobotModel`` only.

    Every collision shape with the joints at zero, its ``outline`` on the ground plane (a wheel
    spinning about its axis keeps its projection).
    """
    if isinstance(robot, RobotModel):
        robot = parse_urdf(simulated_urdf(robot, wheel_contact), str(robot.source))
    elif isinstance(robot, str):
        robot = parse_urdf(robot)
    if not isinstance(robot, UrdfRobot):
        raise ValueError(f"robot must be a RobotModel, a UrdfRobot or URDF text, got "
                         f"{type(robot).__name__}")
    placed = placed_shapes(robot)
    rows = [outline(shape) for shape in placed]
    links = [shape.link for shape in placed]
    k = len(rows)
    if k == 0:
        raise ValueError(f"robot {robot.name!r} has no collision shapes: no footprint")
    kind, centre, yaw, half, z_range, exact = (np.array(v) for v in zip(*rows, strict=True))
    shapes = Shapes2D.from_arrays(kind[None], centre[None], yaw[None], half[None])
    return Footprint(shapes, tuple(links), z_range.reshape(k, 2), exact.astype(bool))
