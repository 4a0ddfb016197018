"""MuJoCo's offscreen renderer as an orbit camera, with the facade's visual-only markers.

Headless, MuJoCo renders through EGL (a GPU's or Mesa's) or OSMesa (software), chosen by the
``MUJOCO_GL`` environment variable before ``mujoco`` is imported (``smartcar_gym.sim.mujoco``
picks one when it is unset and there is no display). A machine that can do neither gets one
line saying what to install.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from smartcar_gym.sim.mujoco.body import Marker, rotation
from smartcar_gym.sim.mujoco.model import GROUP_COLLISION, GROUP_HIDDEN, GROUP_VISUAL, GROUP_WORLD

INSTALL_HINT = ("install Mesa's EGL (Debian: apt-get install libegl1 libgl1-mesa-dri) and set "
                "MUJOCO_GL=egl, or OSMesa (apt-get install libosmesa6) and set MUJOCO_GL=osmesa")

_glfw_lock = threading.Lock()
_glfw_users = 0  # viewer windows and GLFW offscreen renderers, each from its start to its close
_glfw_window_used = False  # a viewer window used GLFW since it was started


def use_glfw(start: Callable[[], None] | None = None, window: bool = False) -> None:
    """One more user of GLFW: a viewer window (``window``) or an offscreen renderer on MuJoCo's
    GLFW backend. ``start`` runs first when there is none (its error: no user is added)."""
    global _glfw_users, _glfw_window_used
    with _glfw_lock:
        if _glfw_users == 0 and start is not None:
            start()
        _glfw_users += 1
        _glfw_window_used = _glfw_window_used or window


def release_glfw() -> None:
    """One user of GLFW less. GLFW lives while any window or renderer uses it:
    ``glfw.terminate()`` destroys every GLFW window, a renderer's hidden one included. When the
    last one goes and a viewer window used GLFW, it is ended (no connection outlives the
    windows); offscreen renderers alone leave it to MuJoCo, as they always did."""
    global _glfw_users, _glfw_window_used
    with _glfw_lock:
        _glfw_users -= 1
        if _glfw_users == 0 and _glfw_window_used:
            import glfw

            glfw.terminate()
            _glfw_window_used = False


def renders_through_glfw() -> bool:
    """Whether MuJoCo's offscreen renderer draws in a hidden GLFW window (``MUJOCO_GL`` unset
    or ``glfw`` under a display)."""
    import mujoco.gl_context

    context = getattr(mujoco.gl_context, "GLContext", None)
    return getattr(context, "__module__", "") == "mujoco.glfw"


class OffscreenCamera:
    """A ``mujoco.Renderer`` of ``width`` x ``height`` pixels for one compiled model."""

    def __init__(self, model: mujoco.MjModel, width: int, height: int,
                 show_collision: bool = False) -> None:
        self.size = (width, height)
        model.vis.global_.offwidth = max(width, model.vis.global_.offwidth)
        model.vis.global_.offheight = max(height, model.vis.global_.offheight)
        self._glfw = renders_through_glfw()
        if self._glfw:
            use_glfw()
        try:
            self.renderer: mujoco.Renderer | None = mujoco.Renderer(model, height, width,
                                                                    max_geom=4000)
        except Exception as exc:  # GL libraries missing: MuJoCo's own error is long
            if self._glfw:
                release_glfw()
            reason = " ".join(str(exc).split())[:160]
            raise RuntimeError(f"MuJoCo cannot render headless here ({reason}): "
                               f"{INSTALL_HINT}") from None
        self.model = model
        self.option = mujoco.MjvOption()
        show_groups(self.option, show_collision)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE

    def image(self, data: mujoco.MjData, target: Sequence[float], distance: float,
              yaw_deg: float, pitch_deg: float, fov_deg: float,
              markers: Sequence[Marker]) -> np.ndarray:
        """The picture from an orbit camera as pybullet's ``computeViewMatrixFromYawPitchRoll``
        places it (MuJoCo's azimuth is pybullet's yaw + 90 degrees)."""
        point_orbit(self.camera, target, distance, yaw_deg, pitch_deg)
        self.model.vis.global_.fovy = fov_deg
        renderer = self.renderer
        renderer.update_scene(data, camera=self.camera, scene_option=self.option)
        add_markers(renderer.scene, markers)
        return renderer.render().copy()

    def close(self) -> None:
        """Free the renderer (idempotent)."""
        renderer, self.renderer = self.renderer, None
        if renderer is not None:
            renderer.close()
            if self._glfw:
                release_glfw()


def show_groups(option: mujoco.MjvOption, show_collision: bool) -> None:
    """Draw the world and the robot's visuals, or its collision shapes where it has no
    visuals (``model.has_visuals``)."""
    option.geomgroup[:] = 0
    option.geomgroup[GROUP_WORLD] = 1
    if show_collision:
        option.geomgroup[GROUP_COLLISION] = option.geomgroup[GROUP_HIDDEN] = 1
    else:
        option.geomgroup[GROUP_VISUAL] = 1


def point_orbit(camera: mujoco.MjvCamera, target: Sequence[float], distance: float,
                yaw_deg: float, pitch_deg: float) -> None:
    """Place ``camera`` as pybullet's ``computeViewMatrixFromYawPitchRoll`` places its orbit
    camera (MuJoCo's azimuth is pybullet's yaw + 90 degrees)."""
    camera.lookat[:] = target
    camera.distance = distance
    camera.azimuth = yaw_deg + 90.0
    camera.elevation = pitch_deg


def add_markers(scene: mujoco.MjvScene, markers: Sequence[Marker]) -> None:
    """Append the visual-only markers' shapes to ``scene`` (as many as it has room for)."""
    for marker in markers:
        frame = rotation(marker.orientation)
        for kind, size, position, quat, rgba in marker.parts:
            if scene.ngeom >= scene.maxgeom:
                return
            mat = frame @ rotation(quat)
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], kind, size,
                                marker.position + frame @ position, mat.ravel(), rgba)
            scene.ngeom += 1
