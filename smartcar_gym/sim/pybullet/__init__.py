"""The pybullet engine, the default: ``ENGINE`` describes it to ``sim.engines``.

Its simulator is ``simulator.Simulator`` (a pybullet client of its own per world, DIRECT
or the GUI); 10 ms substeps by default, at most 20 ms (above that its contacts jitter).
"""

from __future__ import annotations

from typing import Any

from smartcar_gym.sim.clock import DEFAULT_MAX_SUBSTEP_S, MAX_SUBSTEP_RANGE_S
from smartcar_gym.sim.engines import Engine


def _simulator(**options: Any) -> Any:
    from smartcar_gym.sim.pybullet.simulator import Simulator

    return Simulator(**options)


ENGINE = Engine(
    name="pybullet",
    simulator=_simulator,
    max_substep_s=DEFAULT_MAX_SUBSTEP_S,
    substep_range_s=MAX_SUBSTEP_RANGE_S,
    skips_drawing=True,
    module="pybullet",
    summary="the default (docs/engines.md)",
)
