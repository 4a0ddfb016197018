"""The host-side DiffController: cmd_vel conversion, ramp, timeout, odometry in both modes."""

from __future__ import annotations

import dataclasses
import math

import pytest

from smartcar_gym.controller import ArbotixConfig, DiffController, Odometry

SEED = ArbotixConfig(ticks_meter=4100, base_width_m=0.26, kp=12, kd=12, accel_limit=1.0)


def controller(mode="hardware", **overrides) -> DiffController:
    return DiffController(dataclasses.replace(SEED, **overrides), mode)


@pytest.mark.parametrize(
    ("twist", "ticks"),
    [
        ((0.2, 0.0), (27, 27)),  # 0.2*4100/30 = 27.33
        ((0.5, 0.0), (68, 68)),  # 68.33
        ((0.0, 1.0), (-17, 17)),  # 0.13*4100/30 = 17.77
        ((0.2, 0.5), (18, 36)),  # 0.135 -> 18.45, 0.265 -> 36.2
        ((-0.1, 0.0), (-13, -13)),  # -13.67 truncates toward zero
        ((0.0, 0.05), (0, 0)),  # below one tick/frame: no turn at all
    ],
)
def test_cmd_vel_to_ticks_per_frame(twist, ticks):
    c = controller()
    c.cmd_vel(*twist, now_s=0.0)
    assert (c.v_des_left, c.v_des_right) == ticks
    assert c.update(0.1, (0, 0)) is c.odometry
    assert c.last_write == ticks  # max_accel 410: no ramp


def test_sim_mode_stores_the_twist_as_is():
    c = controller("sim")
    c.cmd_vel(0.123, -0.45, now_s=0.3)
    assert (c.dx, c.dr, c.last_cmd) == (0.123, -0.45, 0.3)
    assert (c.v_des_left, c.v_des_right) == (0, 0)
    c.update(0.4)
    assert c.last_write is None


def test_cmd_vel_rejects_non_finite():
    with pytest.raises(ValueError):
        controller().cmd_vel(math.nan, 0.0, 0.0)


def test_ramp_with_small_max_accel():
    c = controller(accel_limit=0.05)  # max_accel = int(0.05*4100/10) = 20
    assert c.max_accel == 20
    c.cmd_vel(0.5, 0.0, 0.0)  # 68
    writes = [c.update(0.1 * k, (0, 0)) and c.last_write[0] for k in range(1, 6)]
    assert writes == [20, 40, 60, 68, 68]
    c.cmd_vel(-0.1, 0.0, 0.5)  # -13: the ramp passes through zero
    writes = [c.update(0.5 + 0.1 * k, (0, 0)) and c.last_write[0] for k in range(1, 7)]
    assert writes == [48, 28, 8, -12, -13, -13]


def test_timeout_stops_hardware_after_one_second():
    c = controller()
    c.cmd_vel(0.2, 0.0, 0.0)
    writes = {k: (c.update(k / 10, (0, 0)), c.last_write)[1] for k in range(1, 13)}
    assert writes[10] == (27, 27)  # 1.0 > 0.0 + 1.0 is false
    assert writes[11] == (0, 0) and writes[12] == (0, 0)
    assert (c.v_des_left, c.v_des_right) == (0, 0)


def test_timeout_ramps_down_with_small_max_accel():
    c = controller(accel_limit=0.05)
    c.cmd_vel(0.5, 0.0, 0.0)
    lefts = [(c.update(k / 10, (0, 0)), c.last_write[0])[1] for k in range(1, 16)]
    assert lefts[9:] == [68, 48, 28, 8, 0, 0]


def test_timeout_uses_exact_time_not_float_noise():
    c = controller()
    c.cmd_vel(0.2, 0.0, 0.0)
    now = 0.0
    for _ in range(10):
        now += 0.1  # 0.9999999999999999
    c.update(now, (0, 0))
    assert c.last_write == (27, 27)
    c.update(1.0000001, (0, 0))
    assert c.last_write == (0, 0)


def test_sim_mode_keeps_moving_after_the_timeout():
    c = controller("sim")
    c.cmd_vel(0.5, 0.0, 0.0)
    for k in range(1, 31):
        odom = c.update(k / 10)
    assert odom.v == 0.5 and odom.x == pytest.approx(1.5)


def test_sim_odometry_by_hand():
    c = controller("sim")  # constructed at t = 0
    c.cmd_vel(0.5, 1.0, 0.05)  # mid-interval: applies to the whole first interval
    odom = c.update(0.1)
    assert (odom.x, odom.y, odom.theta) == pytest.approx((0.05, 0.0, 0.1))
    odom = c.update(0.3)  # 0.2 s at heading 0.1
    assert odom.x == pytest.approx(0.05 + 0.1 * math.cos(0.1))  # 0.1495004
    assert odom.y == pytest.approx(0.1 * math.sin(0.1))  # 0.0099833
    assert odom.theta == pytest.approx(0.3)
    assert (odom.v, odom.omega, odom.stamp_s) == (0.5, 1.0, 0.3)


