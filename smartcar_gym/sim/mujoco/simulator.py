"""``MujocoSimulator``: the simulator facade on MuJoCo, with pybullet's ``Simulator`` interface.

The world is an ``MjSpec`` (a ground plane, then robots and obstacles as they are added) that
is compiled when the physics or a query first needs it, and recompiled, keeping the state
(``MjSpec.recompile``), when something is added later (the Nav obstacles after the car has
settled). The clock and event-driven stepping are ``EventClock``'s, shared with pybullet: each
interval between events is split into the fewest equal substeps no longer than
``max_substep_s`` and stepped with one ``mj_step(model, data, nstep)`` call.

MuJoCo keeps what it is told (``qfrc_applied``, ``dof_damping``) until it is changed, so held
torques are written once, not before every substep as pybullet needs; they, the joint damping,
the gearboxes' Coulomb friction (``dof_frictionloss``) and the friction coefficients are kept
here as well and written again into every recompiled model. Contacts: the robot's geoms decide
a contact's friction (``priority``), set to the product of the two bodies' coefficients as
pybullet multiplies them; ``CONTACT_SOLREF`` makes the ground stiffer than MuJoCo's default so
that a 25 mm wheel sinks about 0.1 mm (at the default 20 ms time constant it sank 1 mm and the
car drove 4 % slower than the same wheel speeds on pybullet).
"""

from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import mujoco
import numpy as np

from smartcar_gym.sim.clock import DEFAULT_MAX_SUBSTEP_S, EventClock, check_max_substep
from smartcar_gym.sim.contracts import BASE, BoxPart
from smartcar_gym.sim.mujoco import mjlog
from smartcar_gym.sim.mujoco.body import Marker, MujocoBody, wxyz
from smartcar_gym.sim.mujoco.model import (
    CONTACT_SOLIMP,
    CONTACT_SOLREF,
    DEFAULT_FRICTION,
    GROUP_WORLD,
    car_spec,
    has_visuals,
    link_frictions,
)
from smartcar_gym.sim.mujoco.rays import cast
from smartcar_gym.sim.rays import RayHits

IMPRATIO = 10.0
CONVERGED_TOLERANCE = 1e-12  # converge_contacts: the Newton solver's tolerance
mjlog.install()  # MuJoCo's warnings come here, not into MUJOCO_LOG.TXT
_SHAPES = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
           "sphere": mujoco.mjtGeom.mjGEOM_SPHERE}


