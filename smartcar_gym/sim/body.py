"""Old path of ``sim.pybullet.body`` (pybullet's ``Body``), kept for old imports; ``BASE`` and
``LinkDynamics`` are every engine's (``sim.contracts``)."""

from smartcar_gym.sim.contracts import BASE, LinkDynamics, Quat, Vec3
from smartcar_gym.sim.pybullet.body import Body

__all__ = ["BASE", "Body", "LinkDynamics", "Quat", "Vec3"]
