"""The planar engine's bodies: ``PlanarBody``, a robot with ``Body``'s interface (joints by
index, held torques, joint damping, velocity motors held at 0 as gearbox friction, gear
constraints, masses and friction) that compiles all of it into the equations of motion
(``model.build_car``) when it is first stepped, again whenever something changes; and
``PlanarStatic``, a fixed obstacle (a box or an upright cylinder) or a visual-only marker. Their
``PlanarSimulator`` (``simulator.py``) holds them and runs the clock.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from smartcar_gym.model.errors import ModelError
from smartcar_gym.sim import contracts
from smartcar_gym.sim.contracts import BASE, LinkDynamics
from smartcar_gym.sim.planar import dynamics
from smartcar_gym.sim.planar.dynamics import new_scratch, substep
from smartcar_gym.sim.planar.layout import (
    ANGLE,
    COS,
    CX,
    CY,
    NC,
    POSE,
    SIN,
    VX,
    VY,
    YAW_RATE,
    X,
    Y,
    rest_state,
    speed_row,
    state_size,
)
from smartcar_gym.sim.planar.model import Actuation, Groups, PlanarCar, RobotTables, build_car
from smartcar_gym.sim.planar.params import PlanarParams

if TYPE_CHECKING:
    from smartcar_gym.sim.planar.simulator import PlanarSimulator

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


def yaw_quaternion(c: float, s: float) -> Quat:
    """The (x, y, z, w) quaternion of a turn about z whose cos and sin are ``c``, ``s``."""
    if c > -0.5:
        half_c = math.sqrt((1.0 + c) / 2.0)
        return (0.0, 0.0, s / (2.0 * half_c), half_c)
    half_s = math.copysign(math.sqrt((1.0 - c) / 2.0), s if s != 0.0 else 1.0)
    return (0.0, 0.0, half_s, s / (2.0 * half_s))


def quaternion_yaw(q: Sequence[float]) -> tuple[float, float]:
    """cos and sin of the yaw of an (x, y, z, w) quaternion (its turn about z)."""
    x, y, z, w = q
    c, s = 1.0 - 2.0 * (y * y + z * z), 2.0 * (w * z + x * y)
    n = math.hypot(c, s)
    return (1.0, 0.0) if n == 0 else (c / n, s / n)


def _at_rest(x: float, y: float, c: float, s: float, model: PlanarCar) -> list[float]:
    """The state of ``model`` at rest with its base link at (``x``, ``y``) heading (c, s)."""
    cx, cy = model.com[0], model.com[1]
    return rest_state(x + c * cx - s * cy, y + s * cx + c * cy, c, s, len(model.groups.members))


class PlanarStatic:
    """A fixed body: the ground (``plane``), an obstacle or a visual-only marker."""

    def __init__(self, sim: PlanarSimulator, name: str, kind: str, size: Sequence[float] = (),
                 position: Sequence[float] = (0.0, 0.0, 0.0), yaw: float = 0.0,
                 rgba: Sequence[float] = (0.5, 0.5, 0.5, 1.0), collides: bool = True,
                 parts: Sequence[Any] = ()) -> None:
        self.sim, self.name, self.kind = sim, name, kind
        self.size = tuple(map(float, size))
        self.position = tuple(map(float, position))
        self.orientation: Quat = (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
        self.rgba = tuple(rgba)
        self.collides = collides
        self.parts = tuple(parts)
        self.friction = 1.0
        self.hidden_from_rays = False

    @property
    def yaw(self) -> float:
        c, s = quaternion_yaw(self.orientation)
        return math.atan2(s, c)

    def link_pose(self) -> tuple[Vec3, Quat]:
        return self.position, self.orientation

    def set_com_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Move a marker (obstacles never move)."""
        self.position = tuple(float(v) for v in position)
        self.orientation = tuple(float(v) for v in orientation)

    set_link_pose = set_com_pose

    def dynamics(self, link: int = BASE) -> LinkDynamics:
        return LinkDynamics(0.0, (0.0, 0.0, 0.0), self.friction)

    def set_friction(self, link: int, friction: float) -> None:
        self.friction = float(friction)
        self.sim._changed()

    def hide_from_rays(self) -> None:
        """Let ray casts pass through it; its collisions are unchanged."""
        self.hidden_from_rays = True


