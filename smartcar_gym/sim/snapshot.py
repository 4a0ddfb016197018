"""Old path of ``sim.pybullet.snapshot`` (a picture of a robot model), kept for old imports."""

from smartcar_gym.sim.pybullet.snapshot import SETTLE_SUBSTEP_S, render_image, write_png

__all__ = ["SETTLE_SUBSTEP_S", "render_image", "write_png"]
