"""The same maneuvers on each engine: the rows of the fidelity table in docs/engines.md.

Every maneuver spawns the shipped car (or a given model) afresh in a world of the given engine,
drives it through the emulated ArbotiX base exactly as the env does, and reduces the run to one
number. ``benchmarks/engine_fidelity.py`` prints the table; ``tests/test_mujoco_fidelity.py``
holds MuJoCo within stated tolerances of pybullet where the physics should agree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from smartcar_gym.calibration.drives import Driver, Plan
from smartcar_gym.calibration.maneuvers import Sample, hold, random_commands, run
from smartcar_gym.controller import ArbotixConfig, load_controller_config
from smartcar_gym.controller.config_yaml import calibrated_config_path
from smartcar_gym.envs.robots.smartcar import SmartCarRobot
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.engines import default_max_substep, make_simulator

SETTLE_S = 3.0  # a twist held this long has reached its steady state
MEASURE_S = 2.0  # ... measured over the following seconds
AT_REST_M_S = 1e-3
ODOMETRY_DRIVE_S = 10.0
ODOMETRY_SEED = 2026


@dataclass(frozen=True)
class Maneuver:
    """One row: a name, a unit and how to measure it on (model, config, engine, and the
    engine's simulator options, e.g. ``planar_params``)."""

    name: str
    unit: str
    measure: Callable[..., float]


def _drive(model: RobotModel, config: ArbotixConfig, engine: str,
           commands: list, **options: Any) -> list[Sample]:
    sim = make_simulator(engine, max_substep_s=default_max_substep(engine), **options)
    try:
        robot = SmartCarRobot(sim, model, config)
        robot.spawn()
        return run(robot, commands)
    finally:
        sim.close()


def steady_speed(linear_m_s: float) -> Maneuver:
    """Ground-truth speed (m/s) with ``cmd_vel`` linear.x held, after ``SETTLE_S``."""
    def measure(model: RobotModel, config: ArbotixConfig, engine: str, **options: Any) -> float:
        rate = config.rate_hz
        commands = hold((linear_m_s, 0.0), SETTLE_S + MEASURE_S, rate)
        samples = _drive(model, config, engine, commands, **options)
        first, last = samples[-round(MEASURE_S * rate) - 1], samples[-1]
        return math.hypot(last.x - first.x, last.y - first.y) / (last.t - first.t)

    return Maneuver(f"steady speed at cmd_vel {linear_m_s:g} m/s", "m/s", measure)


def spin_rate(angular_rad_s: float) -> Maneuver:
    """Ground-truth turn rate (rad/s) with ``cmd_vel`` angular.z held, after ``SETTLE_S``."""
    def measure(model: RobotModel, config: ArbotixConfig, engine: str, **options: Any) -> float:
        rate = config.rate_hz
        commands = hold((0.0, angular_rad_s), SETTLE_S + MEASURE_S, rate)
        samples = _drive(model, config, engine, commands, **options)
        first, last = samples[-round(MEASURE_S * rate) - 1], samples[-1]
        return (last.yaw - first.yaw) / (last.t - first.t)

    return Maneuver(f"spin rate at cmd_vel {angular_rad_s:g} rad/s", "rad/s", measure)


def umbmark(direction: int, side_m: float = 1.0, calibrated: bool = False) -> Maneuver:
    """Borenstein's UMBmark: a ``side_m`` square steered by odometry (0.2 m/s, 1 rad/s),
    counter-clockwise (1) or clockwise (-1); the distance (m) from the true end to the start.
    ``calibrated``: with the shipped calibrated YAML (``base_width`` 0.33 m, the car's effective
    track) instead of the given config."""
    def measure(model: RobotModel, config: ArbotixConfig, engine: str, **options: Any) -> float:
        if calibrated:
            config = load_controller_config(calibrated_config_path())
        drive = Driver(model, config, max_substep_s=default_max_substep(engine), engine=engine,
                       sim_options=options)
        x, y, _ = drive.square(Plan(square_side_m=side_m), direction).true_end
        return math.hypot(x, y)

    way = "counter-clockwise" if direction > 0 else "clockwise"
    yaml = ", calibrated YAML" if calibrated else ""
    return Maneuver(f"UMBmark {side_m:g} m square {way}{yaml}: end error", "m", measure)


def coast_down(linear_m_s: float = 0.3) -> Maneuver:
    """Distance (m) from a stop command (cmd_vel 0) at ``linear_m_s`` steady to rest."""
    def measure(model: RobotModel, config: ArbotixConfig, engine: str, **options: Any) -> float:
        rate = config.rate_hz
        commands = hold((linear_m_s, 0.0), SETTLE_S, rate) + hold((0.0, 0.0), 3.0, rate)
        samples = _drive(model, config, engine, commands, **options)
        stop = round(SETTLE_S * rate) - 1
        rest = next((s for s in samples[stop + 1:] if s.speed < AT_REST_M_S), samples[-1])
        return math.hypot(rest.x - samples[stop].x, rest.y - samples[stop].y)

    return Maneuver(f"coast-down distance from {linear_m_s:g} m/s", "m", measure)


def odometry_error(seconds: float = ODOMETRY_DRIVE_S, seed: int = ODOMETRY_SEED) -> Maneuver:
    """Distance (m) between odometry and ground truth after ``seconds`` of seeded random
    twists (the same on every engine)."""
    def measure(model: RobotModel, config: ArbotixConfig, engine: str, **options: Any) -> float:
        commands = random_commands(seconds, config.rate_hz, seed)
        end = _drive(model, config, engine, commands, **options)[-1]
        return math.hypot(end.odom_x - end.x, end.odom_y - end.y)

    return Maneuver(f"odometry vs ground truth after a {seconds:g} s drive", "m", measure)


#: the table's rows, in order
MANEUVERS: tuple[Maneuver, ...] = (
    *(steady_speed(v) for v in (0.05, 0.1, 0.2, 0.3, 0.5)),
    *(spin_rate(w) for w in (0.5, 1.0, 2.0)),
    umbmark(1), umbmark(-1), umbmark(1, calibrated=True), umbmark(-1, calibrated=True),
    coast_down(), odometry_error(),
)


def compare(model: RobotModel, config: ArbotixConfig, engines: tuple[str, ...],
            maneuvers: tuple[Maneuver, ...] = MANEUVERS,
            options: dict[str, dict[str, Any]] | None = None) -> dict[str, dict[str, float]]:
    """maneuver name -> column -> its number. ``engines`` are engine names, or column names
    that ``options`` maps to ``{"engine": name, **simulator options}`` (e.g. two planar
    columns with different ``planar_params``)."""
    options = options or {}

    def number(m: Maneuver, column: str) -> float:
        spec = dict(options.get(column, {"engine": column}))
        return float(m.measure(model, config, spec.pop("engine"), **spec))

    return {m.name: {e: number(m, e) for e in engines} for m in maneuvers}


def relative_difference(value: float, reference: float) -> float:
    """``value / reference - 1`` (nan when the reference is 0)."""
    return value / reference - 1.0 if reference else float(np.nan)
