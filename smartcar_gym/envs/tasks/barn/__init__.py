"""SmartCarBARN-v0: the BARN challenge's worlds, protocol and score (``protocol``), as a task
(``task.BarnTask``)."""

from smartcar_gym.envs.tasks.barn.protocol import (
    COLLISION,
    FAILURE,
    OUTCOMES,
    SUCCESS,
    TIMEOUT,
    BarnProtocol,
    RunClock,
    barn_score,
)
from smartcar_gym.envs.tasks.barn.task import BarnTask

__all__ = ["COLLISION", "FAILURE", "OUTCOMES", "SUCCESS", "TIMEOUT", "BarnProtocol", "BarnTask",
           "RunClock", "barn_score"]
