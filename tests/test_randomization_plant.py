"""Each randomised factor changes the simulated robot the way it says, measured."""

from __future__ import annotations

import math

import numpy as np
import pytest

from smartcar_gym.calibration.maneuvers import Sample, hold, run
from smartcar_gym.controller import WheelEncoder
from smartcar_gym.controller.encoder_faults import FaultyEncoder
from smartcar_gym.controller.latency import CommandDelay
from smartcar_gym.envs.randomization import Randomization
from smartcar_gym.envs.robots import SmartCarRobot
from smartcar_gym.envs.robots.variation import Variation
from smartcar_gym.sim.contracts import BASE
from smartcar_gym.sim.dynamics import scale_lateral_friction, scale_mass, set_lateral_friction
from smartcar_gym.sim.pybullet.simulator import Simulator


def _drive(model, config, variation, twist, seconds, mode="hardware") -> Sample:
    sim = Simulator()
    try:
        robot = SmartCarRobot(sim, model, config, mode=mode)
        robot.vary(variation)
        robot.spawn()
        return run(robot, hold(twist, seconds, config.rate_hz))[-1]
    finally:
        sim.close()


@pytest.fixture(scope="module")
def nominal(shipped_model, shipped_config):
    """Straight (0.2 m/s, 5 s) and spin (1 rad/s, 10 s) of the nominal robot."""
    return (_drive(shipped_model, shipped_config, None, (0.2, 0.0), 5.0),
            _drive(shipped_model, shipped_config, None, (0.0, 1.0), 10.0))


def _distance(s: Sample) -> tuple[float, float]:
    return math.hypot(s.x, s.y), math.hypot(s.odom_x, s.odom_y)


def test_a_bigger_wheel_goes_further_than_odometry_says(shipped_model, shipped_config):
    end = _drive(shipped_model, shipped_config, Variation(wheel_radius=1.1), (0.2, 0.0), 5.0)
    true, odom = _distance(end)
    assert true / odom == pytest.approx(1.1, rel=2e-3)
    assert end.z == pytest.approx(0.1 * 0.025, abs=5e-4)  # base_link raised by 2.5 mm


def test_encoders_off_scale_make_odometry_off_scale(shipped_model, shipped_config, nominal):
    variation = Variation(left_encoder_scale=1.1, right_encoder_scale=1.1)
    end = _drive(shipped_model, shipped_config, variation, (0.2, 0.0), 5.0)
    true, odom = _distance(end)
    assert odom / true == pytest.approx(1.1, rel=2e-3)
    # the PID holds the counted ticks, so the car itself goes slower: by up to 1 / 1.1, less
    # where the firmware's dead band lets the wheels rest (measured: 0.94 times the distance)
    assert 0.98 / 1.1 < true / _distance(nominal[0])[0] < 0.97


def test_unequal_encoders_curve_the_odometry_of_a_straight_run(shipped_model, shipped_config):
    """Within the firmware's dead band the PID does not correct a 5 % count difference: the car
    goes straight and its odometry turns away from the side that counts more."""
    end = _drive(shipped_model, shipped_config, Variation(left_encoder_scale=1.05), (0.2, 0.0),
                 5.0)
    assert abs(end.yaw) < 0.01
    assert end.odom_theta == pytest.approx(-0.05 * 0.87 / shipped_config.base_width_m, rel=0.1)


def test_a_wider_track_turns_less_and_odometry_overstates_more(shipped_model, shipped_config,
                                                               nominal):
    end = _drive(shipped_model, shipped_config, Variation(track=1.2), (0.0, 1.0), 10.0)
    spin = nominal[1]
    assert end.odom_theta / end.yaw == pytest.approx(1.2 * spin.odom_theta / spin.yaw,
                                                     rel=0.01)