class MujocoSimulator(EventClock):
    """A MuJoCo world (gravity, a ground plane) with the event-driven clock.

    Args: as ``sim.contracts.Simulator``. ``gui`` opens MuJoCo's own viewer
    (``window.Window``) at the first ``point_gui_camera``; without a display it is refused in
    one line, as pybullet's GUI is.
    """

    engine = "mujoco"

    def __init__(
        self,
        max_substep_s: float = DEFAULT_MAX_SUBSTEP_S,
        gui: bool = False,
        gravity_m_s2: float = 9.81,
        ground_friction: float = 1.0,
    ) -> None:
        self.gui = False
        if gui:
            from smartcar_gym.sim.mujoco.window import start_glfw

            start_glfw()
            self.gui = True
        self.max_substep_s = check_max_substep(max_substep_s)
        self.max_substep_ns = round(self.max_substep_s * 1e9)
        self.window = None
        self.gravity_m_s2 = gravity_m_s2
        self.ground_friction = ground_friction
        self._scratch = None
        self._renderer = None
        self._closed = False
        self.model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None
        self.reset()

    # -- world ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """A new world of a ground plane only; the clock restarts. Fully deterministic."""
        if self._closed:
            raise RuntimeError("this MujocoSimulator is closed; make a new one")
        self._restart_clock()
        #: whether ``converge_contacts`` is in force (until the next ``reset``)
        self.contacts_converged = False
        spec = mujoco.MjSpec()
        spec.modelname = "smartcar_gym"
        spec.option.timestep = self.max_substep_s
        spec.option.gravity = [0.0, 0.0, -self.gravity_m_s2]
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        # elliptic friction cones, friction 10 x harder than the normal force: a skid-steer turn
        # then slips as on pybullet (pyramidal cones at impratio 1 spun 17 % faster at 1 rad/s)
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        spec.option.impratio = IMPRATIO
        # no island discovery: a world of one robot on static ground has one island, which
        # MuJoCo would find again at every step (a tenth of a step here); the solution is the
        # same bit for bit (tests/test_mujoco_rollout.py)
        spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_ISLAND
        spec.visual.global_.offwidth = 640
        spec.visual.global_.offheight = 480
        checker = spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                                   builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                                   rgb1=[0.94, 0.94, 0.94], rgb2=[0.63, 0.72, 0.86],
                                   width=64, height=64)
        material = spec.add_material(name="grid", texrepeat=[50.0, 50.0])
        material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = checker.name
        spec.worldbody.add_geom(name="plane", type=mujoco.mjtGeom.mjGEOM_PLANE,
                                size=[50.0, 50.0, 0.1], material="grid", group=GROUP_WORLD,
                                condim=3, solref=CONTACT_SOLREF, solimp=CONTACT_SOLIMP)
        spec.worldbody.add_light(pos=[0.0, 0.0, 5.0], dir=[0.0, 0.0, -1.0],
                                 diffuse=[0.7, 0.7, 0.7])
        self.spec = spec
        self._close_renderer()
        self.model, self._data = None, None
        self._views = None
        self._dirty = True
        self._stale = True  # positions of geoms (xpos) older than qpos
        self._held: dict[tuple[str, str], tuple[MujocoBody, list[int], list[float]]] = {}
        self._damping: dict[tuple[str, int], float] = {}
        self._frictionloss: dict[tuple[str, int], float] = {}
        self._markers: list[Marker] = []
        self._dt = self.max_substep_s
        self._bodies["plane"] = MujocoBody(self, "plane", "world", free=False,
                                           friction=self.ground_friction)

    def converge_contacts(self) -> None:
        """Solve the contacts to a tight tolerance until the next ``reset``.

        The counterpart of pybullet's ``Simulator.converge_contacts``, which a differential-drive
        robot asks for when it spawns: MuJoCo's Newton solver already iterates until converged,
        to ``CONVERGED_TOLERANCE`` here (MuJoCo's default: 1e-8).
        """
        self.spec.option.tolerance = CONVERGED_TOLERANCE
        self._changed()
        self.contacts_converged = True

    @contextlib.contextmanager
    def building(self) -> Iterator[None]:
        """Nothing to pause (``contracts.Window``): MuJoCo's viewer draws only in
        ``point_gui_camera``, on the caller's thread, never while the world is rebuilt."""
        yield

    def close(self) -> None:
        """Close the viewer; free the model, the data, the renderer and the scratch folder
        (idempotent)."""
        self._close_window()
        self._close_renderer()
        self.model, self._data, self.spec, self._views = None, None, None, None
        self._bodies, self._sources, self._held, self._markers = {}, [], {}, []
        self._closed = True
        self._remove_scratch()

    def __getstate__(self) -> None:
        raise TypeError("a Simulator cannot be copied or pickled; make a new Simulator")

    @property
    def connected(self) -> bool:
        return not self._closed

    # -- compiling -----------------------------------------------------------------------------
    def _changed(self) -> None:
        """The spec changed: compile again before the next step or query."""
        self._dirty = True

    def _moved(self) -> None:
        self._stale = True

    def _state(self) -> tuple[mujoco.MjOption, np.ndarray, np.ndarray, np.ndarray]:
        """The model's ``opt`` and the data's ``qpos``, ``qvel`` and ``qfrc_applied`` (compiling
        the spec first if it changed)."""
        if self._dirty:
            self._compile()
        return self._views

    def model_compiled(self) -> mujoco.MjModel:
        """The compiled model (compiling the spec first if it changed)."""
        if self._dirty:
            self._compile()
        return self.model

    @property
    def data(self) -> mujoco.MjData:
        """The world's ``MjData`` (compiling the spec first if it changed)."""
        if self._dirty:
            self._compile()
        return self._data

    def _compile(self) -> None:
        if self._closed:
            raise RuntimeError("this MujocoSimulator is closed; make a new one")
        if self.model is None:
            self.model = self.spec.compile()
            self._data = mujoco.MjData(self.model)
        else:
            self.model, self._data = self.spec.recompile(self.model, self._data)
        self._dirty = False
        self._stale = True
        self._close_renderer()
        # the arrays read and written at every PID frame, fetched once per compile (each
        # attribute of MjModel/MjData makes a new Python object: up to a microsecond a read)
        self._views = (self.model.opt, self._data.qpos, self._data.qvel, self._data.qfrc_applied)
        self.model.opt.timestep = self._dt
        for body in self._bodies.values():
            if isinstance(body, MujocoBody):
                body._forget_ids()
        self._write_runtime()

    def _write_runtime(self) -> None:
        """Write what the simulator keeps (torques, damping, friction) into model and data."""
        if self._dirty or self.model is None:
            return
        m, d = self.model, self._data
        bodies = self._bodies
        for (name, joint), value in self._damping.items():
            m.dof_damping[bodies[name]._ids.dadr[joint]] = value
        for (name, joint), value in self._frictionloss.items():
            m.dof_frictionloss[bodies[name]._ids.dadr[joint]] = value
        for body, joints, torques in self._held.values():
            d.qfrc_applied[body._ids.addresses(joints)[1]] = torques
        self._write_friction()

    def _friction_changed(self) -> None:
        if not self._dirty and self.model is not None:
            self._write_friction()

    def _write_friction(self) -> None:
        m = self.model
        ground = self._bodies["plane"].friction[BASE]
        m.geom_friction[0, 0] = ground  # the plane is the world's first geom
        for body in self._bodies.values():
            if not isinstance(body, MujocoBody) or body.name == "plane":
                continue
            ids = body._ids
            for geom in ids.geoms:
                link = ids.link_of_body.get(int(m.geom_bodyid[geom]), BASE)
                m.geom_friction[geom, 0] = body.friction.get(link, body.friction[BASE]) * ground

    # -- stepping ------------------------------------------------------------------------------
    def _step_physics(self, interval_ns: int, probe: Callable[[float], None] | None) -> None:
        """Step ``interval_ns`` in the fewest equal substeps no longer than ``max_substep_s``."""
        if interval_ns <= 0:
            return
        n, dt = self._substeps(interval_ns)
        if self._dirty:
            self._compile()
        m, d = self.model, self._data
        if dt != self._dt:
            self._views[0].timestep = dt  # m.opt
            self._dt = dt
        if probe is None:
            unstable = mjlog.step(m, d, n)
        else:
            start, unstable = self.now_ns, []
            for i in range(n):
                unstable += mjlog.step(m, d)
                probe((start + interval_ns * (i + 1) / n) / 1e9)
        self._stale = True
        self.physics_steps += n
        if unstable:
            self._report(unstable)

    def _report(self, unstable: list[mjlog.Instability]) -> None:
        """Each instability MuJoCo met in this world as one warning naming the free bodies'
        state then (what MuJoCo would have written into the working folder)."""
        bodies = [(b.name, b._ids.free_q, b._ids.free_v) for b in self._bodies.values()
                  if isinstance(b, MujocoBody) and b.free]
        for event in unstable:
            warnings.warn(mjlog.describe(event, bodies), mjlog.MujocoWarning, stacklevel=4)

    @property
    def time_step_s(self) -> float:
        """The physics step used last (s)."""
        return self._dt

    def kinematics(self) -> mujoco.MjData:
        """The data with every geom's pose computed from the current positions (after a step,
        MuJoCo's geom poses are those before it)."""
        d = self.data
        if self._stale:
            mujoco.mj_kinematics(self.model, d)
            self._stale = False
        return d

    # -- what the simulator keeps applying (used by MujocoBody) --------------------------------
    def _hold(self, key: tuple[str, str], body: MujocoBody, joints: list[int],
              torques: list[float]) -> None:
        self._held[key] = (body, joints, torques)
        if not self._dirty and self.model is not None:
            self._views[3][body._ids.addresses(joints)[1]] = torques  # qfrc_applied

    def _set_damping(self, body: MujocoBody, joints: Sequence[int],
                     damping: Sequence[float]) -> None:
        live = not self._dirty and self.model is not None
        for joint, value in zip(joints, damping, strict=True):
            self._damping[(body.name, joint)] = float(value)
            if live:
                self.model.dof_damping[body._ids.dadr[joint]] = value

    # -- bodies --------------------------------------------------------------------------------
    def load_urdf(
        self,
        name: str,
        path: str | Path,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        yaw: float = 0.0,
        fixed: bool = False,
    ) -> MujocoBody:
        """Compile a URDF file with MuJoCo's importer and add it as body ``name`` with its
        link frame at ``position``, heading ``yaw``; ModelError naming the file otherwise."""
        self._check_new_name(name)
        robot = car_spec(path, free=not fixed)
        root = robot.worldbody.first_body().name
        frame = self.spec.worldbody.add_frame(
            pos=[float(v) for v in position],
            quat=[math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)])
        self.spec.attach(robot, prefix=f"{name}/", frame=frame)
        self._visuals = has_visuals(robot)
        body = MujocoBody(self, name, f"{name}/{root}", free=not fixed)
        frictions = link_frictions(path)
        body.friction[BASE] = frictions.get(root, DEFAULT_FRICTION)
        for index in body.joints.values():
            link = body._spec_joints[index].parent.name.removeprefix(f"{name}/")
            body.friction[index] = frictions.get(link, DEFAULT_FRICTION)
        self._bodies[name] = body
        self._changed()
        return body

    def add_static(self, name: str, shape: str, half_extents: Sequence[float],
                   position: Sequence[float], yaw: float, rgba: Sequence[float],
                   pillar: bool = False) -> MujocoBody:
        """A fixed 'box' or upright 'cylinder' that collides (see pybullet's ``add_static``;
        a ``pillar`` stays a cylinder: MuJoCo's rays and contacts on it are analytic)."""
        self._check_new_name(name)
        spec_body = self.spec.worldbody.add_body(
            name=name, pos=[float(v) for v in position],
            quat=[math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)])
        size = list(half_extents) if shape == "box" else [half_extents[0], half_extents[2], 0.0]
        spec_body.add_geom(type=_SHAPES[shape], size=size, rgba=list(rgba), group=GROUP_WORLD,
                           condim=3)
        body = MujocoBody(self, name, name, free=False, spec_root=spec_body)
        self._bodies[name] = body
        self._changed()
        return body

    def add_visual(self, name: str, shape: str, size: Sequence[float], rgba: Sequence[float],
                   position: Sequence[float] = (0.0, 0.0, 0.0)) -> Marker:
        """A visual-only marker: 'sphere' (radius,), 'cylinder' (radius, length) or 'box'
        (half extents); drawn into pictures, never simulated."""
        if shape not in _SHAPES:
            raise ValueError(f"unknown marker shape {shape!r}: expected sphere, cylinder or box")
        if shape == "sphere":
            dims = [size[0], size[0], size[0]]
        elif shape == "cylinder":
            dims = [size[0], size[0], size[1] / 2.0]
        else:
            dims = list(size)
        part = (int(_SHAPES[shape]), np.array(dims, dtype=float), np.zeros(3),
                np.array([1.0, 0.0, 0.0, 0.0]), np.asarray(rgba, dtype=np.float32))
        marker = Marker(name, [part], position)
        self._markers.append(marker)
        self._bodies[name] = marker
        return marker

    def add_visual_copies(self, prefix: str, parts: Sequence[BoxPart], count: int,
                          position: Sequence[float]) -> list[Marker]:
        """``count`` copies of one visual-only shape made of boxes."""
        shape = [(int(mujoco.mjtGeom.mjGEOM_BOX), np.array(p.half_extents, dtype=float),
                  np.array(p.position, dtype=float), wxyz(p.orientation),
                  np.asarray(p.rgba, dtype=np.float32)) for p in parts]
        markers = [Marker(f"{prefix}{i}", shape, position) for i in range(count)]
        for marker in markers:
            self._markers.append(marker)
            self._bodies[marker.name] = marker
        return markers

    # -- queries -------------------------------------------------------------------------------
    def ray_batch(self, starts: np.ndarray, ends: np.ndarray) -> RayHits:
        """``smartcar_gym.sim.rays.cast_rays`` of checked (N, 3) arrays (``rays.cast``: one
        ``mj_multiRay`` from a common start); bodies hidden from rays are passed through."""
        return cast(self.model_compiled(), self.kinematics(), starts, ends)

    # -- rendering -----------------------------------------------------------------------------
    def render(self, width: int, height: int, target: Sequence[float], distance: float,
               yaw_deg: float, pitch_deg: float, fov_deg: float = 50.0) -> np.ndarray:
        """An RGB image (height, width, 3) uint8 from an orbit camera (MuJoCo's offscreen
        renderer), with the markers; the same camera as pybullet's for the same arguments."""
        from smartcar_gym.sim.mujoco.render import OffscreenCamera

        m, d = self.model_compiled(), self.kinematics()
        if self._renderer is None or self._renderer.size != (width, height):
            self._close_renderer()
            self._renderer = OffscreenCamera(m, width, height,
                                             show_collision=not getattr(self, "_visuals", True))
        return self._renderer.image(d, target, distance, yaw_deg, pitch_deg, fov_deg,
                                    self._markers)

    def _close_renderer(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def point_gui_camera(self, target: Sequence[float], distance: float, yaw_deg: float,
                         pitch_deg: float) -> None:
        """Show the world in MuJoCo's viewer (``gui``: opened the first time) from this orbit
        camera, with the markers; nothing when headless."""
        if not self.gui:
            return
        from smartcar_gym.sim.mujoco.window import Window

        if self.window is None:
            self.window = Window()
        self.window.show(self.model_compiled(), self.kinematics(), self._markers, target,
                         distance, yaw_deg, pitch_deg,
                         show_collision=not getattr(self, "_visuals", True))

    def _close_window(self) -> None:
        if getattr(self, "window", None) is not None:
            self.window.close()
            self.window = None
        if getattr(self, "gui", False):
            from smartcar_gym.sim.mujoco.window import stop_glfw

            self.gui = False
            stop_glfw()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self._close_window()
            self._close_renderer()
