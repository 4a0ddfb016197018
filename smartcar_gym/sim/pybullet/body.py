"""pybullet's ``Body`` (``sim.contracts.Body``): one body's poses, joints and dynamics.

Handles are made by ``Simulator.load_urdf`` / ``add_visual``; every pybullet call about one body
goes through here. Actuation that pybullet forgets after a step (joint torques) or scales with
the time step (force-limited motors, gear constraints) is registered with the simulator, which
re-applies it when needed.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from smartcar_gym.sim import contracts
from smartcar_gym.sim.contracts import BASE, LinkDynamics, Quat, Vec3

if TYPE_CHECKING:
    from smartcar_gym.sim.pybullet.simulator import Simulator

__all__ = ["BASE", "Body", "LinkDynamics"]


class Body:
    """One body of a ``Simulator``: ``name``, its pybullet ``uid`` and its joints by name."""

    def __init__(self, sim: Simulator, name: str, uid: int) -> None:
        self.sim = sim
        self.name = name
        self.uid = uid

    @functools.cached_property
    def joints(self) -> dict[str, int]:
        """Joint name -> pybullet joint index (= the index of the joint's child link)."""
        c = self.sim.client
        return {c.getJointInfo(self.uid, i)[1].decode(): i
                for i in range(c.getNumJoints(self.uid))}

    @functools.cached_property
    def _link_to_com(self) -> tuple[Vec3, Quat]:
        # pybullet reports a base pose at its centre of mass; URDF users think in link frames
        info = self.sim.client.getDynamicsInfo(self.uid, BASE)
        return tuple(info[3]), tuple(info[4])

    @functools.cached_property
    def _com_to_link(self) -> tuple[Vec3, Quat]:
        return self.sim.client.invertTransform(*self._link_to_com)

    def joint_index(self, joint: str) -> int:
        """pybullet's index of ``joint``; KeyError naming the body's joints otherwise."""
        return contracts.joint_index(self.name, self.joints, joint)

    def _indices(self, joints: Sequence[str]) -> list[int]:
        return [self.joint_index(j) for j in joints]

    # -- state ---------------------------------------------------------------------------------
    def link_pose(self) -> tuple[Vec3, Quat]:
        """Position and orientation (x, y, z, w) of the base link's frame in the world."""
        c = self.sim.client
        com_pos, com_orn = c.getBasePositionAndOrientation(self.uid)
        pos, orn = c.multiplyTransforms(com_pos, com_orn, *self._com_to_link)
        return tuple(pos), tuple(orn)

    def set_link_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport the body so that its base link's frame is at ``position``/``orientation``."""
        c = self.sim.client
        com = c.multiplyTransforms(list(position), list(orientation), *self._link_to_com)
        c.resetBasePositionAndOrientation(self.uid, com[0], com[1])

    def set_com_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport the body's base centre of mass (pybullet's base frame)."""
        self.sim.client.resetBasePositionAndOrientation(self.uid, list(position),
                                                        list(orientation))

    def velocity(self) -> tuple[Vec3, Vec3]:
        """Linear (m/s) and angular (rad/s) velocity of the base, world frame."""
        linear, angular = self.sim.client.getBaseVelocity(self.uid)
        return tuple(linear), tuple(angular)

    def joint_states(self, joints: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Positions (rad) and velocities (rad/s) of joints given by index (see ``joints``)."""
        states = self._get_joint_states(self.uid, joints)
        return (np.array([s[0] for s in states]), np.array([s[1] for s in states]))

    def joint_lists(self, joints: Sequence[int]) -> tuple[list[float], list[float]]:
        """Positions (rad) and velocities (rad/s) as lists (cheaper than ``joint_states``)."""
        states = self._get_joint_states(self.uid, joints)
        return [s[0] for s in states], [s[1] for s in states]

    def joint_angles(self, joints: Sequence[int]) -> list[float]:
        """Positions (rad) of joints given by index: the cheapest read (encoders)."""
        return [s[0] for s in self._get_joint_states(self.uid, joints)]

    @functools.cached_property
    def _get_joint_states(self):  # bound once: BulletClient builds a partial per access
        return self.sim.client.getJointStates

    def reset_joint(self, joint: int, angle: float, speed: float) -> None:
        """Set a joint's position and velocity (kinematic motion)."""
        self.sim.client.resetJointState(self.uid, joint, angle, speed)

    def contact_points(self, other: Body | None = None) -> list[tuple[int, Vec3]]:
        """Current contacts as (link index, position on this body)."""
        c = self.sim.client
        points = (
            c.getContactPoints(bodyA=self.uid) if other is None
            else c.getContactPoints(bodyA=self.uid, bodyB=other.uid)
        )
        return [(p[3], tuple(p[5])) for p in points]

    # -- dynamics ------------------------------------------------------------------------------
    def dynamics(self, link: int = BASE) -> LinkDynamics:
        """Mass, inertia and friction of a link (``BASE`` or a joint's child link index)."""
        info = self.sim.client.getDynamicsInfo(self.uid, link)
        return LinkDynamics(info[0], tuple(info[2]), info[1])

    def set_mass(self, link: int, mass_kg: float, inertia_diagonal: Sequence[float]) -> None:
        """Set a link's mass (kg) and its inertia diagonal (kg m^2, the link's inertial frame)."""
        self.sim.client.changeDynamics(self.uid, link, mass=mass_kg,
                                       localInertiaDiagonal=list(inertia_diagonal))

    def set_friction(self, link: int, friction: float) -> None:
        """Set a link's lateral (Coulomb) friction coefficient; a contact multiplies the two
        bodies' coefficients."""
        self.sim.client.changeDynamics(self.uid, link, lateralFriction=friction)

    def add_axle_inertia(self, link: int, axis: Sequence[float], inertia_kg_m2: float) -> None:
        """Add ``inertia_kg_m2`` about a joint's ``axis`` (a gearmotor's rotor as the wheel sees
        it): to the component of the link's inertia diagonal the axis points along."""
        values = list(self.dynamics(link).inertia_diagonal)
        values[int(np.argmax(np.abs(axis)))] += inertia_kg_m2
        self.sim.client.changeDynamics(self.uid, link, localInertiaDiagonal=values)

    def clear_damping(self, link: int) -> None:
        """No damping on a link but what is set on purpose: pybullet's default linear and
        angular damping (0.04) off, and the joint's damping (not the base's) 0."""
        values = {"linearDamping": 0.0, "angularDamping": 0.0}
        if link != BASE:
            values["jointDamping"] = 0.0
        self.sim.client.changeDynamics(self.uid, link, **values)

    def set_joint_damping(self, joints: Sequence[int], damping: Sequence[float]) -> None:
        """Viscous damping (N m s/rad) per joint, applied by pybullet every step."""
        c = self.sim.client
        for joint, value in zip(joints, damping, strict=True):
            c.changeDynamics(self.uid, joint, jointDamping=float(value))

    # -- queries -------------------------------------------------------------------------------
    def hide_from_rays(self) -> None:
        """Let ray casts pass through every link of this body; its collisions are unchanged."""
        from smartcar_gym.sim.pybullet.rays import ALL_GROUPS, HIDDEN_GROUP

        client = self.sim.client
        for link in [BASE, *range(client.getNumJoints(self.uid))]:
            client.setCollisionFilterGroupMask(self.uid, link, HIDDEN_GROUP, ALL_GROUPS)

    def distance_to(self, other: Body, max_distance_m: float) -> float:
        """The smallest distance (m) between this body's collision shapes and ``other``'s at
        their current poses (< 0: overlapping), or ``max_distance_m`` if none is nearer."""
        nearest = max_distance_m
        for point in self.sim.client.getClosestPoints(self.uid, other.uid, max_distance_m):
            nearest = min(nearest, point[8])
        return nearest

    # -- actuation -----------------------------------------------------------------------------
    def hold_torques(self, joints: list[int], torques: list[float], key: str = "") -> None:
        """Apply these joint torques (N m) at every physics step until changed."""
        self.sim._hold((self.name, key), self.uid, joints, torques)

    def set_velocity_motors(self, joints: Sequence[int], targets: Sequence[float],
                            max_forces: Sequence[float], key: str = "") -> None:
        """pybullet's velocity motors: drive joints toward ``targets`` with at most ``max_forces``.

        Kept by the simulator and re-sent whenever the time step changes (pybullet stores the
        force as an impulse ``force * dt``).
        """
        self.sim._motor((self.name, key), self.uid, list(joints),
                        [float(t) for t in targets], [float(f) for f in max_forces])

    def add_gear(self, parent: int, child: int, ratio: float, max_force: float) -> int:
        """A gear constraint between two joints: ``q_parent + ratio * q_child`` = constant."""
        return self.sim._gear(self.uid, parent, child, ratio, max_force)
