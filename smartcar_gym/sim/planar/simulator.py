"""``PlanarSimulator``: the simulator facade on the planar engine (``sim.contracts``).

The world is flat ground, static obstacles (boxes and upright cylinders) and robots, each a
``PlanarBody``: a rigid body in the plane on its wheel groups (``model.build_car``), stepped by
``dynamics.substep``. The clock and event-driven stepping are ``EventClock``'s, shared with
pybullet and MuJoCo: each interval between events is split into the fewest equal substeps no
longer than ``max_substep_s``. The robot addresses its body exactly as on pybullet (joints by
index, held torques, joint damping, velocity motors held at 0 as gearbox friction, gear
constraints, masses and friction), and the body compiles all of it into the equations of motion
when it is first stepped (again whenever something changes).

One car steps in Python floats (``math.sqrt``), which for one car is several times faster than
numpy; ``batch.PlanarBatch`` steps N cars in arrays with the same function, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.model.errors import ModelError
from smartcar_gym.sim import contracts
from smartcar_gym.sim.clock import EventClock, check_max_substep
from smartcar_gym.sim.contracts import BASE, LinkDynamics
from smartcar_gym.sim.planar import PLANAR_MAX_SUBSTEP_S, PLANAR_SUBSTEP_RANGE_S, dynamics
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
from smartcar_gym.sim.planar.params import PlanarParams, resolve

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
        self.size = tuple(float(v) for v in size)
        self.position = tuple(float(v) for v in position)
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
        """``n`` substeps of ``dt`` s (compiled when numba is installed)."""
        if dynamics.COMPILED:
            car, contacts, groups = self._arrays
            dynamics.run_car(self.state, car, contacts, groups, self._drive_array, dt, n)
            return
        m = self.model
        state, car, contacts, groups, drive = (self.state, m.car, m.contacts, m.contact_groups,
                                               self.drive)
        scratch = new_scratch(len(self.groups.members))
        for _ in range(n):
            substep(state, car, contacts, groups, drive, dt, scratch)

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


class PlanarSimulator(EventClock):
    """A flat world stepped by the planar engine, with the event-driven clock.

    Args: as ``sim.contracts.Simulator`` (``gui`` is refused: the planar engine draws
    ``rgb_array`` pictures only), plus
    ``planar_params``: the model's free parameters (``params.resolve``: None for the shipped
    pybullet fit, "mujoco", a file, a dict or a ``PlanarParams``).
    """

    engine = "planar"

    def __init__(
        self,
        max_substep_s: float = PLANAR_MAX_SUBSTEP_S,
        gui: bool = False,
        gravity_m_s2: float = 9.81,
        ground_friction: float = 1.0,
        planar_params: Any = None,
    ) -> None:
        if gui:
            raise RuntimeError("render_mode='human' opens pybullet's GUI; with engine='planar' "
                               "use render_mode='rgb_array' (a top-down picture)")
        self.max_substep_s = check_max_substep(max_substep_s, "max_substep_s",
                                               PLANAR_SUBSTEP_RANGE_S)
        self.max_substep_ns = round(self.max_substep_s * 1e9)
        self.gui = False
        self.gravity_m_s2 = gravity_m_s2
        self.ground_friction = ground_friction
        self.params: PlanarParams = resolve(planar_params)
        self._scratch = None
        self._closed = False
        self.reset()

    # -- world ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """A new world of flat ground only; the clock restarts. Fully deterministic."""
        if self._closed:
            raise RuntimeError("this PlanarSimulator is closed; make a new one")
        self._restart_clock()
        self.ground = PlanarStatic(self, "plane", "plane")
        self.ground.friction = self.ground_friction
        self._bodies["plane"] = self.ground
        self._robots: list[PlanarBody] = []
        self._dt = self.max_substep_s

    def _changed(self) -> None:
        for robot in getattr(self, "_robots", ()):
            robot._changed()

    def close(self) -> None:
        """Forget the world and remove the scratch folder (idempotent)."""
        self._bodies, self._sources, self._robots = {}, [], []
        self._closed = True
        self._remove_scratch()

    def __getstate__(self) -> None:
        raise TypeError("a Simulator cannot be copied or pickled; make a new Simulator")

    @property
    def connected(self) -> bool:
        return not self._closed

    @property
    def time_step_s(self) -> float:
        """The physics substep used last (s)."""
        return self._dt

    # -- stepping ------------------------------------------------------------------------------
    def _step_physics(self, interval_ns: int, probe: Callable[[float], None] | None) -> None:
        if interval_ns <= 0:
            return
        n, dt = self._substeps(interval_ns)
        self._dt = dt
        robots = self._robots
        for robot in robots:
            robot.compiled()
        if probe is None:
            for robot in robots:  # they do not touch each other: each its whole interval
                robot.run(n, dt)
        else:
            start = self.now_ns
            for i in range(n):
                for robot in robots:
                    robot.run(1, dt)
                probe((start + interval_ns * (i + 1) / n) / 1e9)
        self.physics_steps += n

    # -- bodies --------------------------------------------------------------------------------
    def load_urdf(self, name: str, path: str | Path, position: Sequence[float] = (0.0, 0.0, 0.0),
                  yaw: float = 0.0, fixed: bool = False) -> PlanarBody:
        """Read a URDF file as robot ``name`` with its base link at ``position`` (its height:
        where the ground is below it), heading ``yaw``; ModelError naming the file otherwise."""
        self._check_new_name(name)
        if fixed:
            raise ValueError("the planar engine moves robots in the plane; fixed=True is "
                             "not supported")
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as exc:
            raise ModelError(f"cannot read the URDF: {exc.strerror}", file=Path(path)) from None
        body = PlanarBody(self, name, RobotTables.from_text(text, str(path)), position, yaw)
        self._bodies[name] = body
        self._robots.append(body)
        return body

    def add_static(self, name: str, shape: str, half_extents: Sequence[float],
                   position: Sequence[float], yaw: float, rgba: Sequence[float],
                   pillar: bool = False) -> PlanarStatic:
        """A fixed 'box' or upright 'cylinder' that collides (see pybullet's ``add_static``;
        a ``pillar`` is its circle, as every cylinder)."""
        self._check_new_name(name)
        if shape not in ("box", "cylinder"):
            raise ValueError(f"static shape must be 'box' or 'cylinder', got {shape!r}")
        body = PlanarStatic(self, name, shape, half_extents, position, yaw, rgba)
        self._bodies[name] = body
        return body

    def add_visual(self, name: str, shape: str, size: Sequence[float], rgba: Sequence[float],
                   position: Sequence[float] = (0.0, 0.0, 0.0)) -> PlanarStatic:
        """A visual-only marker ('sphere', 'cylinder' or 'box'), drawn, never simulated."""
        if shape not in ("sphere", "cylinder", "box"):
            raise ValueError(f"unknown marker shape {shape!r}: expected sphere, cylinder or box")
        body = PlanarStatic(self, name, shape, size, position, rgba=rgba, collides=False)
        self._bodies[name] = body
        return body

    def add_visual_copies(self, prefix: str, parts: Sequence[Any], count: int,
                          position: Sequence[float]) -> list[PlanarStatic]:
        """``count`` copies of one visual-only shape made of boxes (``camera.BoxPart``)."""
        bodies = [PlanarStatic(self, f"{prefix}{i}", "parts", (), position, collides=False,
                               parts=parts) for i in range(count)]
        for body in bodies:
            self._bodies[body.name] = body
        return bodies

    def statics(self) -> list[PlanarStatic]:
        """The obstacles (fixed bodies that collide), in the order they were added."""
        return [b for b in self._bodies.values()
                if isinstance(b, PlanarStatic) and b.collides and b.kind in ("box", "cylinder")]

    def markers(self) -> list[PlanarStatic]:
        """The visual-only markers, in the order they were added."""
        return [b for b in self._bodies.values()
                if isinstance(b, PlanarStatic) and not b.collides]

    # -- queries -------------------------------------------------------------------------------
    def ray_batch(self, starts: np.ndarray, ends: np.ndarray):
        """``smartcar_gym.sim.rays.cast_rays`` of checked (N, 3) arrays: exact 2D casts
        against the obstacles' footprints (rays are horizontal)."""
        from smartcar_gym.sim.planar.world import cast_world

        return cast_world(self, starts, ends)

    def distance(self, body: PlanarBody, other: Any, max_distance_m: float) -> float:
        """The smallest distance between a robot's footprint and a static body."""
        from smartcar_gym.sim.planar.world import body_distance

        return body_distance(self, body, other, max_distance_m)

    # -- rendering -----------------------------------------------------------------------------
    def render(self, width: int, height: int, target: Sequence[float], distance: float,
               yaw_deg: float, pitch_deg: float, fov_deg: float = 50.0) -> np.ndarray:
        """A top-down RGB picture (height, width, 3) uint8 centred on ``target``, spanning
        what an orbit camera at ``distance`` would: ground grid, obstacles, robots, markers."""
        from smartcar_gym.sim.planar.render import top_down

        return top_down(self, width, height, target, distance, fov_deg)
