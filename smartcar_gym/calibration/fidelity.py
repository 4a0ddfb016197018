"""The fidelity figures of a stepping: the scenarios behind the gates in
``tests/test_fidelity.py`` and the table of ``benchmarks/fidelity.py``.

Each scenario drives a freshly spawned robot through one command sequence and reduces the run to
a few numbers; runs with different ``max_substep_s`` on identical commands are then compared.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from smartcar_gym.calibration.maneuvers import (
    Sample,
    circle_centre_drift,
    hold,
    random_commands,
    run,
)
from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.envs.robots.smartcar import SmartCarRobot
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.clock import EventClock
from smartcar_gym.sim.engines import DEFAULT_ENGINE, make_simulator

RANDOM_SEED = 2026


@dataclass
class Figures:
    """What one stepping gives on every scenario (units in the names)."""

    max_substep_s: float
    wheel_contact: str
    steady_speed_m_s: dict[float, float] = field(default_factory=dict)  # cmd_vel -> wheels
    odometry_error_straight: float = 0.0  # (odom distance - true distance) / true distance
    spin_revolutions: float = 0.0  # 30 s at 1 rad/s
    spin_centre_drift_m_per_rev: float = 0.0
    coast_speed_m_s: dict[float, float] = field(default_factory=dict)  # s after stop -> m/s
    coast_at_rest_s: float = math.inf  # first time after the stop with speed < 1 mm/s
    random_end: tuple[float, float, float] = (0.0, 0.0, 0.0)  # x, y, unwrapped yaw after 20 s
    min_up_z: float = 1.0
    max_z_jitter_m: float = 0.0  # peak-to-peak base height: steady at 0.4 m/s, and at rest
    speed_3s_after_stop_m_s: float = 0.0


def _robot(model: RobotModel, config: ArbotixConfig, contact: str,
           max_substep_s: float, engine: str = DEFAULT_ENGINE) -> tuple[EventClock, SmartCarRobot]:
    sim = make_simulator(engine, max_substep_s=max_substep_s)
    robot = SmartCarRobot(sim, model, config, wheel_contact=contact)
    robot.spawn()
    return sim, robot


def measure(model: RobotModel, config: ArbotixConfig, contact: str,
            max_substep_s: float, engine: str = DEFAULT_ENGINE) -> Figures:
    """Run every scenario with this stepping; a fresh world for each."""
    rate = config.rate_hz
    fig = Figures(max_substep_s, contact)
    ups: list[float] = []

    def scenario(commands) -> list[Sample]:
        sim, robot = _robot(model, config, contact, max_substep_s, engine)
        try:
            samples = run(robot, commands)
        finally:
            sim.close()
        ups.extend(s.up_z for s in samples)
        return samples

    for speed in (0.2, 0.4):  # 5 s from rest; the last 2 s
        samples = scenario(hold((speed, 0.0), 5.0, rate))
        fig.steady_speed_m_s[speed] = float(np.mean([s.wheel_speed for s in samples[-20:]]))
        fig.max_z_jitter_m = max(fig.max_z_jitter_m, float(np.ptp([s.z for s in samples[-20:]])))
        if speed == 0.2:
            end = samples[-1]
            true = math.hypot(end.x - 0.0, end.y - 0.0)
            fig.odometry_error_straight = math.hypot(end.odom_x, end.odom_y) / true - 1.0

    samples = scenario(hold((0.0, 1.0), 30.0, rate))
    fig.spin_revolutions, fig.spin_centre_drift_m_per_rev = circle_centre_drift(samples)

    # coast-down: 3 s at 0.3 m/s, then stop. The stop reaches the board at the next update
    # (the controller writes (0, 0): PWM 0 disconnects the motors), one period after it is sent.
    run_in = round(3.0 * rate)
    samples = scenario(hold((0.3, 0.0), 3.0, rate) + hold((0.0, 0.0), 3.5, rate))
    after = samples[run_in:]
    stop_t = samples[run_in - 1].t + 1.0 / rate  # the update that writes (0, 0)
    for delay in (0.0, 0.2, 0.5):
        fig.coast_speed_m_s[delay] = next(s.speed for s in after if s.t >= stop_t + delay - 1e-9)
    fig.coast_at_rest_s = next((s.t - stop_t for s in after if s.speed < 1e-3), math.inf)
    fig.speed_3s_after_stop_m_s = next(s.speed for s in after if s.t >= stop_t + 3.0 - 1e-9)
    heights = [s.z for s in after if s.t >= stop_t + 2.0]
    fig.max_z_jitter_m = max(fig.max_z_jitter_m, float(np.ptp(heights)))

    samples = scenario(random_commands(20.0, rate, RANDOM_SEED, hold_s=0.1))
    fig.random_end = (samples[-1].x, samples[-1].y, samples[-1].yaw)
    fig.min_up_z = float(min(ups))
    return fig