@pytest.mark.parametrize("variation", [Variation(latency=1), Variation(latency=3)])
def test_latency_delays_every_command_by_whole_periods(shipped_model, shipped_config,
                                                       variation):
    """Kinematic mode (odometry = the commanded twist): the first motion comes k updates late."""
    sim = Simulator()
    try:
        robot = SmartCarRobot(sim, shipped_model, shipped_config, mode="sim")
        robot.vary(variation)
        robot.spawn()
        samples = run(robot, hold((0.2, 0.0), 1.0, 10) + hold((0.0, 0.0), 1.0, 10))
    finally:
        sim.close()
    k = variation.latency
    xs = [round(s.odom_x, 9) for s in samples]
    assert xs[:k + 1] == [0.0] * k + [0.02]  # 0.2 m/s for one 0.1 s period
    assert xs[-1] == pytest.approx(0.2)  # 10 periods of motion in all, just later
    assert xs[k + 8] < xs[k + 9] == xs[k + 10]  # and the stop k periods late


def test_motor_factors_reach_the_motor_model_and_the_gearbox_registry(shipped_model,
                                                                      shipped_config):
    sim = Simulator()
    try:
        robot = SmartCarRobot(sim, shipped_model, shipped_config)
        robot.vary(Variation(stall_torque=0.5, no_load_speed=2.0, gearbox_friction=1.5,
                             reflected_inertia=2.0))
        robot.spawn()
        motor, nominal_motor = robot.config.motor, shipped_config.motor
        assert motor.stall_torque_nm == 0.5 * nominal_motor.stall_torque_nm
        assert motor.no_load_speed_rad_s == 2.0 * nominal_motor.no_load_speed_rad_s
        assert robot.base.motor.config is motor
        # force-limited: kept by the simulator, re-sent when the time step changes
        _, _, _, forces = sim._motors[("smartcar", "gearbox")]
        assert sum(forces) * 2 / len(forces) == pytest.approx(1.5 * 0.03)
        wheel = robot.wheel_joint_indices[0]
        inertia = robot.body.dynamics(wheel).inertia_diagonal
        assert max(inertia) == pytest.approx(3.1e-5 + 0.5 * 2.0 * 1.8e-3, rel=0.01)
        assert robot.config.base_width_m == shipped_config.base_width_m  # YAML kept
    finally:
        sim.close()


def test_masses_and_wheel_friction_are_set_before_the_robot_settles(shipped_model,
                                                                   shipped_config):
    sim = Simulator()
    try:
        robot = SmartCarRobot(sim, shipped_model, shipped_config)
        robot.spawn()
        base, wheel = robot.body.dynamics(BASE), robot.body.dynamics(robot.wheel_joint_indices[1])
        sim.reset()
        robot.vary(Variation(base_mass=1.5, wheel_mass=0.5, wheel_friction=0.7))
        robot.spawn()
        base2 = robot.body.dynamics(BASE)
        wheel2 = robot.body.dynamics(robot.wheel_joint_indices[1])
        assert base2.mass_kg == pytest.approx(1.5 * base.mass_kg)
        assert np.allclose(base2.inertia_diagonal, np.array(base.inertia_diagonal) * 1.5)
        assert wheel2.mass_kg == pytest.approx(0.5 * wheel.mass_kg)
        assert wheel2.lateral_friction == pytest.approx(0.7 * wheel.lateral_friction)
        sim.reset()
        robot.vary(None)  # back to the model as written
        robot.spawn()
        assert robot.body.dynamics(BASE) == base
    finally:
        sim.close()


def test_ground_friction_is_set_on_the_plane(shipped_model, shipped_config):
    sim = Simulator()
    try:
        robot = SmartCarRobot(sim, shipped_model, shipped_config)
        spec = Randomization.from_spec({"ground_friction": 0.6, "base_mass": 1.2})
        draw = spec.apply(np.random.default_rng(0), sim, robot)
        robot.spawn(*draw.start_pose)
        assert sim.body("plane").dynamics(BASE).lateral_friction == pytest.approx(0.6)
        assert robot.variation.base_mass == 1.2
    finally:
        sim.close()


def test_heavier_and_weaker_robots_are_slower_to_turn(shipped_model, shipped_config, nominal):
    heavy = _drive(shipped_model, shipped_config, Variation(base_mass=2.0), (0.0, 1.0), 10.0)
    assert heavy.yaw < 0.97 * nominal[1].yaw


