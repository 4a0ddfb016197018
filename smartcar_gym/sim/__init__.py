"""The simulator facade: the only package that imports pybullet.

``Simulator`` owns the client, the clock and event-driven stepping; ``Body`` handles reach one
body's joints, poses and actuation.
"""

from smartcar_gym.sim.body import Body
from smartcar_gym.sim.simulator import EventSource, Simulator

__all__ = ["Body", "EventSource", "Simulator"]
