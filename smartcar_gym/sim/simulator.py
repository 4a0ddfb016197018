"""The simulator facade: one pybullet ``BulletClient`` with a ground plane and named bodies.

Robots, tasks and the env never hold pybullet ids of other bodies or call pybullet on the global
client; they go through this class (the panda-gym pattern). Time is counted in physics ticks, so
``time_s`` is exact (``ticks / physics_hz``) and seeded runs are reproducible.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from smartcar_gym._bullet import connect, pybullet, silenced_output

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


class Simulator:
    """A pybullet world stepped at ``physics_hz`` with gravity and a ground plane.

    Args:
        physics_hz: physics rate (Hz); the step is ``1 / physics_hz`` s.
        gui: open the pybullet GUI instead of a headless DIRECT client.
        gravity_m_s2: gravitational acceleration (positive number, applied along -z).
        ground_friction: lateral friction coefficient of the ground plane.
        solver_iterations: constraint solver iterations per physics step.
    """

    def __init__(
        self,
        physics_hz: float = 500.0,
        gui: bool = False,
        gravity_m_s2: float = 9.81,
        ground_friction: float = 1.0,
        solver_iterations: int = 10,
    ) -> None:
        if not (math.isfinite(physics_hz) and physics_hz > 0):
            raise ValueError(f"physics_hz must be a positive number, got {physics_hz!r}")
        self.physics_hz = float(physics_hz)
        self.dt = 1.0 / self.physics_hz
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
        self.client = connect(gui=gui)
        self._bodies: dict[str, int] = {}
        self.ticks = 0
        self.reset()

    # -- world ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """Clear the world (``resetSimulation``) and add the ground plane: fully deterministic."""
        c = self.client
        c.resetSimulation()
        if self.gui:
            c.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
        # 10 solver iterations (pybullet: 50) converge the wheel contacts, gear and friction
        # constraints of this small car to the same trajectories, at half the cost per step
        c.setPhysicsEngineParameter(
            fixedTimeStep=self.dt, deterministicOverlappingPairs=1,
            numSolverIterations=self.solver_iterations,
        )
        c.setGravity(0.0, 0.0, -self.gravity_m_s2)
        self._bodies = {"plane": c.loadURDF("plane.urdf")}
        c.changeDynamics(self._bodies["plane"], -1, lateralFriction=self.ground_friction)
        self.ticks = 0

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

    @property
    def time_s(self) -> float:
        """Simulated time since the last ``reset`` or ``restart_clock`` (s)."""
        return self.ticks / self.physics_hz

    def restart_clock(self) -> None:
        """Set the simulated clock back to 0 (after settling bodies at reset)."""
        self.ticks = 0

    def step(self, ticks: int = 1) -> None:
        """Advance the physics by ``ticks`` steps of ``dt``."""
        for _ in range(ticks):
            self.client.stepSimulation()
        self.ticks += ticks

    def close(self) -> None:
        """Disconnect the client (idempotent)."""
        client = getattr(self, "client", None)
        if client is not None:
            # the GUI's threads report their shutdown on the C-level stdout
            with silenced_output(), contextlib.suppress(pybullet.error):
                client.disconnect()
            self.client = None

    @property
    def connected(self) -> bool:
        return self.client is not None and self.client.isConnected()

    # -- bodies --------------------------------------------------------------------------------
    def load_urdf(
        self,
        name: str,
        path: str | Path,
        position: Sequence[float] = (0.0, 0.0, 0.0),
        yaw: float = 0.0,
    ) -> int:
        """Load a URDF file as body ``name`` with its link frame at ``position``, heading ``yaw``.

        The inertias written in the file are used (pybullet would otherwise recompute them
        from the collision shapes). pybullet's importer messages are silenced; a file it cannot
        load raises ``ModelError`` naming the file (and the reason where it can be told).
        """
        from smartcar_gym.model.bodies import load_body  # the model package imports xacro

        flags = pybullet.URDF_USE_INERTIA_FROM_FILE | pybullet.URDF_USE_IMPLICIT_CYLINDER
        body = load_body(
            self.client,
            path,
            position,
            self.client.getQuaternionFromEuler([0.0, 0.0, yaw]),
            flags=flags,
        )
        self._bodies[name] = body
        return body

    def add_visual(
        self,
        name: str,
        shape: str,
        size: Sequence[float],
        rgba: Sequence[float],
        position: Sequence[float] = (0.0, 0.0, 0.0),
    ) -> int:
        """Add a visual-only, collision-free marker: ``shape`` is 'sphere', 'cylinder' or 'box'.

        ``size`` is (radius,), (radius, length) or box half-extents respectively.
        """
        c = self.client
        if shape == "sphere":
            vis = c.createVisualShape(pybullet.GEOM_SPHERE, radius=size[0], rgbaColor=rgba)
        elif shape == "cylinder":
            vis = c.createVisualShape(
                pybullet.GEOM_CYLINDER, radius=size[0], length=size[1], rgbaColor=rgba
            )
        elif shape == "box":
            vis = c.createVisualShape(pybullet.GEOM_BOX, halfExtents=list(size), rgbaColor=rgba)
        else:
            raise ValueError(f"unknown marker shape {shape!r}: expected sphere, cylinder or box")
        body = c.createMultiBody(baseMass=0.0, baseVisualShapeIndex=vis, basePosition=position)
        self._bodies[name] = body
        return body

    def body(self, name: str) -> int:
        """The pybullet id of body ``name``."""
        try:
            return self._bodies[name]
        except KeyError:
            raise KeyError(f"no body named {name!r}; bodies: {sorted(self._bodies)}") from None

    def has_body(self, name: str) -> bool:
        return name in self._bodies

    def joint_indices(self, name: str) -> dict[str, int]:
        """Joint name -> pybullet joint index for body ``name``."""
        body = self.body(name)
        c = self.client
        return {
            c.getJointInfo(body, i)[1].decode(): i for i in range(c.getNumJoints(body))
        }

    def set_pose(self, name: str, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Teleport a body's base (centre-of-mass frame) to ``position``/``orientation``."""
        self.client.resetBasePositionAndOrientation(self.body(name), position, orientation)

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
        """An RGB image (height, width, 3) uint8 from an orbit camera, headless (TinyRenderer)."""
        c = self.client
        view = c.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=list(target),
            distance=distance,
            yaw=yaw_deg,
            pitch=pitch_deg,
            roll=0.0,
            upAxisIndex=2,
        )
        proj = c.computeProjectionMatrixFOV(
            fov=fov_deg, aspect=width / height, nearVal=0.02, farVal=100.0
        )
        renderer = pybullet.ER_BULLET_HARDWARE_OPENGL if self.gui else pybullet.ER_TINY_RENDERER
        _, _, rgba, _, _ = c.getCameraImage(
            width, height, viewMatrix=view, projectionMatrix=proj, renderer=renderer
        )
        return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()