def test_sim_theta_is_not_wrapped():
    c = controller("sim")
    c.cmd_vel(0.0, 4.0, 0.0)
    for k in range(1, 11):
        odom = c.update(k / 10)
    assert odom.theta == pytest.approx(4.0)


def test_hardware_odometry_first_sample_and_straight():
    c = controller()
    odom = c.update(0.1, (500, 700))  # first read: no motion, whatever the counts
    assert (odom.x, odom.y, odom.theta, odom.v, odom.omega) == (0, 0, 0, 0, 0)
    assert (c.enc_left, c.enc_right) == (500, 700)
    odom = c.update(0.2, (910, 1110))  # 410 ticks each = 0.1 m in 0.1 s
    assert (odom.x, odom.y, odom.theta) == pytest.approx((0.1, 0.0, 0.0))
    assert (odom.v, odom.omega) == pytest.approx((1.0, 0.0))


def test_hardware_odometry_theta_minus_dtheta_quirk():
    c = controller(ticks_meter=1000, base_width_m=0.5)
    c.update(0.1, (0, 0))
    # d_l = 0.1, d_r = 0.2: d = 0.15, dtheta = 0.1/0.5 = 0.2.
    odom = c.update(0.2, (100, 200))
    assert odom.x == pytest.approx(0.15 * math.cos(0.2))  # 0.1470100
    assert odom.y == pytest.approx(-0.15 * math.sin(0.2))  # -0.0298004: along theta - dtheta
    midpoint_y = 0.15 * math.sin(0.1)  # +0.0149750: what the midpoint formula would give
    assert odom.y < 0 < midpoint_y
    assert (odom.theta, odom.v, odom.omega) == pytest.approx((0.2, 1.5, 2.0))
    odom = c.update(0.3, (200, 300))  # straight 0.1 m at heading 0.2
    assert odom.x == pytest.approx(0.15 * math.cos(0.2) + 0.1 * math.cos(0.2))  # 0.2450167
    assert odom.y == pytest.approx(-0.15 * math.sin(0.2) + 0.1 * math.sin(0.2))  # -0.0099335
    assert odom.theta == pytest.approx(0.2)


def test_elapsed_is_measured_from_construction():
    c = DiffController(SEED, "hardware", now_s=5.0)
    c.update(5.5, (0, 0))
    odom = c.update(5.75, (205, 205))  # 0.05 m in 0.25 s
    assert odom.v == pytest.approx(0.2)
    s = DiffController(SEED, "sim", now_s=5.0)
    s.cmd_vel(1.0, 0.0, 5.0)
    assert s.update(5.5).x == pytest.approx(0.5)


def test_read_failure_skips_odometry_timeout_and_write():
    c = controller()
    c.cmd_vel(0.2, 0.0, 0.0)
    before = c.update(0.1, (0, 0))
    assert c.update(2.0, None) is before  # upstream: "Could not update encoders", return
    assert c.last_write is None and c.then == 2.0
    assert (c.v_des_left, c.v_des_right) == (27, 27)


def test_zero_elapsed_and_time_going_backwards():
    c = controller()
    c.update(0.1, (0, 0))
    assert c.update(0.1, (10, 10)).v == 0.0  # upstream would divide by zero
    with pytest.raises(ValueError, match="backwards"):
        c.update(0.05, (0, 0))


def test_invalid_mode():
    with pytest.raises(ValueError, match="mode"):
        DiffController(SEED, "fake")


def test_odometry_message():
    odom = Odometry(12.5, "odom", "base_link", 1.0, -2.0, math.pi / 2, 0.3, -0.1)
    assert odom.quaternion == pytest.approx((0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)))
    msg = odom.as_ros_dict()
    assert msg["header"] == {"stamp": {"secs": 12, "nsecs": 500_000_000}, "frame_id": "odom"}
    assert msg["child_frame_id"] == "base_link"
    assert msg["pose"]["pose"]["position"] == {"x": 1.0, "y": -2.0, "z": 0.0}
    assert msg["pose"]["pose"]["orientation"]["w"] == pytest.approx(math.sqrt(0.5))
    assert msg["twist"]["twist"]["linear"] == {"x": 0.3, "y": 0.0, "z": 0.0}
    assert msg["twist"]["twist"]["angular"] == {"x": 0.0, "y": 0.0, "z": -0.1}
    assert msg["pose"]["covariance"] == [0.0] * 36 == msg["twist"]["covariance"]


def test_frames_come_from_the_config():
    c = controller(base_frame_id="base_footprint", odom_frame_id="world")
    odom = c.update(0.1, (0, 0))
    assert (odom.frame_id, odom.child_frame_id) == ("world", "base_footprint")
