"""The ArbotiX firmware PID: integer arithmetic, clamping, start/stop, frame timing."""

from __future__ import annotations

import numpy as np
import pytest

from smartcar_gym.controller import ArbotixBoard, WheelPID
from smartcar_gym.controller._cint import c_div, wrap_int16, wrap_int32


def armed_board(gains=(12, 12, 0, 50), targets=(27, 27), encoders=(0, 0)) -> ArbotixBoard:
    board = ArbotixBoard()
    board.setup(*gains)
    board.write(*targets, encoders)
    return board


def test_c_integer_helpers():
    assert c_div(-336, 50) == -6 and -336 // 50 == -7  # C truncates, Python floors
    assert c_div(336, 50) == 6 and c_div(-49, 50) == 0 and c_div(7, -2) == -3
    assert wrap_int16(32768) == -32768 and wrap_int16(-32769) == 32767 and wrap_int16(-5) == -5
    assert wrap_int32(2**31) == -(2**31) and wrap_int32(2**32 + 7) == 7


def test_boot_gains_until_setup():
    board = ArbotixBoard()
    assert (board.kp, board.kd, board.ki, board.ko) == (25, 30, 0, 100)
    board.setup(12, 12, 0, 50)
    assert (board.kp, board.kd, board.ki, board.ko) == (12, 12, 0, 50)


@pytest.mark.parametrize(
    "gains", [(256, 0, 0, 50), (12, -1, 0, 50), (12, 12, 1.5, 50), (1, 1, 0, 0)]
)
def test_setup_rejects_non_bytes(gains):
    with pytest.raises(ValueError):
        ArbotixBoard().setup(*gains)


def test_pid_frames_by_hand():
    # Kp = Kd = 12, Ki = 0, Ko = 50; target 27 ticks/frame; armed at counts (1000, -50).
    board = armed_board(encoders=(1000, -50))
    assert board.left.prev_enc == 1000 and board.right.prev_enc == -50
    # Frame 1, wheels still: e = 27, du = (12*27 + 12*(27-0))/50 = 648/50 -> 12.
    assert board.tick(1, (1000, -50))
    assert board.pwm == (12, 12)
    assert (board.left.prev_err, board.left.ierror) == (27, 27)
    # Frame 2, moved 5: e = 22, du = (264 + 12*(22-27))/50 = 204/50 -> 4; u = 16.
    assert board.tick(40, (1005, -45))
    assert board.pwm == (16, 16)
    assert (board.left.prev_err, board.left.ierror, board.left.prev_enc) == (22, 49, 1005)
    # Frame 3, moved 30: e = -3, du = (-36 + 12*(-3-22))/50 = -336/50 -> -6 (C), not -7; u = 10.
    assert board.tick(80, (1035, -15))
    assert board.pwm == (10, 10)
    assert (board.left.prev_err, board.left.ierror) == (-3, 46)
    # Frame 4, moved 28: e = -1, du = (-12 + 12*(-1+3))/50 = 12/50 -> 0; u = 10.
    assert board.tick(120, (1063, 13))
    assert board.pwm == (10, 10)
    assert (board.left.prev_err, board.left.ierror) == (-1, 45)


def test_wheels_are_independent_left_then_right():
    board = armed_board(targets=(27, -27))
    board.tick(1, (0, 0))
    assert board.pwm == (12, -12)  # -648/50 -> -12 (floor would give -13)


def test_integral_term_uses_ierror_before_this_frame():
    # Kp = Kd = 0, Ki = 10, Ko = 3; target 5; wheels still: e = 5 every frame.
    board = armed_board(gains=(0, 0, 10, 3), targets=(5, 5))
    outputs = []
    for now_ms in (1, 40, 80):
        board.tick(now_ms, (0, 0))
        outputs.append((board.left.output, board.left.ierror))
    # du = 10*Ierror/3: 0, 50/3 -> 16, 100/3 -> 33.
    assert outputs == [(0, 5), (16, 10), (49, 15)]


def test_clamp_and_ierror_frozen_while_clamped():
    # Kp = 100, Ko = 1: one tick of error is 100 PWM.
    board = armed_board(gains=(100, 0, 0, 1), targets=(3, -3))
    board.tick(1, (0, 0))  # e = +-3: du = +-300 -> clamped
    assert board.pwm == (255, -255)
    assert (board.left.ierror, board.right.ierror) == (0, 0)  # frozen, not +-3
    board.tick(40, (3, -3))  # e = 0: u stays at the limit (still "clamped")
    assert board.pwm == (255, -255)
    board.tick(80, (8, -8))  # e = -+2: du = -+200 -> 55, -55, inside the limits
    assert board.pwm == (55, -55)
    assert (board.left.ierror, board.right.ierror) == (-2, 2)  # accumulates again


def test_stop_clears_pid_state_but_keeps_prev_enc():
    board = armed_board()
    board.tick(1, (0, 0))
    board.tick(40, (5, 5))
    board.write(0, 0, (9, 9))
    assert board.pwm == (0, 0)
    assert not board.moving and not board.pid_mode
    for wheel in (board.left, board.right):
        assert (wheel.velocity, wheel.prev_err, wheel.ierror, wheel.output) == (0, 0, 0, 0)
        assert wheel.prev_enc == 5
    assert not board.tick(1000, (50, 50))  # idle: no frames while stopped
    assert board.pwm == (0, 0)