class PlanarBody:
    """A robot in a ``PlanarSimulator``, with ``Body``'s interface (joints by index, ``BASE``
    = -1 for the base link)."""

    def __init__(self, sim: PlanarSimulator, name: str, tables: RobotTables,
                 position: Sequence[float], yaw: float) -> None:
        self.sim, self.name, self.tables = sim, name, tables
        self.joints = {joint: i for i, joint in enumerate(tables.joint_names)}
        self.ground_z = -float(position[2])
        self.height = float(position[2])
        self._spawn = (float(position[0]), float(position[1]), math.cos(yaw), math.sin(yaw))
        self._coulomb: dict[str, tuple[list[int], list[float]]] = {}
        self._gears: list[tuple[int, int, float]] = []
        self._held: dict[str, tuple[list[int], list[float]]] = {}
        self._damping: dict[int, float] = {}
        self._fixed_q: dict[int, tuple[float, float]] = {}  # joints outside any wheel group
        self.hidden_from_rays = False
        self.model: PlanarCar | None = None
        self.groups: Groups | None = None
        self.com = np.zeros(3)
        #: the car's state in ``dynamics``' layout: x, y, c, s, vx, vy, w, angles, speeds
        self.state: list[float] | None = None
        #: each wheel group's motor drive torque, then its back-EMF damping
        self.drive: list[float] = []
        self._dirty = True

    # -- compiling -----------------------------------------------------------------------------
    def _changed(self) -> None:
        self._dirty = True

    def compiled(self) -> PlanarCar:
        """The equations of motion of the body as it is set up now (built when changed)."""
        if self._dirty:
            self._compile()
        return self.model

    def _compile(self) -> None:
        try:
            model = self.model_with(self.sim.params)
        except ValueError as exc:
            raise ModelError(f"the planar engine cannot simulate it: {exc}",
                             file=self.tables.robot.name) from None
        ng = len(model.groups.members)
        state = self.state
        if state is None:
            state = _at_rest(*self._spawn, model)
        elif len(state) != state_size(ng):
            raise RuntimeError("the wheel groups changed after the body started moving")
        if dynamics.COMPILED:  # numba's loop takes arrays (the same numbers, bit for bit)
            state = np.array(state, dtype=np.float64)
            self._arrays = (np.array(model.car), np.array(model.contacts).reshape(-1, NC),
                            np.array(model.contact_groups, dtype=np.int64))
        self.model, self.groups, self.com, self.state = model, model.groups, model.com, state
        self._speed_row = speed_row(ng)  # where the groups' speeds start, read every step
        self._dirty = False
        self._drive()

    def model_with(self, params: PlanarParams) -> PlanarCar:
        """The car this body would be with other free parameters (its masses, contacts and
        actuation as they are now): what a batch of candidate models steps in a fit."""
        coulomb: dict[int, float] = {}
        for joints, forces in self._coulomb.values():
            for j, f in zip(joints, forces, strict=True):
                coulomb[j] = coulomb.get(j, 0.0) + f
        driven = {j for joints, _ in self._held.values() for j in joints}
        return build_car(self.tables, self.ground_z,
                         Actuation(coulomb, list(self._gears), driven), params,
                         self.sim.ground.friction, self.sim.gravity_m_s2)

    def spawn_state(self, x: float, y: float, yaw: float) -> list[float]:
        """The state of this car at rest with its base link at (x, y) heading ``yaw``."""
        return _at_rest(x, y, math.cos(yaw), math.sin(yaw), self.compiled())

    def _drive(self) -> None:
        """Each group's motor torque and damping from the joints' held torques and damping."""
        if self._dirty:
            return
        tau = [0.0] * len(self.groups.members)
        for joints, torques in self._held.values():
            for j, t in zip(joints, torques, strict=True):
                if j in self.groups.of:
                    g, sign = self.groups.of[j]
                    tau[g] += sign * t
        damping = [0.0] * len(self.groups.members)
        for j, b in self._damping.items():
            if j in self.groups.of:
                g, sign = self.groups.of[j]
                damping[g] += sign * sign * b
        self.drive = tau + damping  # drive_values' layout, without its check (every frame)
        if dynamics.COMPILED:
            self._drive_array = np.array(self.drive)

    def run(self, n: int, dt: float) -> None:
        """``n`` substeps of ``dt`` s: compiled where numba is installed, but for a
        process's first few (``dynamics.compiled_run``; the same numbers)."""
        if dynamics.compiled_run(n):
            car, contacts, groups = self._arrays
            dynamics.run_car(self.state, car, contacts, groups, self._drive_array, dt, n)
            return
        m = self.model
        array = isinstance(self.state, np.ndarray)  # numba's layout: stepped as floats
        state = self.state.tolist() if array else self.state
        car, contacts, groups, drive = m.car, m.contacts, m.contact_groups, self.drive
        scratch = new_scratch(len(self.groups.members))
        for _ in range(n):
            substep(state, car, contacts, groups, drive, dt, scratch)
        if array:
            self.state[:] = state

    # -- joints --------------------------------------------------------------------------------
    def joint_index(self, joint: str) -> int:
        return contracts.joint_index(self.name, self.joints, joint)

    def _joint(self, j: int) -> tuple[float, float]:
        self.compiled()
        found = self.groups.of.get(j)
        if found is None:
            return self._fixed_q.get(j, (0.0, 0.0))
        g, sign = found
        return sign * self.state[ANGLE + g], sign * self.state[self._speed_row + g]

    def joint_states(self, joints: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Positions (rad) and velocities (rad/s) of joints given by index."""
        q, qd = self.joint_lists(joints)
        return np.array(q), np.array(qd)

    def joint_lists(self, joints: Sequence[int]) -> tuple[list[float], list[float]]:
        pairs = [self._joint(j) for j in joints]
        return [p[0] for p in pairs], [p[1] for p in pairs]

    def joint_angles(self, joints: Sequence[int]) -> list[float]:
        """Positions (rad) of joints given by index: the encoders' read."""
        return [self._joint(j)[0] for j in joints]

    def reset_joint(self, joint: int, angle: float, speed: float) -> None:
        """Set a joint's position and velocity (its whole wheel group turns with it)."""
        self.compiled()
        found = self.groups.of.get(joint)
        if found is None:
            self._fixed_q[joint] = (float(angle), float(speed))
            return
        g, sign = found
        self.state[ANGLE + g] = angle / sign
        self.state[speed_row(len(self.groups.members)) + g] = speed / sign

    # -- pose ----------------------------------------------------------------------------------
    def link_pose(self) -> tuple[Vec3, Quat]:
        """Position and (x, y, z, w) orientation of the base link's frame in the world."""
        self.compiled()
        x, y, c, s = self.state[POSE]
        cx, cy = self.com[0], self.com[1]
        return (x - (c * cx - s * cy), y - (s * cx + c * cy), self.height), yaw_quaternion(c, s)

    def set_link_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport the base link's frame to ``position`` (x, y; the height stays) heading as
        ``orientation``'s yaw."""
        self.compiled()
        c, s = quaternion_yaw(orientation)
        cx, cy = self.com[0], self.com[1]
        body = self.state
        body[X] = float(position[0]) + c * cx - s * cy
        body[Y] = float(position[1]) + s * cx + c * cy
        body[COS], body[SIN] = c, s

    def velocity(self) -> tuple[Vec3, Vec3]:
        """Linear (m/s, of the centre of mass) and angular (rad/s) velocity, world frame."""
        self.compiled()
        body = self.state
        return (body[VX], body[VY], 0.0), (0.0, 0.0, body[YAW_RATE])

    def contact_points(self, other: Any = None) -> list[tuple[int, Vec3]]:
        """The ground contacts as (link index, world position): every contact of the car."""
        model = self.compiled()
        x, y, c, s = self.state[POSE]
        return [(BASE, (x + c * k[CX] - s * k[CY], y + s * k[CX] + c * k[CY], 0.0))
                for k in model.contacts]

    # -- dynamics ------------------------------------------------------------------------------
    def dynamics(self, link: int = BASE) -> LinkDynamics:
        state = self.tables.links[link]
        return LinkDynamics(state.mass, tuple(float(v) for v in np.diag(state.inertia)),
                            state.friction)

    def set_mass(self, link: int, mass_kg: float, inertia_diagonal: Sequence[float]) -> None:
        state = self.tables.links[link]
        state.mass = float(mass_kg)
        state.inertia = np.diag(np.asarray(inertia_diagonal, dtype=float))
        self._changed()

    def set_friction(self, link: int, friction: float) -> None:
        self.tables.links[link].friction = float(friction)
        self._changed()

    def add_axle_inertia(self, link: int, axis: Sequence[float], inertia_kg_m2: float) -> None:
        """Add ``inertia_kg_m2`` about a joint's axis (the rotor): to the inertia diagonal's
        component the axis points along, as pybullet's ``Body`` does."""
        state = self.tables.links[link]
        state.inertia = state.inertia.copy()
        k = int(np.argmax(np.abs(axis)))
        state.inertia[k, k] += inertia_kg_m2
        self._changed()

    @property
    def damped_joints(self) -> tuple[int, ...]:
        """The joints whose damping was set, in the order the body sums them into its wheel
        groups."""
        return tuple(self._damping)

    def clear_damping(self, link: int) -> None:
        """No damping but what is set on purpose (the planar engine adds none of its own)."""
        if link != BASE:
            self._damping[link] = 0.0
            self._drive()

    def set_joint_damping(self, joints: Sequence[int], damping: Sequence[float]) -> None:
        for joint, value in zip(joints, damping, strict=True):
            self._damping[joint] = float(value)
        self._drive()

    # -- actuation -----------------------------------------------------------------------------
    def hold_torques(self, joints: list[int], torques: list[float], key: str = "") -> None:
        """Apply these joint torques (N m) at every substep until changed."""
        new = key not in self._held or set(self._held[key][0]) != set(joints)
        self._held[key] = (list(joints), [float(t) for t in torques])
        if new:
            self._changed()
        else:
            self._drive()

    def set_velocity_motors(self, joints: Sequence[int], targets: Sequence[float],
                            max_forces: Sequence[float], key: str = "") -> None:
        """A velocity motor held at 0 with a force limit: Coulomb friction of that torque."""
        if any(t != 0.0 for t in targets):
            raise ValueError("the planar engine models velocity motors held at 0 (Coulomb "
                             f"friction) only, got targets {list(targets)}")
        self._coulomb[key] = (list(joints), [float(f) for f in max_forces])
        self._changed()

    def add_gear(self, parent: int, child: int, ratio: float, max_force: float) -> int:
        """Tie two joints: ``q_parent + ratio * q_child`` = constant (the chain)."""
        self._gears.append((parent, child, float(ratio)))
        self._changed()
        return len(self._gears) - 1

    # -- queries -------------------------------------------------------------------------------
    def hide_from_rays(self) -> None:
        self.hidden_from_rays = True

    def distance_to(self, other: Any, max_distance_m: float) -> float:
        """The smallest distance (m) between this body's footprint and ``other``'s (< 0:
        overlapping), or ``max_distance_m`` if none is nearer."""
        return self.sim.distance(self, other, max_distance_m)
