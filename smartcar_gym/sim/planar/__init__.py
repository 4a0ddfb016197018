"""The planar engine: rigid cars in the plane (x, y, yaw), simulated in numpy arrays over N cars.

``ENGINE`` describes it to ``sim.engines``: its own keyword ``planar_params`` (the fitted
parameters, ``params.resolve``), 20 ms substeps by default and up to 50 ms (its implicit step is
stable at any length), no window (it draws top-down pictures), and its car batch (``cars``:
N cars in arrays, differential-drive models included).
"""

from __future__ import annotations

from typing import Any

from smartcar_gym.sim.batch import LazyCarBatch
from smartcar_gym.sim.engines import Engine

#: the planar engine's longest substep by default and at most (s): its implicit step is stable
#: at any length; 0.02 s is within 1 % of 2 ms stepping on every fidelity figure (docs/planar.md)
PLANAR_MAX_SUBSTEP_S = 0.02
PLANAR_SUBSTEP_RANGE_S = (1e-4, 0.05)


def _simulator(**options: Any) -> Any:
    from smartcar_gym.sim.planar.simulator import PlanarSimulator

    return PlanarSimulator(**options)


def _resolve_params(value: Any, model: Any = None) -> Any:
    """``planar_params`` resolved; not given: the shipped fit for the shipped smartcar, the
    neutral values for any other robot (``params.for_robot``)."""
    from smartcar_gym.sim.planar.params import for_robot, resolve

    return resolve(value) if model is None else for_robot(value, model)


ENGINE = Engine(
    name="planar",
    simulator=_simulator,
    max_substep_s=PLANAR_MAX_SUBSTEP_S,
    substep_range_s=PLANAR_SUBSTEP_RANGE_S,
    window_unavailable=lambda: "the planar engine draws top-down pictures only (no window)",
    kwargs={"planar_params": _resolve_params},
    spawn_check=True,
    # measured (4096 cars, SmartCar-v0): about 6 KiB of arrays per car; the margin covers the
    # per-car generators
    car_batch=LazyCarBatch("smartcar_gym.sim.planar.cars:PlanarCars", 16 * 1024),
    batches_differential=True,  # BatchedArbotix starts the encoders mid-tick, as the single env
    summary="a rigid car on identified tyres, in arrays (docs/planar.md)",
)
