"""What an engine provides, written once: the ``Simulator`` and ``Body`` protocols.

The robot (``envs.robots.smartcar``), the tasks, the sensors, the envs and the calibration
call an engine's world only through these. An engine's simulator subclasses
``clock.EventClock`` (the integer-ns clock, event sources, named bodies and stepping from
event to event) and adds the physics: loading robots, static and visual bodies, ray casts and
pictures. Its bodies answer ``Body``. Optional capabilities are protocols of their own, which
a caller tests with ``isinstance``: ``Window`` (a world shown in a window, ``gui=True``) and
``ConvergesContacts`` (an iterative contact solver that can be run to convergence). The batch
of N cars a batched vector env steps is ``sim.batch.CarBatch``.

Conventions every engine keeps: SI units; positions (x, y, z) in m; orientations as (x, y, z,
w) quaternions; a body's links addressed by ``BASE`` (the root link) or a joint's index (the
index of the joint's child link, ``Body.joint_index``); a contact's friction the product of
the two bodies' coefficients.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from smartcar_gym.sim.clock import EventSource
from smartcar_gym.sim.rays import RayHits

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
#: the link index of a body's root link (pybullet's convention, which every engine keeps)
BASE = -1


@dataclass(frozen=True)
class LinkDynamics:
    """A link's mass (kg), diagonal inertia about its centre of mass (kg m^2) and friction."""

    mass_kg: float
    inertia_diagonal: Vec3
    lateral_friction: float


@dataclass(frozen=True)
class BoxPart:
    """One box of a composite visual shape: half extents and pose in the shape's frame (m)."""

    half_extents: tuple[float, float, float]
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    rgba: tuple[float, float, float, float]


