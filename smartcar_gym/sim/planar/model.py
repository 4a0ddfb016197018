"""A robot as the planar engine sees it: what its URDF and its actuation make of a car.

``RobotTables`` reads a URDF (the one the other engines load: ``model.contact.simulated_urdf``)
at zero joint angles: each link's mass, centre of mass and inertia, its collision shapes and
friction, each joint's axis. ``PlanarBody`` (``simulator.py``) lets the robot change masses,
friction and actuation exactly as it does on pybullet; ``build_car`` then turns all of it into
a ``PlanarCar``: the flat sequences the equations of motion take (``dynamics``):

* **degrees of freedom**: the body's x, y, yaw, and one per wheel group. A group is the set of
  joints tied together by gear constraints (``add_gear``: a side's chain), or one wheel joint;
  each joint turns ``sign`` times its group's angle. A joint is a wheel when it is continuous
  (or revolute without limits) and its child link touches the ground with a round shape.
* **contacts**: every collision shape whose lowest point is on the ground (within
  ``GROUND_TOLERANCE_M``). A wheel's round shape rolls with its group; any other shape slides
  (a caster ball fixed to the body: boxes by their bottom corners, spheres and upright
  cylinders by their lowest point, lying cylinders by their two bottom ends).
* **loads**: static, from the centre of mass over the contacts (``dynamics.static_loads``), and
  how moments about the centre of mass move them (``dynamics.load_transfer``): the ground's
  force acting the centre of mass's height below it, and the wheels' spin momentum changing
  (its share ``spin_reaction``).
* **inertia**: the whole robot's mass and yaw inertia about its centre of mass; each group's
  spin inertia is its wheels' inertia about their axles (with the rotor's, which the robot adds
  with ``add_axle_inertia``).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from smartcar_gym.model.contact import link_frictions
from smartcar_gym.model.kinematics import link_frames, rpy_matrix
from smartcar_gym.model.urdf import UrdfRobot, parse_urdf
from smartcar_gym.sim.contracts import BASE
from smartcar_gym.sim.planar.dynamics import load_transfer, static_loads
from smartcar_gym.sim.planar.layout import car_values, contact_values
from smartcar_gym.sim.planar.params import PlanarParams
from smartcar_gym.sim.planar.projection import link_shapes, support_points

GROUND_TOLERANCE_M = 1e-3  # a shape whose lowest point is this close to the ground touches it
_UNSET = object()


@dataclass
class LinkState:
    """What the simulator may change of a link: mass (kg), inertia in its inertial frame
    (3x3, kg m^2) and lateral friction coefficient."""

    mass: float
    inertia: np.ndarray
    friction: float


@functools.lru_cache(maxsize=16)
def parsed(text: str, source: str
           ) -> tuple[UrdfRobot, Mapping[str, float], Mapping[str, np.ndarray]]:
    """A URDF's parse (frozen), its links' frictions and frames (read-only), kept for the
    next body loaded from the same text: an env spawns its robot again every episode."""
    robot = parse_urdf(text, source)
    frames = link_frames(robot)
    for frame in frames.values():
        frame.flags.writeable = False
    return robot, MappingProxyType(link_frictions(text, source)), MappingProxyType(frames)


@dataclass
class RobotTables:
    """A URDF at zero joint angles: links by index (``BASE`` = -1, else the joint's index),
    frames in the base link, joints in document order."""

    robot: UrdfRobot
    joint_names: list[str]
    frames: dict[str, np.ndarray]
    links: dict[int, LinkState] = field(default_factory=dict)

    @classmethod
    def from_text(cls, text: str, source: str) -> RobotTables:
        robot, frictions, frames = parsed(text, source)
        names = list(robot.joints)
        tables = cls(robot, names, dict(frames))
        for index in [BASE, *range(len(names))]:
            link = robot.links[tables.link_name(index)]
            inertia = (np.zeros((3, 3)) if link.inertial is None
                       else np.array(link.inertial.inertia, dtype=float))
            tables.links[index] = LinkState(link.mass, inertia,
                                            frictions.get(link.name, 0.5))
        return tables

    def link_name(self, index: int) -> str:
        return self.robot.base_link if index == BASE else \
            self.robot.joints[self.joint_names[index]].child

    def inertial_pose(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """Centre of mass (3,) and inertial frame rotation (3x3) of a link, base frame."""
        link = self.robot.links[self.link_name(index)]
        frame = self.frames[link.name]
        if link.inertial is None:
            return frame[:3, 3].copy(), frame[:3, :3].copy()
        origin = link.inertial.origin
        rotation = frame[:3, :3] @ rpy_matrix(origin.rpy)
        return frame[:3, :3] @ np.asarray(origin.xyz, float) + frame[:3, 3], rotation

    def axis(self, joint: int) -> np.ndarray:
        """Unit axis of a joint in the base frame."""
        j = self.robot.joints[self.joint_names[joint]]
        a = self.frames[j.child][:3, :3] @ np.asarray(j.axis, dtype=float)
        return a / np.linalg.norm(a)

    def rolls(self, joint: int) -> bool:
        """Whether a joint can turn a wheel for ever (continuous or revolute without limits)."""
        j = self.robot.joints[self.joint_names[joint]]
        if j.type == "continuous":
            return True
        return j.type == "revolute" and (j.lower is None or j.upper is None
                                         or j.lower >= j.upper)


@dataclass(frozen=True)
class Groups:
    """The wheel groups: ``members[g]`` lists ``(joint, sign)``; ``of[joint]`` = (g, sign)."""

    members: tuple[tuple[tuple[int, float], ...], ...]
    of: dict[int, tuple[int, float]]


def wheel_groups(tables: RobotTables, ground_z: float,
                 gears: list[tuple[int, int, float]], driven: set[int]) -> Groups:
    """Joints that roll a wheel on the ground, or are driven or geared, grouped by gears.

    A gear ``(parent, child, ratio)`` holds ``q_parent + ratio * q_child`` constant, so the
    child turns ``-1 / ratio`` times the parent.
    """
    moving = {j for j in range(len(tables.joint_names))
              if tables.rolls(j) and _round_contact(tables, j, ground_z) is not None}
    moving |= driven | {p for p, _, _ in gears} | {c for _, c, _ in gears}
    sign: dict[int, float] = {}
    root: dict[int, int] = {}
    for j in sorted(moving):
        if j not in sign:
            sign[j], root[j] = 1.0, j
            pending = [j]
            while pending:  # walk the gear graph from j
                a = pending.pop()
                for p, c, ratio in gears:
                    for here, there, factor in ((p, c, -1.0 / ratio), (c, p, -ratio)):
                        if here == a and there not in sign:
                            sign[there], root[there] = sign[a] * factor, j
                            pending.append(there)
    roots = sorted(set(root.values()))
    members = tuple(tuple((j, sign[j]) for j in sorted(moving) if root[j] == r) for r in roots)
    of = {j: (g, s) for g, group in enumerate(members) for j, s in group}
    return Groups(members, of)


def _round_contact(tables: RobotTables, joint: int, ground_z: float
                   ) -> tuple[np.ndarray, float] | None:
    """The wheel shape of a joint's child touching the ground: (centre (3,), radius) of its
    first sphere, or cylinder lying with its axis along the joint's, or None."""
    axis = tables.axis(joint)
    for shape in link_shapes(tables.robot, tables.frames, tables.link_name(joint)):
        g = shape.geometry
        if g.type not in ("sphere", "cylinder"):
            continue
        if g.type == "cylinder" and abs(float(shape.rotation[:, 2] @ axis)) < 0.99:
            continue
        centre = shape.centre
        radius = float(g.size[0])
        if abs(centre[2] - radius - ground_z) <= GROUND_TOLERANCE_M:
            return centre, centre[2] - ground_z
    return None


def _sliding_points(tables: RobotTables, index: int, ground_z: float) -> list[np.ndarray]:
    """The points (3,) where a link's collision shapes rest on the ground."""
    return [p for shape in link_shapes(tables.robot, tables.frames, tables.link_name(index))
            for p in support_points(shape) if abs(p[2] - ground_z) <= GROUND_TOLERANCE_M]


@dataclass(frozen=True)
class PlanarCar:
    """A car as ``dynamics.substep`` takes it: ``car`` and ``contacts`` (its rows) in the
    layout ``dynamics`` describes, each contact's wheel group (-1: sliding), the wheel groups'
    joints, and the centre of mass (3,) in the base frame."""

    car: list[float]
    contacts: list[list[float]]
    contact_groups: tuple[int, ...]
    groups: Groups
    com: np.ndarray


@dataclass(frozen=True)
class Actuation:
    """What the robot asked of the joints: gearbox Coulomb friction (a velocity motor held at 0
    with a force limit, N m), gear constraints, and the joints a motor drives."""

    coulomb: dict[int, float]
    gears: list[tuple[int, int, float]]
    driven: set[int]


def build_car(tables: RobotTables, ground_z: float, actuation: Actuation,
              params: PlanarParams, ground_friction: float, gravity_m_s2: float,
              ) -> PlanarCar:
    """The ``PlanarCar`` of a robot whose base link stands ``-ground_z`` m above the ground.

    ValueError when nothing or too little touches the ground, or the robot would tip over.
    """
    groups = wheel_groups(tables, ground_z, actuation.gears, actuation.driven)
    masses, centres, inertias = [], [], []
    for index, link in tables.links.items():
        centre, rotation = tables.inertial_pose(index)
        masses.append(link.mass)
        centres.append(centre)
        inertias.append(rotation @ link.inertia @ rotation.T)
    masses_a = np.array(masses)
    mass = float(masses_a.sum())
    if not mass > 0:
        raise ValueError(f"{tables.robot.name}: the robot has no mass")
    com = (masses_a[:, None] * np.array(centres)).sum(axis=0) / mass
    yaw_inertia = float(sum(i[2, 2] + m * ((c[0] - com[0]) ** 2 + (c[1] - com[1]) ** 2)
                            for m, c, i in zip(masses, centres, inertias, strict=True)))
    points, rolling, bounds, radii = [], [], [], []
    for index in tables.links:
        wheel = None
        if index != BASE and index in groups.of:
            wheel = _round_contact(tables, index, ground_z)
        if wheel is not None:
            centre, radius = wheel
            g, sign = groups.of[index]
            a = tables.axis(index) * sign
            points.append(centre[:2])
            rolling.append((g, -radius * a[1], radius * a[0]))
            radii.append(radius)
        else:
            for p in _sliding_points(tables, index, ground_z):
                points.append(p[:2])
                rolling.append((-1, 0.0, 0.0))
                radii.append(0.0)
        mu = tables.links[index].friction * ground_friction * params.friction_scale
        bounds += [mu] * (len(points) - len(bounds))
    if not points:
        raise ValueError(f"{tables.robot.name}: no collision shape touches the ground")
    balance = com[:2] + np.array([params.load_shift_x, 0.0])
    try:
        loads = static_loads(np.array(points), balance, mass * gravity_m_s2)
    except ValueError as exc:
        if params.load_shift_x == 0.0:
            raise
        low, high = load_shift_range(np.array(points) - com[:2])  # raises if not the shift
        raise ValueError(f"{exc} (planar.load_shift_x {params.load_shift_x:g} m from "
                         f"{params.source}); this robot's contacts allow "
                         f"[{low:.6g}, {high:.6g}] m") from None
    transfer = load_transfer(np.array(points))
    contacts = [contact_values(x=float(p[0] - com[0]), y=float(p[1] - com[1]), roll_x=float(wx),
                               roll_y=float(wy), load=float(load), friction_x=float(mu),
                               friction_y=float(mu * (params.lateral_friction_ratio if g >= 0
                                                      else 1.0)),
                               load_per_pitch=float(lx), load_per_roll=float(ly))
                for p, (g, wx, wy), mu, load, (lx, ly)
                in zip(points, rolling, bounds, loads, transfer, strict=True)]
    group_inertia, coulomb, momentum = [], [], []
    for g, members in enumerate(groups.members):
        spin = 0.0
        along = np.zeros(3)  # the group's angular momentum per rad/s, body frame (N m s)
        for joint, sign in members:
            link = tables.links[joint]
            _, rotation = tables.inertial_pose(joint)
            a = rotation.T @ tables.axis(joint)
            about = float(a @ link.inertia @ a)  # the wheel's inertia about its axle
            spin += sign * sign * about
            along += sign * tables.axis(joint) * about
        momentum.append(along * params.spin_reaction)
        rolling_torque = sum(params.rolling_resistance * load * radius
                             for load, radius, (cg, _, _) in zip(loads, radii, rolling,
                                                                  strict=True) if cg == g)
        gearbox = sum(abs(sign) * actuation.coulomb.get(joint, 0.0) for joint, sign in members)
        group_inertia.append(spin)
        coulomb.append(params.gearbox_friction_scale * gearbox + rolling_torque)
    for g, spin in enumerate(group_inertia):
        if not spin > 0:
            joints = [tables.joint_names[j] for j, _ in groups.members[g]]
            raise ValueError(f"{tables.robot.name}: wheel joints {joints} have no inertia about "
                             "their axles")
    car = car_values(mass=mass, yaw_inertia=yaw_inertia, eps2=params.slip_speed ** 2,
                     eps_w2=params.stiction_speed ** 2, height=float(com[2] - ground_z),
                     inertia=group_inertia, coulomb=coulomb,
                     spin_x=[float(h[0]) for h in momentum],
                     spin_y=[float(h[1]) for h in momentum])
    return PlanarCar(car, contacts, tuple(g for g, _, _ in rolling), groups, com)


def load_shift_range(points: np.ndarray) -> tuple[float, float]:
    """The ``load_shift_x`` values (m) over which ground contacts at ``points`` ((K, 2), m
    from the centre of mass) carry the body: every static load of ``static_loads`` at least
    zero. ValueError (``static_loads``'): they cannot carry it whatever the shift."""
    points = np.asarray(points, dtype=float)
    static_loads(points, np.zeros(2), 1.0)  # too few contacts, on one line, or tipping
    a = np.vstack([np.ones(len(points)), points[:, 0], points[:, 1]])
    gram = a @ a.T
    base = a.T @ np.linalg.solve(gram, np.array([1.0, 0.0, 0.0]))  # the loads at no shift
    per = a.T @ np.linalg.solve(gram, np.array([0.0, 1.0, 0.0]))  # and per metre of it
    low, high = -np.inf, np.inf
    for b, p in zip(base, per, strict=True):
        if p > 1e-12:
            low = max(low, -b / p)
        elif p < -1e-12:
            high = min(high, -b / p)
    return float(low), float(high)
