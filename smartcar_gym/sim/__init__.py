"""The simulator facade: the only package that imports pybullet or mujoco.

``Simulator`` (pybullet) owns the client, the clock and event-driven stepping; ``Body`` handles
reach one body's joints, poses and actuation. ``clock.EventClock`` is what every engine shares;
``mujoco.simulator.MujocoSimulator`` is the MuJoCo implementation (the ``mujoco`` extra), and
``engines.make_simulator(engine)`` picks one.
"""

from smartcar_gym.sim.body import Body
from smartcar_gym.sim.simulator import EventSource, Simulator

__all__ = ["Body", "EventSource", "Simulator"]
