"""Old path of ``sim.pybullet.camera`` (pybullet's cameras and visual shapes), kept for old
imports; ``BoxPart`` is every engine's (``sim.contracts``)."""

from smartcar_gym.sim.contracts import BoxPart
from smartcar_gym.sim.pybullet.camera import model_image, orbit_image, visual_batch, visual_body

__all__ = ["BoxPart", "model_image", "orbit_image", "visual_batch", "visual_body"]
