"""Old path of ``sim.pybullet.bullet`` (quiet access to pybullet), kept for old imports."""

from smartcar_gym.sim.pybullet.bullet import (
    bullet_client,
    connect,
    pybullet,
    pybullet_data,
    silenced_output,
)

__all__ = ["bullet_client", "connect", "pybullet", "pybullet_data", "silenced_output"]