def test_rearm_from_rest_sets_prev_enc_and_nonzero_change_keeps_state():
    board = armed_board()
    board.tick(1, (0, 0))
    board.write(0, 0, (300, 400))
    board.write(10, 10, (2000, 2100))  # from rest: arm
    assert board.moving and (board.left.prev_enc, board.right.prev_enc) == (2000, 2100)
    board.tick(2000, (2000, 2100))
    assert board.pwm == (4, 4)  # fresh start: 24*10/50 = 4.8 -> 4
    board.write(20, 30, (9999, 9999))  # non-zero -> non-zero: only the targets change
    assert (board.left.prev_enc, board.right.prev_enc) == (2000, 2100)
    assert (board.left.velocity, board.right.velocity) == (20, 30)
    assert (board.left.ierror, board.left.output) == (10, 4)


def test_one_zero_target_regulates_that_wheel_to_zero():
    board = armed_board(targets=(0, 27))
    assert board.moving
    board.tick(1, (4, 0))  # left moved 4 with target 0: e = -4, du = -96/50 -> -1
    assert board.pwm == (-1, 12)


def test_frames_are_at_least_frame_ms_plus_one_apart():
    board = armed_board()
    assert not board.tick(0, (0, 0))  # millis() > f_time (0) is strict
    assert board.tick(1, (0, 0)) and board.f_time == 34
    assert not board.tick(34, (0, 0))
    assert board.tick(35, (0, 0)) and board.f_time == 68
    ran = [ms for ms in range(36, 300) if board.tick(ms, (0, 0))]
    assert ran == [69, 103, 137, 171, 205, 239, 273]  # every 34 ms


def test_frame_ms_is_configurable():
    board = ArbotixBoard(frame_ms=20)
    board.write(5, 5, (0, 0))
    assert [ms for ms in range(0, 50) if board.tick(ms, (0, 0))] == [1, 22, 43]


def test_targets_are_16_bit_on_the_wire():
    board = ArbotixBoard()
    board.write(65535, 40000, (0, 0))
    assert (board.left.velocity, board.right.velocity) == (-1, 40000 - 65536)
    board.write(65536, 0, (0, 0))  # 0x10000 & 0xffff == 0: a stop
    assert not board.moving


def test_encoder_difference_wraps_like_long():
    board = armed_board(targets=(1, 1), encoders=(2**31 - 1, 0))
    board.tick(1, (-(2**31), 0))  # counter wrapped: one tick forward
    assert board.left.prev_err == 0  # e = 1 - 1


def test_state_exposes_internals():
    board = armed_board()
    board.tick(1, (0, 0))
    state = board.state()
    assert state["gains"] == (12, 12, 0, 50) and state["pwm"] == (12, 12)
    assert state["left"] == {"velocity": 27, "encoder": 0, "prev_enc": 0, "prev_err": 27,
                             "ierror": 27, "output": 12}
    assert state["moving"] and state["f_time_ms"] == 34


def _reference_do_pid(board: ArbotixBoard, p: WheelPID) -> None:
    """``DoPid`` through ``_cint``'s calls, as it was written before it was inlined."""
    perror = wrap_int32(p.velocity - wrap_int32(p.encoder - p.prev_enc))
    numerator = wrap_int32(wrap_int32(board.kp * perror)
                           + wrap_int32(board.kd * wrap_int32(perror - p.prev_err))
                           + wrap_int16(board.ki * p.ierror))
    output = wrap_int32(c_div(numerator, board.ko) + p.output)
    p.prev_err = wrap_int16(perror)
    p.prev_enc = p.encoder
    if output >= 255:
        output = 255
    elif output <= -255:
        output = -255
    else:
        p.ierror = wrap_int16(p.ierror + perror)
    p.output = output


def test_the_inlined_pid_is_the_cint_arithmetic_on_random_and_wrapping_states():
    rng = np.random.default_rng(0)
    edges = [0, 1, -1, 2**15 - 1, -(2**15), 2**31 - 1, -(2**31), 2**31, 2**40]
    for _ in range(5000):
        board = ArbotixBoard()
        board.kp, board.kd, board.ki = (int(v) for v in rng.integers(0, 256, 3))
        board.ko = int(rng.integers(1, 256))
        pick = [int(v) for v in rng.integers(-(2**33), 2**33, 5)]
        state = [int(rng.choice(edges)) if rng.random() < 0.3 else v for v in pick]
        fields = dict(velocity=state[0] % 2**16 - 2**15, encoder=state[1], prev_enc=state[2],
                      prev_err=state[3] % 2**16 - 2**15, ierror=state[4] % 2**16 - 2**15,
                      output=int(rng.integers(-255, 256)))
        fast, reference = WheelPID(**fields), WheelPID(**fields)
        board._do_pid(fast)
        _reference_do_pid(board, reference)
        assert fast == reference, fields
