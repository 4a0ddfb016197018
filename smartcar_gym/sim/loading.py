"""Old path of ``sim.pybullet.loading`` (a URDF file into pybullet, quietly), kept for old
imports."""

from smartcar_gym.sim.pybullet.loading import load_body

__all__ = ["load_body"]
