"""Old path of ``sim.pybullet.simulator`` (pybullet's ``Simulator``), kept for old imports,
with the clock's names (``sim.clock``) it always offered."""

from smartcar_gym.sim.clock import (
    DEFAULT_MAX_SUBSTEP_S,
    MAX_FIRINGS_PER_INSTANT,
    MAX_SUBSTEP_RANGE_S,
    NS_PER_S,
    EventClock,
    EventSource,
    check_max_substep,
    seconds_to_ns,
)
from smartcar_gym.sim.pybullet.simulator import (
    CONVERGED_SOLVER_ITERATIONS,
    CONVERGED_SOLVER_RESIDUAL,
    Quat,
    Simulator,
    Vec3,
)

__all__ = [
    "CONVERGED_SOLVER_ITERATIONS", "CONVERGED_SOLVER_RESIDUAL", "DEFAULT_MAX_SUBSTEP_S",
    "MAX_FIRINGS_PER_INSTANT", "MAX_SUBSTEP_RANGE_S", "NS_PER_S", "EventClock", "EventSource",
    "Quat", "Simulator", "Vec3", "check_max_substep", "seconds_to_ns",
]
