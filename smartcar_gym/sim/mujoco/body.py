"""Body handles of a MuJoCo world, addressed like the pybullet ones.

A ``MujocoBody`` is one robot or obstacle: its links are addressed as ``Body`` addresses them
(``BASE`` = -1 for the root link, otherwise the index of a moving joint, which is the index of
its child link), its joints by name. What is fixed at build time (masses, inertias, the rotor
inertia about an axle, the chain between wheels) is written into the world's ``MjSpec``; what
changes while it runs (joint torques and damping, friction, the gearbox's Coulomb friction) is
kept by the simulator and written into the compiled model and data, also after a recompile.

A ``Marker`` is a visual-only shape (the goal, odometry arrows, laser hits): it is not part of
the model, the renderer draws it into the scene.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from smartcar_gym.sim import contracts
from smartcar_gym.sim.contracts import BASE, LinkDynamics
from smartcar_gym.sim.mujoco.model import GROUP_COLLISION, GROUP_HIDDEN, GROUP_WORLD

if TYPE_CHECKING:
    from smartcar_gym.sim.mujoco.simulator import MujocoSimulator

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


def wxyz(q: Sequence[float]) -> np.ndarray:
    """An (x, y, z, w) quaternion as MuJoCo's (w, x, y, z)."""
    return np.array([q[3], q[0], q[1], q[2]], dtype=float)


def xyzw(q: Sequence[float]) -> Quat:
    """MuJoCo's (w, x, y, z) as (x, y, z, w)."""
    return (float(q[1]), float(q[2]), float(q[3]), float(q[0]))


def rotation(q_wxyz: np.ndarray) -> np.ndarray:
    """The 3x3 rotation matrix of a (w, x, y, z) quaternion."""
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(q_wxyz, dtype=float))
    return mat.reshape(3, 3)


