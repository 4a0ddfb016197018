"""The emulated ArbotiX base driving the smartcar in pybullet (hardware mode)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from smartcar_gym.calibration.maneuvers import circle_centre_drift, hold, run
from smartcar_gym.envs.robots import SmartCarRobot, drive


def _turn(robot: SmartCarRobot, angular_z: float, seconds: float):
    """Turn in place: (true unwrapped yaw turned, odometry yaw, the recorded samples)."""
    start = robot.pose().yaw
    samples = run(robot, hold((0.0, angular_z), seconds, robot.config.rate_hz))
    return samples[-1].yaw - start, samples[-1].odom_theta, samples


@pytest.fixture(params=["sphere", "urdf"])
def contact_robot(request, sim, shipped_model, shipped_config) -> SmartCarRobot:
    """The shipped car in hardware mode with each wheel contact model (sphere: the default)."""
    robot = SmartCarRobot(sim, shipped_model, shipped_config, wheel_contact=request.param)
    robot.spawn()
    return robot


# Measured with each wheel contact model: steady speed at cmd_vel 0.2 m/s (m/s), and how much
# odometry overstates a turn in place at 1 rad/s (odometry yaw / true yaw over 30 s).
MEASURED = {"sphere": (0.2020, 1.265), "urdf": (0.2004, 1.335)}


def test_straight_cmd_vel_reaches_a_steady_speed_and_odometry_follows(contact_robot):
    robot = contact_robot
    config = robot.config
    speeds = []
    for step in range(50):  # cmd_vel (0.2, 0) held for 5 s
        odom = drive(robot, 0.2, 0.0)
        if step >= 30:
            speeds.append(robot.joint_states().velocity.mean() * robot.model.wheel_radius_m)
    # The driver asks for trunc(0.2 * 4100 / 30) = 27 ticks per 1/30 s frame (0.1976 m/s);
    # the board counts them per 34 ms frame.
    assert robot.base.state()["v_des"] == (27, 27)
    speed = float(np.mean(speeds))
    assert np.std(speeds) < 0.01 * speed  # steady
    ticks_per_frame = speed * config.ticks_meter * (config.frame_ms + 1) / 1000
    # The firmware's integer PID leaves an error alone while |Kp*e + Kd*de| < Ko, i.e.
    # |e| <= 4 ticks/frame with Kp = Kd = 12, Ko = 50: the steady speed sits in that dead band.
    dead_band = config.ko / (config.kp + config.kd) * 2
    assert abs(ticks_per_frame - 27) <= dead_band
    # Where in that band it rests depends on the plant (reflected_inertia, wheel contact) and a
    # little on the stepping. With the shipped plant it is within 5 % of what the driver means
    # (27 ticks per 1/30 s = 0.1976 m/s) and of the cmd_vel: measured 0.2020 m/s with sphere
    # wheels (2.2 % and 1.0 % above them), 0.2004 m/s with the URDF's cylinders (1.4 % and
    # 0.2 %); at fixed 2 ms steps 0.2036 and 0.2020.
    assert speed == pytest.approx(27 * 30 / config.ticks_meter, rel=0.05)
    assert speed == pytest.approx(0.2, rel=0.05)
    # pinned, so that a change of the plant shows
    assert speed == pytest.approx(MEASURED[robot.wheel_contact][0], abs=0.001)
    # Odometry from the encoders follows the ground-truth distance (no slip going straight).
    pose = robot.pose()
    assert pose.x > 0.85  # 0.892 m (sphere), 0.886 m (urdf): 5 s from rest
    assert odom.x == pytest.approx(pose.x, rel=0.05)
    assert abs(odom.y) < 0.01 and abs(pose.y) < 0.02


def test_turning_in_place_keeps_the_centre_and_odometry_overestimates_rotation(contact_robot):
    yaw, odom_yaw, samples = _turn(contact_robot, 1.0, 30.0)
    revolutions, drift = circle_centre_drift(samples)
    # it does turn: measured 3.22 revolutions in 30 s (sphere), 3.10 (urdf)
    assert revolutions > 2.5
    # It circles a point a few cm off base_link, and that point moves under 5 cm per revolution
    # (measured 0.08 cm/rev with sphere wheels, 4.3 cm/rev with cylinders).
    assert drift < 0.05
    offsets = np.hypot([s.x for s in samples], [s.y for s in samples])
    assert offsets.max() < 0.25
    # Skid steer: the wheels slip sideways, so the body turns less than base_width = 0.26 m
    # implies; odometry (which trusts base_width) overestimates rotation: measured 26.5 %
    # (sphere: 25.6 rad for 20.3), 33.5 % (urdf: 26.0 rad for 19.5). Pinned.
    ratio = odom_yaw / yaw
    assert 1.15 < ratio < 1.45
    assert ratio == pytest.approx(MEASURED[contact_robot.wheel_contact][1], abs=0.01)


def test_effective_base_width_removes_the_heading_drift(sim, shipped_model, shipped_config):
    """Calibrating base_width to the measured effective track (0.329 m) fixes odometry."""
    calibrated = dataclasses.replace(shipped_config, base_width_m=0.33)
    robot = SmartCarRobot(sim, shipped_model, calibrated, mode="hardware")
    robot.spawn()
    yaw, odom_yaw, _ = _turn(robot, 1.0, 10.0)
    assert odom_yaw == pytest.approx(yaw, rel=0.02)  # measured 0.3 % under (0.26 m: 27 % over)


def test_timeout_stops_the_base_after_one_second(hardware_robot):
    robot = hardware_robot
    for _ in range(10):
        drive(robot, 0.3, 0.0)
    assert robot.joint_states().velocity.mean() > 5.0  # rad/s
    # No new cmd_vel: after 1 s the driver's timeout writes (0, 0); the board stops and coasts.
    for _ in range(9):
        drive(robot, None, None)
    assert robot.base.state()["v_des"] == (41, 41)  # 0.3 m/s, still commanded at 0.9 s
    for _ in range(3):
        drive(robot, None, None)
    state = robot.base.state()
    assert state["v_des"] == (0, 0) and state["pwm"] == (0, 0)
    for _ in range(20):
        drive(robot, None, None)
    assert abs(robot.joint_states().velocity.mean()) < 0.2  # rolled to a stop


def test_the_wiring_a_car_batch_reads(hardware_robot):
    """What an engine's car batch reads of the robot (``sim/*/cars.py``): the tutorial's four
    wheels, two a side, each half its side's motor output; the encoders left then right, each
    read forward-positive."""
    robot = hardware_robot
    assert [w.joint for w in robot.wheels] == [
        "left_front_wheel_joint", "left_back_wheel_joint", "right_front_wheel_joint",
        "right_back_wheel_joint"]
    assert robot.wheel_left == [True, True, False, False]
    assert robot.wheel_shares == [0.5] * 4
    assert robot.wheel_signs == [1.0] * 4  # every wheel rolls forward on a positive angle
    assert robot.encoder_signs == (1, 1)
    # the encoders on the front wheels (the default), left then right
    assert robot.encoder_joint_indices == [robot.wheel_joint_indices[0],
                                           robot.wheel_joint_indices[2]]
    left, right = robot.encoder_angles()
    angles, _ = robot.body.joint_states(robot.encoder_joint_indices)
    assert (left, right) == (angles[0] * robot.encoder_signs[0],
                             angles[1] * robot.encoder_signs[1])