# -- the parts ---------------------------------------------------------------------------------
def test_a_faulty_encoder_without_faults_counts_as_the_plain_one():
    plain, faulty = WheelEncoder(0.025, 4100), FaultyEncoder(0.025, 4100)
    for encoder in (plain, faulty):
        encoder.reset(0.3)
    for angle in np.linspace(-50, 400, 2001):
        assert faulty.count(angle) == plain.count(angle)
    # so it says it is exact (a batch then counts it in arrays); any fault says it is not
    assert plain.exact and faulty.exact
    rng = np.random.default_rng(0)
    for fault in ({"scale": 1.02}, {"noise_ticks": 0.5}, {"slip": 0.01}):
        assert not FaultyEncoder(0.025, 4100, rng=rng, **fault).exact, fault


def test_encoder_scale_noise_and_slip_are_measured_as_asked():
    turns = np.linspace(0, 400, 4001)  # 4000 readings, 10 m of travel at r = 25 mm
    scaled = FaultyEncoder(0.025, 4100, scale=1.05)
    scaled.reset(0.0)
    assert scaled.count(400.0) == math.floor(400 * 0.025 * 4100 * 1.05)

    noisy = FaultyEncoder(0.025, 4100, noise_ticks=2.0, rng=np.random.default_rng(1))
    noisy.reset(0.0)
    errors = np.array([noisy.count(a) - math.floor(a * 0.025 * 4100) for a in turns])
    assert abs(errors.mean()) < 0.15 and errors.std() == pytest.approx(2.0, rel=0.1)

    finals = []
    for seed in range(60):
        slipping = FaultyEncoder(0.025, 4100, slip=0.05, rng=np.random.default_rng(seed))
        slipping.reset(0.0)
        counts = [slipping.count(a) for a in turns]
        finals.append(counts[-1] - 41000)
    # each of 4000 increments of 10.25 ticks is off by 5 % at random: sqrt(4000)*0.51 ticks
    assert np.std(finals) == pytest.approx(math.sqrt(4000) * 10.25 * 0.05, rel=0.25)

    a = FaultyEncoder(0.025, 4100, noise_ticks=1, slip=0.01, rng=np.random.default_rng(3))
    b = FaultyEncoder(0.025, 4100, noise_ticks=1, slip=0.01, rng=np.random.default_rng(3))
    assert [a.count(t) for t in turns[:200]] == [b.count(t) for t in turns[:200]]


@pytest.mark.parametrize("kwargs, match", [
    ({"scale": 0.0}, "scale must be a finite number > 0"),
    ({"noise_ticks": -1.0}, "noise_ticks must be a finite number >= 0"),
    ({"slip": float("nan")}, "slip must be"),
    ({"slip": 0.1}, "needs a seeded rng"),
])
def test_faulty_encoder_refuses_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FaultyEncoder(0.025, 4100, **kwargs)


def test_command_delay_hands_messages_over_in_order_after_whole_periods():
    delay = CommandDelay(2, 100)
    delay.publish(1.0, 0.0, 0)
    delay.publish(2.0, 0.0, 100)
    assert delay.arrivals(100) == []
    assert delay.arrivals(200) == [(1.0, 0.0)]
    assert delay.arrivals(350) == [(2.0, 0.0)] and len(delay) == 0
    delay.publish(3.0, 0.0, 400)
    delay.clear()
    assert delay.arrivals(10_000) == []
    with pytest.raises(ValueError, match=r"latency must be an integer in 0\.\.10"):
        CommandDelay(11, 100)


def test_dynamics_facade_scales_and_sets(shipped_model, shipped_config):
    sim = Simulator()
    try:
        robot = SmartCarRobot(sim, shipped_model, shipped_config)
        robot.spawn()
        body = robot.body
        before = body.dynamics(BASE)
        scale_mass(body, [BASE], 2.0)
        assert body.dynamics(BASE).mass_kg == pytest.approx(2 * before.mass_kg)
        set_lateral_friction(body, [BASE], 0.4)
        scale_lateral_friction(body, [BASE], 0.5)
        assert body.dynamics(BASE).lateral_friction == pytest.approx(0.2)
        for call in (lambda: scale_mass(body, [BASE], 0.0),
                     lambda: set_lateral_friction(body, [BASE], float("inf")),
                     lambda: scale_lateral_friction(body, [BASE], True)):
            with pytest.raises(ValueError, match="must be a finite number > 0"):
                call()
    finally:
        sim.close()
