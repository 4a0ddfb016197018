"""``PlanarSimulator``: the simulator facade on the planar engine (``sim.contracts``).

The world is flat ground, static obstacles (boxes and upright cylinders) and robots, each a
``PlanarBody`` (``body.py``): a rigid body in the plane on its wheel groups
(``model.build_car``), stepped by ``dynamics.substep``, addressed exactly as on pybullet. The
clock and event-driven stepping are ``EventClock``'s, shared with pybullet and MuJoCo: each
interval between events is split into the fewest equal substeps no longer than
``max_substep_s``.

One car steps in Python floats (``math.sqrt``), which for one car is several times faster than
numpy; ``batch.PlanarBatch`` steps N cars in arrays with the same function, bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.model.errors import ModelError
from smartcar_gym.sim.clock import EventClock, check_max_substep
from smartcar_gym.sim.planar import PLANAR_MAX_SUBSTEP_S, PLANAR_SUBSTEP_RANGE_S
from smartcar_gym.sim.planar.body import PlanarBody, PlanarStatic
from smartcar_gym.sim.planar.model import RobotTables
from smartcar_gym.sim.planar.params import PlanarParams, resolve


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
