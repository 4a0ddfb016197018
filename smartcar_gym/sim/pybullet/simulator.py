"""The simulator facade: one pybullet ``BulletClient``, its clock and its stepping.

Robots, tasks and envs never call pybullet; they go through this class and the ``Body``
handles it returns (the panda-gym pattern).

**Time.** The clock counts integer nanoseconds from the start of an episode, so event times
(the board's 34 ms PID frames, the controller's 0.1 s updates) are exact. ``run_until`` steps
the physics from event to event: each interval between two events is split into the fewest
equal substeps no longer than ``max_substep_s``. Event sources (``EventSource``) say when they
next need to act; the simulator never looks inside them.

**What depends on the time step.** pybullet turns a force-limited velocity motor's ``maxForce``
and a constraint's ``maxForce`` into an impulse ``force * dt`` at the moment they are set, and
it clears applied joint torques after every physics step. So the simulator keeps those itself:
torques held by ``Body.hold_torques`` are re-applied before every substep, force-limited motors
and constraints are re-sent whenever the time step changes.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from smartcar_gym.sim.clock import (
    DEFAULT_MAX_SUBSTEP_S,
    NS_PER_S,
    EventClock,
    check_max_substep,
    seconds_to_ns,
)
from smartcar_gym.sim.pybullet import camera
from smartcar_gym.sim.pybullet.body import Body
from smartcar_gym.sim.pybullet.bullet import connect, pybullet, silenced_output

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
# A differential-drive robot's contacts solved to convergence: the solver iterates until its
# residual is below 1e-14 (pybullet's default stops at 1e-7), at most 100 times (a light robot
# needed more than 50). The casterbot's two wheels then roll 1e-4 ticks apart in 0.5 s under
# equal torques, where 10 iterations leave them 0.35 tick apart (docs/stepping.md, "Driving
# straight").
CONVERGED_SOLVER_ITERATIONS = 100
CONVERGED_SOLVER_RESIDUAL = 1e-14


class Simulator(EventClock):
    """A pybullet world (gravity, a ground plane) with an event-driven clock.

    Args:
        max_substep_s: the longest physics substep (s); intervals between events are split
            into the fewest equal substeps no longer than this. 0.002 reproduces fixed 500 Hz
            stepping.
        gui: open the pybullet GUI instead of a headless DIRECT client.
        gravity_m_s2: gravitational acceleration (positive number, applied along -z).
        ground_friction: lateral friction coefficient of the ground plane.
        solver_iterations: constraint solver iterations per physics step (10: 5 jitters at
            10 ms substeps, 20 costs 15 % for nothing).
    """

    engine = "pybullet"

    def __init__(
        self,
        max_substep_s: float = DEFAULT_MAX_SUBSTEP_S,
        gui: bool = False,
        gravity_m_s2: float = 9.81,
        ground_friction: float = 1.0,
        solver_iterations: int = 10,
        draws: bool = True,
    ) -> None:
        self.max_substep_s = check_max_substep(max_substep_s)
        #: whether anything draws this world: False (and no GUI) leaves the visual shapes of
        #: ``add_static``'s bodies out (a BARN world's 300 pillars: 84 ms less per reset)
        self.draws = bool(draws) or gui
        self.max_substep_ns = seconds_to_ns(self.max_substep_s)
        self.gui = gui
        if gui and sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        ):
            # pybullet's GUI blocks forever without a display instead of failing.
            raise RuntimeError(
                "render_mode='human' opens the pybullet GUI, which needs a display (DISPLAY is "
                "not set); use render_mode='rgb_array' for headless rendering"
            )
        self.gravity_m_s2 = gravity_m_s2
        self.ground_friction = ground_friction
        self.solver_iterations = int(solver_iterations)
        #: whether ``converge_contacts`` is in force (until the next ``reset``)
        self.contacts_converged = False
        self.client = connect(gui=gui)
        # bound once: every attribute access of a BulletClient builds a new partial
        self._step_simulation = self.client.stepSimulation
        self._set_joint_motors = self.client.setJointMotorControlArray
        self._set_time_step_raw = self.client.setTimeStep
        self._restart_clock()
        self._dt = 0.0
        self._held: dict[tuple[str, str], tuple[int, list[int], list[float]]] = {}
        self._motors: dict[tuple[str, str], tuple[int, list[int], list[float], list[float]]] = {}
        self._scratch = None
        self.reset()

    # -- world ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """Clear the world (``resetSimulation``), add the ground plane, restart the clock.

        Fully deterministic: what was loaded, held or scheduled before is gone.
        """
        c = self.client
        c.resetSimulation()  # a new dynamics world: pybullet's default solver settings
        self.contacts_converged = False
        if self.gui:
            c.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
        self._dt = self.max_substep_s
        # pybullet's file cache keeps every file it has read, keyed by its path, for the life of
        # the client. On for the ground only: its mesh (plane100.obj) is then parsed once, not
        # at every reset (13 ms -> 1 ms). Off for everything else: a robot is rewritten at every
        # reset (randomised, maybe), and the cache would serve the old text or grow without end.
        c.setPhysicsEngineParameter(
            fixedTimeStep=self._dt, deterministicOverlappingPairs=1,
            numSolverIterations=self.solver_iterations, enableFileCaching=1,
        )
        c.setGravity(0.0, 0.0, -self.gravity_m_s2)
        self._restart_clock()
        self._held = {}
        self._motors = {}
        #: pillars to put to sleep after the next physics step (``_sleep_pillars``)
        self._to_sleep: list[int] = []
        plane = Body(self, "plane", c.loadURDF("plane.urdf"))  # pybullet_data's, no flags
        c.setPhysicsEngineParameter(enableFileCaching=0)
        plane.set_friction(-1, self.ground_friction)
        self._bodies["plane"] = plane

    def converge_contacts(self) -> None:
        """Solve the contacts to convergence until the next ``reset``.

        The constraint solver iterates at every substep until its residual is below
        ``CONVERGED_SOLVER_RESIDUAL``, at most ``CONVERGED_SOLVER_ITERATIONS`` times. It visits
        the contacts in order, so 10 iterations leave a mirror-symmetric robot slightly
        lopsided; converged, its two sides move alike to rounding. A robot that turns freely
        with any difference between its sides (``RobotModel.drive_kind == "differential"``)
        asks for this when it spawns.
        """
        self.client.setPhysicsEngineParameter(
            numSolverIterations=CONVERGED_SOLVER_ITERATIONS,
            solverResidualThreshold=CONVERGED_SOLVER_RESIDUAL,
        )
        self.contacts_converged = True

    @contextlib.contextmanager
    def building(self) -> Iterator[None]:
        """Pause the GUI's drawing while the world is rebuilt and bodies are created.

        pybullet's GUI draws from its own thread; creating bodies while it draws can crash
        the process (seen with the batch-created odometry arrows). Headless: does nothing.
        """
        if not self.gui:
            yield
            return
        self.client.configureDebugVisualizer(pybullet.COV_ENABLE_RENDERING, 0)
        try:
            yield
        finally:
            if self.connected:
                self.client.configureDebugVisualizer(pybullet.COV_ENABLE_RENDERING, 1)

    def close(self) -> None:
        """Disconnect the client and remove the scratch folder (idempotent)."""
        client = getattr(self, "client", None)
        if client is not None:
            # the GUI's threads report their shutdown on the C-level stdout
            with silenced_output(), contextlib.suppress(pybullet.error):
                client.disconnect()
            self.client = None
        self._remove_scratch()

    def __getstate__(self) -> None:
        raise TypeError(
            "a Simulator cannot be copied or pickled: a copy of its BulletClient would drive the "
            "same physics server (and disconnect it when collected); make a new Simulator"
        )

    @property
    def connected(self) -> bool:
        return self.client is not None and self.client.isConnected()

    # -- stepping ------------------------------------------------------------------------------
    def _step_physics(self, interval_ns: int, probe: Callable[[float], None] | None) -> None:
        """Step ``interval_ns`` in the fewest equal substeps no longer than ``max_substep_s``."""
        if interval_ns <= 0:
            return
        n = -(-interval_ns // self.max_substep_ns)
        dt = interval_ns / (n * NS_PER_S)
        if dt != self._dt:
            self._set_time_step(dt)
        step, set_joints = self._step_simulation, self._set_joint_motors
        held = list(self._held.values())
        torque = pybullet.TORQUE_CONTROL
        start = self.now_ns
        for i in range(n):
            for body, joints, torques in held:  # pybullet clears them after every step
                set_joints(body, joints, torque, forces=torques)
            step()
            if probe is not None:
                probe((start + interval_ns * (i + 1) / n) / NS_PER_S)
        self.physics_steps += n
        if self._to_sleep:
            self._sleep_pillars()

    def _sleep_pillars(self) -> None:
        """Put the pillars built since the last step to sleep: Bullet then stops computing
        their bounding boxes at every step (it does for every awake body, static or not), a
        BARN world's physics step 43 us instead of 55.

        After a step, not at their creation: the step gives each box the contact margin
        that Bullet's broadphase works with. Asleep from its creation a pillar keeps a box
        without it, and a ray grazing the pillar missed it (seen in a BARN run). With the
        boxes set, a sleeping pillar is hit and touched as before (static bodies are never
        woken; the car stays awake), so every run is the same to the bit
        (``tests/test_barn_env.py``, and BARN's 500 DWA runs compared).
        """
        sleep = pybullet.ACTIVATION_STATE_SLEEP
        for uid in self._to_sleep:
            self.client.changeDynamics(uid, -1, activationState=sleep)
        self._to_sleep = []

    def _set_time_step(self, dt: float) -> None:
        """Change the physics step and re-send the motors pybullet scaled by the old one.

        Gear constraints are not re-sent: their force cap (also stored as ``force * dt``) is
        chosen far above what they ever carry, so it never binds at any step in range
        (``tests/test_sim_stepping.py`` measures it).
        """
        self._set_time_step_raw(dt)
        self._dt = dt
        for body, joints, targets, forces in self._motors.values():
            self._set_joint_motors(body, joints, pybullet.VELOCITY_CONTROL,
                                   targetVelocities=targets, forces=forces)

    @property
    def time_step_s(self) -> float:
        """The physics step pybullet used last (s)."""
        return self._dt

    # -- what the simulator keeps applying (used by Body) --------------------------------------
    def _hold(self, key: tuple[str, str], body: int, joints: list[int],
              torques: list[float]) -> None:
        self._held[key] = (body, joints, torques)

    def _motor(self, key: tuple[str, str], body: int, joints: list[int], targets: list[float],
               forces: list[float]) -> None:
        self._motors[key] = (body, joints, targets, forces)
        self.client.setJointMotorControlArray(body, joints, pybullet.VELOCITY_CONTROL,
                                              targetVelocities=targets, forces=forces)

    def _gear(self, body: int, parent: int, child: int, ratio: float, force: float) -> int:
        c = self.client
        cid = c.createConstraint(body, parent, body, child, pybullet.JOINT_GEAR,
                                 [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        c.changeConstraint(cid, gearRatio=ratio, maxForce=force)
        return cid

    # -- bodies --------------------------------------------------------------------------------
    def load_urdf(
        self,
        name: str,
        path: str | Path,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        yaw: float = 0.0,
        fixed: bool = False,
    ) -> Body:
        """Load a URDF file as body ``name`` with its link frame at ``position``, heading ``yaw``.

        The inertias written in the file are used (pybullet would otherwise recompute them
        from the collision shapes). pybullet's importer messages are silenced; a file it cannot
        load raises ``ModelError`` naming the file (and the reason where it can be told).
        """
        from smartcar_gym.sim.pybullet.loading import load_body  # imports the model package (xacro)

        self._check_new_name(name)
        flags = pybullet.URDF_USE_INERTIA_FROM_FILE | pybullet.URDF_USE_IMPLICIT_CYLINDER
        orientation = (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
        uid = load_body(self.client, path, position, orientation, flags=flags,
                        fixed=fixed)
        body = Body(self, name, uid)
        self._bodies[name] = body
        return body

    def add_visual(
        self,
        name: str,
        shape: str,
        size: Sequence[float],
        rgba: Sequence[float],
        position: Sequence[float] = (0.0, 0.0, 0.0),
    ) -> Body:
        """Add a visual-only, collision-free marker: ``shape`` is 'sphere', 'cylinder' or 'box'.

        ``size`` is (radius,), (radius, length) or box half-extents respectively.
        """
        uid = camera.visual_body(self.client, shape, size, rgba, position)
        body = Body(self, name, uid)
        self._bodies[name] = body
        return body

    def add_visual_copies(self, prefix: str, parts: Sequence[camera.BoxPart], count: int,
                          position: Sequence[float]) -> list[Body]:
        """``count`` copies of one visual-only shape made of boxes, created in one batch."""
        uids = camera.visual_batch(self.client, parts, count, position)
        bodies = [Body(self, f"{prefix}{i}", uid) for i, uid in enumerate(uids)]
        for body in bodies:
            self._bodies[body.name] = body
        return bodies

    def add_static(self, name: str, shape: str, half_extents: Sequence[float],
                   position: Sequence[float], yaw: float, rgba: Sequence[float],
                   pillar: bool = False) -> Body:
        """A fixed body (mass 0) of one 'box' (``half_extents``) or upright 'cylinder' (radius
        ``half_extents[0]``, height ``2 * half_extents[2]``) that collides, centred on
        ``position`` and turned by ``yaw``. A ``pillar`` cylinder collides as a capsule whose
        straight part is the cylinder (its round ends lie below the ground and above the
        top): Bullet ray-tests capsules about 2.6 times faster than cylinders (a BARN world's
        scan of 360 rays among 300 pillars: 1.8 ms instead of 4.7), and its side is the
        same; it is drawn as the cylinder. A pillar is also a static rigid body (maximal
        coordinates) rather than a fixed-base multibody, which Bullet's multibody solver
        would visit at every step (a BARN world's step: 55 us instead of 122), and asleep
        after its first step (``_sleep_pillars``: 43 us); its scans, distances and contacts
        came out the same to the bit (``tests/test_barn_env.py``, and 500 BARN runs
        compared). Other static bodies stay multibodies: as rigid bodies the recorded Nav
        rollout changed in its last bit (one clearance 1 ulp off)."""
        self._check_new_name(name)
        c = self.client
        if shape == "box":
            half = list(half_extents)
            collision = c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half)
            visual = (c.createVisualShape(pybullet.GEOM_BOX, halfExtents=half,
                                          rgbaColor=list(rgba)) if self.draws else -1)
        else:
            radius, height = half_extents[0], 2.0 * half_extents[2]
            collision = c.createCollisionShape(
                pybullet.GEOM_CAPSULE if pillar else pybullet.GEOM_CYLINDER, radius=radius,
                height=height)
            visual = (c.createVisualShape(pybullet.GEOM_CYLINDER, radius=radius, length=height,
                                          rgbaColor=list(rgba)) if self.draws else -1)
        uid = c.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=collision, baseVisualShapeIndex=visual,
            basePosition=list(position),
            baseOrientation=[0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)],
            useMaximalCoordinates=pillar,
        )
        if pillar:
            self._to_sleep.append(uid)
        body = Body(self, name, uid)
        self._bodies[name] = body
        return body

    def ray_batch(self, starts: np.ndarray, ends: np.ndarray):
        """``smartcar_gym.sim.rays.cast_rays`` of checked (N, 3) arrays: pybullet's batch."""
        from smartcar_gym.sim.pybullet.rays import bullet_rays

        return bullet_rays(self.client, starts, ends)

    # -- rendering -----------------------------------------------------------------------------
    def render(
        self,
        width: int,
        height: int,
        target: Sequence[float],
        distance: float,
        yaw_deg: float,
        pitch_deg: float,
        fov_deg: float = 50.0,
    ) -> np.ndarray:
        """An RGB image (height, width, 3) uint8 from an orbit camera (TinyRenderer headless)."""
        return camera.orbit_image(self.client, width, height, target, distance, yaw_deg,
                                  pitch_deg, fov_deg, opengl=self.gui)

    def point_gui_camera(self, target: Sequence[float], distance: float, yaw_deg: float,
                         pitch_deg: float) -> None:
        """Point the GUI's camera (``render_mode="human"``); nothing when headless."""
        if self.gui:
            self.client.resetDebugVisualizerCamera(distance, yaw_deg, pitch_deg, list(target))
