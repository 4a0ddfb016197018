"""Properties of the emulation for arbitrary gains, targets, encoder motion and commands."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from smartcar_gym.controller import ArbotixBoard, ArbotixConfig, DiffController
from smartcar_gym.controller._cint import wrap_int32

INT16 = st.integers(-(2**15), 2**15 - 1)
gains = st.tuples(
    st.integers(0, 255), st.integers(0, 255), st.integers(0, 255), st.integers(1, 255)
)
write_op = st.tuples(st.just("write"), INT16, INT16)
tick_op = st.tuples(
    st.just("tick"), st.integers(-(2**31), 2**31 - 1), st.integers(-(2**31), 2**31 - 1)
)
small_tick_op = st.tuples(st.just("tick"), st.integers(-500, 500), st.integers(-500, 500))


@settings(max_examples=300, deadline=None)
@given(gains=gains, ops=st.lists(st.one_of(write_op, tick_op, small_tick_op), max_size=60))
def test_pwm_never_leaves_the_byte_range(gains, ops):
    board = ArbotixBoard()
    board.setup(*gains)
    counts = [0, 0]
    now_ms = 0
    for op in ops:
        if op[0] == "write":
            board.write(op[1], op[2], (counts[0], counts[1]))
        else:
            counts = [wrap_int32(counts[0] + op[1]), wrap_int32(counts[1] + op[2])]
            now_ms += 34
            board.tick(now_ms, (counts[0], counts[1]))
        for wheel in (board.left, board.right):
            assert -255 <= wheel.output <= 255
            assert -(2**15) <= wheel.ierror < 2**15 and -(2**15) <= wheel.prev_err < 2**15
        if not board.moving:
            assert board.pwm == (0, 0)


@settings(max_examples=200, deadline=None)
@given(
    ticks_meter=st.floats(100.0, 1e5),
    base_width=st.floats(0.05, 2.0),
    deltas=st.lists(st.integers(-10_000, 10_000), max_size=40),
)
def test_straight_run_odometry_is_exact(ticks_meter, base_width, deltas):
    config = ArbotixConfig(ticks_meter=ticks_meter, base_width_m=base_width)
    c = DiffController(config, "hardware")
    count = 7  # any start count: the first sample is ignored
    odom = c.update(0.1, (count, count))
    expected = 0.0
    for k, delta in enumerate(deltas, start=2):
        count += delta
        odom = c.update(k / 10, (count, count))
        expected += delta / ticks_meter
    assert odom.x == expected
    assert odom.y == 0.0 and odom.theta == 0.0


@settings(max_examples=200, deadline=None)
@given(v=st.floats(-2.0, 2.0), w=st.floats(-5.0, 5.0))
def test_wheel_targets_truncate_toward_zero_symmetrically(v, w):
    config = ArbotixConfig(ticks_meter=4100, base_width_m=0.26)
    forward, backward = DiffController(config, "hardware"), DiffController(config, "hardware")
    forward.cmd_vel(v, w, 0.0)
    backward.cmd_vel(-v, -w, 0.0)
    assert (forward.v_des_left, forward.v_des_right) == (
        -backward.v_des_left, -backward.v_des_right
    )
    exact_left = (v - w * 0.26 / 2) * 4100 / 30
    assert abs(forward.v_des_left) <= abs(exact_left) < abs(forward.v_des_left) + 1 + 1e-9


@settings(max_examples=200, deadline=None)
@given(
    accel_limit=st.floats(0.01, 2.0),
    commands=st.lists(st.tuples(st.floats(-1, 1), st.floats(-3, 3)), min_size=1, max_size=20),
)
def test_ramp_steps_never_exceed_max_accel(accel_limit, commands):
    config = ArbotixConfig(ticks_meter=4100, base_width_m=0.26, accel_limit=accel_limit)
    c = DiffController(config, "hardware")
    previous = (0, 0)
    for k, (v, w) in enumerate(commands, start=1):
        c.cmd_vel(v, w, k / 10)
        c.update(k / 10 + 0.05, (0, 0))
        for before, after, target in zip(previous, c.last_write, (c.v_des_left, c.v_des_right),
                                         strict=True):
            assert abs(after - before) <= config.max_accel
            assert abs(after - target) <= abs(before - target)
        previous = c.last_write