class Body(Protocol):
    """One body of a world: a robot loaded from a URDF file, the ground, an obstacle or a
    visual-only marker, addressed by its ``name``.

    A robot answers every method. The ground and obstacles (``Simulator.add_static``) answer
    the pose, ``dynamics``/``set_friction`` and the queries; a marker (``add_visual``)
    answers ``link_pose`` and ``set_com_pose`` only.
    """

    name: str

    def joint_index(self, joint: str) -> int:
        """The index of the joint called ``joint``; KeyError naming the body's joints."""
        ...

    # -- state ---------------------------------------------------------------------------------
    def link_pose(self) -> tuple[Vec3, Quat]:
        """Position and orientation of the root link's frame in the world."""
        ...

    def set_link_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport the body so that its root link's frame is at ``position``/``orientation``."""
        ...

    def set_com_pose(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport the body's root centre of mass (a marker: its frame)."""
        ...

    def velocity(self) -> tuple[Vec3, Vec3]:
        """Linear (m/s) and angular (rad/s) velocity of the root link, world frame."""
        ...

    def joint_states(self, joints: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Positions (rad) and velocities (rad/s) of the joints given by index."""
        ...

    def joint_lists(self, joints: Sequence[int]) -> tuple[list[float], list[float]]:
        """``joint_states`` as two lists (the cheaper read)."""
        ...

    def joint_angles(self, joints: Sequence[int]) -> list[float]:
        """Positions (rad) of the joints given by index: the cheapest read (encoders)."""
        ...

    def reset_joint(self, joint: int, angle: float, speed: float) -> None:
        """Set a joint's position and velocity (kinematic motion)."""
        ...

    def contact_points(self, other: Body | None = None) -> list[tuple[int, Vec3]]:
        """Current contacts (with ``other``, or any body) as (link index, position)."""
        ...

    # -- dynamics ------------------------------------------------------------------------------
    def dynamics(self, link: int = BASE) -> LinkDynamics:
        """Mass, inertia and friction of a link."""
        ...

    def set_mass(self, link: int, mass_kg: float, inertia_diagonal: Sequence[float]) -> None:
        """Set a link's mass (kg) and its inertia diagonal (kg m^2, its inertial frame)."""
        ...

    def set_friction(self, link: int, friction: float) -> None:
        """Set a link's lateral (Coulomb) friction coefficient."""
        ...

    def add_axle_inertia(self, link: int, axis: Sequence[float], inertia_kg_m2: float) -> None:
        """Add ``inertia_kg_m2`` about a joint's ``axis`` (a gearmotor's rotor)."""
        ...

    def clear_damping(self, link: int) -> None:
        """No damping on a link but what is set on purpose (no engine default)."""
        ...

    def set_joint_damping(self, joints: Sequence[int], damping: Sequence[float]) -> None:
        """Viscous damping (N m s/rad) per joint, applied at every physics step."""
        ...

    # -- queries -------------------------------------------------------------------------------
    def hide_from_rays(self) -> None:
        """Let ``Simulator.ray_batch`` pass through this body; its collisions are unchanged."""
        ...

    def distance_to(self, other: Body, max_distance_m: float) -> float:
        """The smallest distance (m) between the two bodies' collision shapes at their
        current poses (< 0: overlapping), or ``max_distance_m`` if none is nearer."""
        ...

    # -- actuation -----------------------------------------------------------------------------
    def hold_torques(self, joints: list[int], torques: list[float], key: str = "") -> None:
        """Apply these joint torques (N m) at every physics step until changed (per ``key``)."""
        ...

    def set_velocity_motors(self, joints: Sequence[int], targets: Sequence[float],
                            max_forces: Sequence[float], key: str = "") -> None:
        """Drive the joints toward ``targets`` (rad/s) with at most ``max_forces`` (N m): a
        motor held at speed 0 is a gearbox's Coulomb friction."""
        ...

    def add_gear(self, parent: int, child: int, ratio: float, max_force: float) -> int:
        """A gear between two joints: ``q_parent + ratio * q_child`` stays constant."""
        ...


class Simulator(Protocol):
    """One world of an engine (gravity, a ground plane called ``plane``) and its clock.

    Made by the engine's factory (``sim.engines.Engine.simulator``) with the keywords
    ``max_substep_s`` (the longest physics substep, s), ``gui`` (a window; an engine without
    one refuses True), ``gravity_m_s2`` and ``ground_friction``, plus the env keywords only
    that engine takes (``Engine.kwargs``) and, where ``Engine.skips_drawing``, ``draws``.
    ``clock.EventClock`` implements the clock, the event sources and the named bodies; an
    engine adds the rest.
    """

    #: the engine's name, as ``engine=`` takes it
    engine: str
    max_substep_s: float
    max_substep_ns: int
    #: the time since the last ``reset`` (ns, integer)
    now_ns: int
    #: physics substeps since the last ``reset``
    physics_steps: int
    ground_friction: float

    # -- world ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """A new world of the ground only, the clock at 0; fully deterministic."""
        ...

    def close(self) -> None:
        """Free the world (idempotent)."""
        ...

    @property
    def connected(self) -> bool:
        """Whether the world is still open."""
        ...

    @property
    def scratch_dir(self) -> Path:
        """A folder of this world's own for files the engine reads (removed by ``close``)."""
        ...

    # -- clock and stepping (``clock.EventClock``) ----------------------------------------------
    @property
    def time_s(self) -> float:
        """Simulated time since the last ``reset`` (s)."""
        ...

    @property
    def time_step_s(self) -> float:
        """The physics substep used last (s)."""
        ...

    def add_event_source(self, source: EventSource) -> None:
        """Let ``source`` act at the instants it asks for (until the next ``reset``)."""
        ...

    def settle(self, seconds: float) -> None:
        """Step the physics ``seconds`` before time starts; the clock stays at 0."""
        ...

    def run_for(self, seconds: float, *, physics: bool = True,
                probe: Callable[[float], None] | None = None) -> None:
        """``run_until`` the current time plus ``seconds``."""
        ...

    def run_until(self, end_ns: int, *, physics: bool = True,
                  probe: Callable[[float], None] | None = None) -> None:
        """Advance the clock to ``end_ns``, stepping the physics from event to event
        (``physics=False``: the clock only, for bodies moved kinematically)."""
        ...

    # -- bodies --------------------------------------------------------------------------------
    def body(self, name: str) -> Body:
        """The body called ``name``; KeyError naming the bodies otherwise."""
        ...

    def has_body(self, name: str) -> bool:
        """Whether a body is called ``name``."""
        ...

    def load_urdf(self, name: str, path: str | Path, position: Sequence[float] = (0.0, 0.0, 0.0),
                  yaw: float = 0.0, fixed: bool = False) -> Body:
        """Load a URDF file as body ``name``, its root link at ``position`` heading ``yaw``;
        ``model.ModelError`` naming the file if the engine cannot."""
        ...

    def add_static(self, name: str, shape: str, half_extents: Sequence[float],
                   position: Sequence[float], yaw: float, rgba: Sequence[float],
                   pillar: bool = False) -> Body:
        """A fixed body that collides: a 'box' (``half_extents``) or an upright 'cylinder'
        (radius ``half_extents[0]``, height ``2 * half_extents[2]``) centred on ``position``.
        ``pillar``: a cylinder standing on the ground whose top nothing reaches (BARN's): the
        engine may round its ends beyond its height where that makes contacts and rays
        cheaper (pybullet's capsules); its side stays the cylinder's. ``sim.obstacles.
        add_obstacle`` passes it only when true, so an engine may leave it out."""
        ...

    def add_visual(self, name: str, shape: str, size: Sequence[float], rgba: Sequence[float],
                   position: Sequence[float] = (0.0, 0.0, 0.0)) -> Body:
        """A visual-only marker: 'sphere' (radius,), 'cylinder' (radius, length) or 'box'
        (half extents)."""
        ...

    def add_visual_copies(self, prefix: str, parts: Sequence[BoxPart], count: int,
                          position: Sequence[float]) -> list[Body]:
        """``count`` visual-only markers of one shape made of boxes, named ``prefix0``..."""
        ...

    # -- queries and pictures ------------------------------------------------------------------
    def ray_batch(self, starts: np.ndarray, ends: np.ndarray) -> RayHits:
        """Rays from ``starts`` to ``ends`` (checked (N, 3) arrays; ``rays.cast_rays`` checks
        them): what each hit first, bodies hidden from rays passed through."""
        ...

    def render(self, width: int, height: int, target: Sequence[float], distance: float,
               yaw_deg: float, pitch_deg: float, fov_deg: float = 50.0) -> np.ndarray:
        """An RGB picture (height, width, 3) uint8 from an orbit camera around ``target``."""
        ...


@runtime_checkable
class Window(Protocol):
    """A simulator that can show its world in a window (made with ``gui=True``:
    ``render_mode="human"``). An engine without a window leaves these out, and says why in
    ``Engine.window_unavailable``."""

    #: whether this world has a window (``gui=True``)
    gui: bool

    def building(self) -> AbstractContextManager[None]:
        """A block in which the world is rebuilt: a window that draws from a thread of its own
        pauses, so that it never draws a half-built world."""
        ...

    def point_gui_camera(self, target: Sequence[float], distance: float, yaw_deg: float,
                         pitch_deg: float) -> None:
        """Show the world in the window from this orbit camera (nothing without one)."""
        ...


@runtime_checkable
class ConvergesContacts(Protocol):
    """A simulator whose contact solver iterates, and can be run to convergence."""

    #: whether ``converge_contacts`` is in force (until the next ``reset``)
    contacts_converged: bool

    def converge_contacts(self) -> None:
        """Solve the contacts to convergence until the next ``reset``: a robot that turns
        with any difference between its sides (differential drive) asks for it."""
        ...


def window_of(sim: object) -> Window | None:
    """``sim`` if it has a window open (``gui=True``), else None."""
    return sim if isinstance(sim, Window) and sim.gui else None


def joint_index(body: str, joints: dict[str, int], joint: str) -> int:
    """``joints[joint]`` (a body's joints by name); KeyError naming the body's joints
    otherwise: what every engine's ``Body.joint_index`` answers."""
    try:
        return joints[joint]
    except KeyError:
        raise KeyError(f"body {body!r} has no joint {joint!r}; joints: {sorted(joints)}") from None