class MujocoBody:
    """One body of a ``MujocoSimulator``: ``name``, its links and joints (prefixed ``name/``)."""

    def __init__(self, sim: MujocoSimulator, name: str, root: str, free: bool,
                 friction: float = 1.0, spec_root: mujoco.MjsBody | None = None) -> None:
        self.sim = sim
        self.name = name
        self.free = free
        self._root = root  # the root body's full name in the world spec
        if spec_root is None:
            spec_root = sim.spec.worldbody if root == "world" else sim.spec.body(root)
        self._spec_bodies = [spec_root, *spec_root.find_all(mujoco.mjtObj.mjOBJ_BODY)]
        self._spec_joints = [j for j in spec_root.find_all(mujoco.mjtObj.mjOBJ_JOINT)
                             if j.type in (mujoco.mjtJoint.mjJNT_HINGE,
                                           mujoco.mjtJoint.mjJNT_SLIDE)]
        prefix = f"{name}/"
        #: joint name (as the URDF writes it) -> index
        self.joints: dict[str, int] = {
            j.name.removeprefix(prefix): i for i, j in enumerate(self._spec_joints)}
        #: lateral friction coefficient per link (the root: BASE)
        self.friction: dict[int, float] = {BASE: friction,
                                           **{i: friction for i in range(len(self._spec_joints))}}
        self.hidden = False

    # -- addressing ----------------------------------------------------------------------------
    def joint_index(self, joint: str) -> int:
        """The index of ``joint``; KeyError naming the body's joints otherwise."""
        return contracts.joint_index(self.name, self.joints, joint)

    def _spec_body(self, link: int) -> mujoco.MjsBody:
        return self._spec_bodies[0] if link == BASE else self._spec_joints[link].parent

    @functools.cached_property
    def _ids(self) -> _Ids:
        return _Ids(self)

    def _forget_ids(self) -> None:
        """Called by the simulator after every (re)compile."""
        self.__dict__.pop("_ids", None)

    @property
    def uid(self) -> int:
        """The root body's id in the compiled model (what ``RayHits.body`` reports)."""
        return self._ids.root

    # -- state ---------------------------------------------------------------------------------
    def link_pose(self) -> tuple[Vec3, Quat]:
        """Position and orientation (x, y, z, w) of the base link's frame in the world."""
        ids = self._ids
        if not self.free:
            m = self.sim.model
            return (tuple(float(v) for v in m.body_pos[ids.root]),
                    xyzw(m.body_quat[ids.root]))
        q = self.sim._state()[1][ids.free_q:ids.free_q + 7].tolist()
        return (q[0], q[1], q[2]), (q[4], q[5], q[6], q[3])

    def set_link_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport the body so that its base link's frame is at ``position``/``orientation``."""
        ids = self._ids
        if not self.free:
            raise ValueError(f"body {self.name!r} is fixed: it cannot be moved")
        data = self.sim.data
        data.qpos[ids.free_q:ids.free_q + 3] = position
        data.qpos[ids.free_q + 3:ids.free_q + 7] = wxyz(orientation)
        self.sim._moved()

    def set_com_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport the body's base centre of mass (its inertial frame)."""
        m = self.sim.model
        ipos, iquat = m.body_ipos[self._ids.root], m.body_iquat[self._ids.root]
        inverse = np.zeros(4)
        mujoco.mju_negQuat(inverse, iquat)
        link_q = np.zeros(4)
        mujoco.mju_mulQuat(link_q, wxyz(orientation), inverse)
        link_pos = np.asarray(position, dtype=float) - rotation(link_q) @ ipos
        self.set_link_pose(link_pos, xyzw(link_q))

    def velocity(self) -> tuple[Vec3, Vec3]:
        """Linear velocity of the base's centre of mass (m/s) and its angular velocity (rad/s),
        world frame (pybullet's ``getBaseVelocity``)."""
        if not self.free:
            return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        ids, data = self._ids, self.sim.data
        v = data.qvel[ids.free_v:ids.free_v + 6]  # origin's linear (world), angular (local)
        rot = rotation(data.qpos[ids.free_q + 3:ids.free_q + 7])
        angular = rot @ v[3:]
        linear = v[:3] + np.cross(angular, rot @ self.sim.model.body_ipos[ids.root])
        return tuple(float(x) for x in linear), tuple(float(x) for x in angular)

    def joint_states(self, joints: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Positions (rad) and velocities (rad/s) of joints given by index."""
        qadr, dadr = self._ids.addresses(joints)
        _, qpos, qvel, _ = self.sim._state()
        return qpos[qadr], qvel[dadr]

    def joint_lists(self, joints: Sequence[int]) -> tuple[list[float], list[float]]:
        """Positions (rad) and velocities (rad/s) as lists."""
        position, velocity = self.joint_states(joints)
        return position.tolist(), velocity.tolist()

    def joint_angles(self, joints: Sequence[int]) -> list[float]:
        """Positions (rad) of joints given by index: the cheapest read (encoders)."""
        qadr = self._ids.addresses(joints)[0]
        return self.sim._state()[1][qadr].tolist()

    def reset_joint(self, joint: int, angle: float, speed: float) -> None:
        """Set a joint's position and velocity (kinematic motion)."""
        ids, data = self._ids, self.sim.data
        data.qpos[ids.qadr[joint]] = angle
        data.qvel[ids.dadr[joint]] = speed
        self.sim._moved()

    def contact_points(self, other: MujocoBody | None = None) -> list[tuple[int, Vec3]]:
        """Current contacts as (link index, contact position)."""
        ids, m, data = self._ids, self.sim.model, self.sim.data
        root = m.body_rootid
        found = []
        for contact in data.contact[:data.ncon]:
            for mine, theirs in ((contact.geom1, contact.geom2), (contact.geom2, contact.geom1)):
                body = m.geom_bodyid[mine]
                if root[body] != ids.root or body == 0:
                    continue
                if other is not None and root[m.geom_bodyid[theirs]] != other.uid:
                    continue
                found.append((ids.link_of_body.get(int(body), BASE),
                              tuple(float(x) for x in contact.pos)))
        return found

    # -- dynamics ------------------------------------------------------------------------------
    def dynamics(self, link: int = BASE) -> LinkDynamics:
        """Mass, inertia diagonal and friction of a link (``BASE`` or a joint index)."""
        b = self._spec_body(link)
        return LinkDynamics(float(b.mass), tuple(float(v) for v in _diagonal(b)),
                            self.friction[link])

    def set_mass(self, link: int, mass_kg: float, inertia_diagonal: Sequence[float]) -> None:
        """Set a link's mass (kg) and inertia diagonal (kg m^2); products of inertia scale with
        the diagonal."""
        b = self._spec_body(link)
        old = _diagonal(b)
        scale = sum(inertia_diagonal) / sum(old) if sum(old) > 0 else 1.0
        b.mass = float(mass_kg)
        if b.inertia[0] == 0 and not math.isnan(b.fullinertia[0]):
            b.fullinertia = [*inertia_diagonal, *(v * scale for v in b.fullinertia[3:])]
        else:
            b.inertia = list(inertia_diagonal)
        self.sim._changed()

    def set_friction(self, link: int, friction: float) -> None:
        """Set a link's lateral friction coefficient (a contact multiplies the two bodies')."""
        self.friction[link] = float(friction)
        self.sim._friction_changed()

    def add_axle_inertia(self, link: int, axis: Sequence[float], inertia_kg_m2: float) -> None:
        """Add ``inertia_kg_m2`` about a joint's axis: MuJoCo's joint ``armature``."""
        joint = self._spec_joints[link]
        joint.armature = float(joint.armature) + float(inertia_kg_m2)
        self.sim._changed()

    def clear_damping(self, link: int) -> None:
        """No joint damping but what is set on purpose (MuJoCo has no default body damping)."""
        if link != BASE:
            joint = self._spec_joints[link]
            # a number before MuJoCo 3.5, an array (polynomial damping) since
            joint.damping = 0.0 if np.ndim(joint.damping) == 0 else [0.0] * len(joint.damping)
            self.sim._damping.pop((self.name, link), None)
            self.sim._changed()

    def set_joint_damping(self, joints: Sequence[int], damping: Sequence[float]) -> None:
        """Viscous damping (N m s/rad) per joint (MuJoCo integrates it implicitly)."""
        self.sim._set_damping(self, joints, damping)

    # -- queries -------------------------------------------------------------------------------
    def hide_from_rays(self) -> None:
        """Let ray casts pass through this body; its collisions are unchanged."""
        self.hidden = True
        for b in self._spec_bodies:
            for geom in b.geoms:
                if geom.group == GROUP_COLLISION:
                    geom.group = GROUP_HIDDEN
        if self.sim.model is not None:
            m = self.sim.model
            for g in self._ids.collision_geoms:
                m.geom_group[g] = GROUP_HIDDEN

    def distance_to(self, other: MujocoBody, max_distance_m: float) -> float:
        """The smallest distance (m) between this body's collision shapes and ``other``'s at
        their current poses (< 0: overlapping), or ``max_distance_m`` if none is nearer."""
        m, data = self.sim.model, self.sim.kinematics()
        nearest = max_distance_m
        for g1 in self._ids.collision_geoms:
            for g2 in other._ids.collision_geoms:
                nearest = min(nearest, mujoco.mj_geomDistance(m, data, int(g1), int(g2),
                                                              max_distance_m, None))
        return float(nearest)

    # -- actuation -----------------------------------------------------------------------------
    def hold_torques(self, joints: list[int], torques: list[float], key: str = "") -> None:
        """Apply these joint torques (N m) at every physics step until changed."""
        self.sim._hold((self.name, key), self, joints, torques)

    def set_velocity_motors(self, joints: Sequence[int], targets: Sequence[float],
                            max_forces: Sequence[float], key: str = "") -> None:
        """Hold joints at speed 0 with at most ``max_forces`` (N m): MuJoCo's joint
        ``frictionloss``, a Coulomb friction. Only target speeds of 0 have this meaning."""
        if any(float(t) != 0.0 for t in targets):
            raise ValueError(f"the MuJoCo engine holds joints at speed 0 only (Coulomb "
                             f"friction), got target speeds {list(targets)}")
        for joint, force in zip(joints, max_forces, strict=True):
            self.sim._frictionloss[(self.name, int(joint))] = float(force)
        self.sim._changed()

    def add_gear(self, parent: int, child: int, ratio: float, max_force: float) -> int:
        """Couple two joints: ``q_parent + ratio * q_child`` = constant (a joint equality;
        ``max_force`` is pybullet's and has no MuJoCo counterpart: the coupling is stiff)."""
        spec = self.sim.spec
        equality = spec.add_equality(
            type=mujoco.mjtEq.mjEQ_JOINT, name1=self._spec_joints[parent].name,
            name2=self._spec_joints[child].name)
        equality.data[:5] = [0.0, -float(ratio), 0.0, 0.0, 0.0]
        self.sim._changed()
        return len(spec.equalities) - 1


class _Ids:
    """A body's ids and addresses in the compiled model (rebuilt after each compile)."""

    def __init__(self, body: MujocoBody) -> None:
        m = body.sim.model_compiled()
        self.root = m.body(body._root).id
        joints = [m.joint(j.name).id for j in body._spec_joints]
        self.qadr = np.array([m.jnt_qposadr[j] for j in joints], dtype=int)
        self.dadr = np.array([m.jnt_dofadr[j] for j in joints], dtype=int)
        self.link_of_body = {int(m.jnt_bodyid[j]): i for i, j in enumerate(joints)}
        bodies = [b for b in range(m.nbody) if m.body_rootid[b] == self.root and b != 0]
        self.collision_geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] in bodies
                                and m.geom_group[g] in (GROUP_COLLISION, GROUP_HIDDEN,
                                                        GROUP_WORLD)]
        self.geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] in bodies]
        self._addresses: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}
        free = [j for j in range(m.njnt) if m.jnt_bodyid[j] == self.root
                and m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
        self.free_q = int(m.jnt_qposadr[free[0]]) if free else -1
        self.free_v = int(m.jnt_dofadr[free[0]]) if free else -1


    def addresses(self, joints: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """The qpos and dof addresses of joints given by index (kept per list of joints: the
        robot reads the same ones at every PID frame)."""
        key = tuple(joints)
        found = self._addresses.get(key)
        if found is None:
            found = self._addresses[key] = (self.qadr[list(key)], self.dadr[list(key)])
        return found


def _diagonal(body: mujoco.MjsBody) -> list[float]:
    if body.inertia[0] == 0 and not math.isnan(body.fullinertia[0]):
        return [float(v) for v in body.fullinertia[:3]]
    return [float(v) for v in body.inertia]


class Marker:
    """A visual-only shape drawn into rendered pictures: boxes, a sphere or a cylinder.

    ``parts`` are (MuJoCo geom type, size, local position, local (w, x, y, z), rgba).
    """

    def __init__(self, name: str, parts: list[tuple[int, np.ndarray, np.ndarray, np.ndarray,
                                                    np.ndarray]],
                 position: Sequence[float]) -> None:
        self.name = name
        self.parts = parts
        self.position = np.asarray(position, dtype=float)
        self.orientation = np.array([1.0, 0.0, 0.0, 0.0])

    def set_com_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Move the marker (its frame)."""
        self.position = np.asarray(position, dtype=float)
        self.orientation = wxyz(orientation)

    set_link_pose = set_com_pose

    def link_pose(self) -> tuple[Vec3, Quat]:
        return tuple(float(v) for v in self.position), xyzw(self.orientation)
