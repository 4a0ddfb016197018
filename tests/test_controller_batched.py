"""BatchedArbotix is the scalar ArbotixBase, bit for bit, for every car and every frame.

N random configurations (gains, Ko, frame length, rate, timeout, ramp, ticks_meter, track,
motor) get random cmd_vel streams, random encoder wheel angle streams (with jumps that wrap the
board's 32-bit counters and targets that wrap its 16-bit ones) and random resets; every
millisecond both emulations get the same calls and every number of their state is compared.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from smartcar_gym.controller import ArbotixBase, ArbotixConfig, MotorConfig, MotorOutput, compiled
from smartcar_gym.controller._cint import c_div as c_div1
from smartcar_gym.controller._cint import wrap_int16 as wrap16
from smartcar_gym.controller._cint import wrap_int32 as wrap32
from smartcar_gym.controller.batched import BatchedArbotix, c_div, wrap_int16, wrap_int32
from smartcar_gym.controller.encoder_faults import FaultyEncoder


class FakeDrive:
    """A WheelDrive whose encoder angles the test sets, recording the motor outputs."""

    def __init__(self) -> None:
        self.angles = (0.0, 0.0)
        self.outputs: tuple[MotorOutput, MotorOutput] | None = None

    def encoder_angles(self) -> tuple[float, float]:
        return self.angles

    def set_motor_output(self, left: MotorOutput, right: MotorOutput) -> None:
        self.outputs = (left, right)


def random_config(rng: np.random.Generator) -> ArbotixConfig:
    ticks_meter = float(rng.choice([4100.0, rng.uniform(50, 2e5), 9e5]))
    return ArbotixConfig(
        ticks_meter=ticks_meter,
        base_width_m=float(rng.uniform(0.05, 1.0)),
        rate_hz=float(rng.choice([10.0, 20.0, 7.3, rng.uniform(2, 60)])),
        timeout_s=float(rng.choice([1.0, 0.25, rng.uniform(0.05, 2.0)])),
        kp=int(rng.integers(0, 256)), kd=int(rng.integers(0, 256)),
        ki=int(rng.integers(0, 256)), ko=int(rng.integers(1, 256)),
        accel_limit=float(rng.uniform(0.01, 20.0)),
        frame_ms=int(rng.integers(1, 60)),
        motor=MotorConfig(stall_torque_nm=float(rng.uniform(0.01, 2.0)),
                          no_load_speed_rad_s=float(rng.uniform(1, 100)),
                          pwm_zero=str(rng.choice(["coast", "brake"]))),
    )


def assert_same(bases: list[ArbotixBase], drives: list[FakeDrive], batch: BatchedArbotix,
                where: str) -> None:
    for i, (base, drive) in enumerate(zip(bases, drives, strict=True)):
        c, b = base.controller, base.board
        odom = base.odometry
        got = (batch.x[i], batch.y[i], batch.theta[i], batch.odom_v[i], batch.odom_w[i],
               batch.stamp[i])
        want = (odom.x, odom.y, odom.theta, odom.v, odom.omega, odom.stamp_s)
        assert got == want, f"{where}, car {i}: odometry {got} != {want}"
        assert tuple(batch.v_des[i]) == (c.v_des_left, c.v_des_right), f"{where}, car {i}"
        assert tuple(batch.v[i]) == (c.v_left, c.v_right), f"{where}, car {i}"
        assert (c.last_write is not None) == batch.wrote[i], f"{where}, car {i}"
        assert batch.last_cmd[i] == c.last_cmd and batch.then[i] == c.then
        assert tuple(batch.ticks[i]) == base.ticks, f"{where}, car {i}: encoder ticks"
        assert (batch.moving[i], batch.pid_mode[i], batch.f_time[i]) == (
            b.moving, b.pid_mode, b.f_time), f"{where}, car {i}: board timing"
        assert tuple(batch.board_gains[i]) == (b.kp, b.kd, b.ki, b.ko)
        for k, p in enumerate((b.left, b.right)):
            got = (batch.velocity[i, k], batch.encoder[i, k], batch.prev_enc[i, k],
                   batch.prev_err[i, k], batch.ierror[i, k], batch.output[i, k])
            want = (p.velocity, p.encoder, p.prev_enc, p.prev_err, p.ierror, p.output)
            assert got == want, f"{where}, car {i}, wheel {k}: PID {got} != {want}"
        assert batch.next_frame_ms()[i] == (b.next_frame_ms() or -1)
        if drive.outputs is not None:
            for k, out in enumerate(drive.outputs):
                assert (batch.drive_torque[i, k], batch.damping[i, k]) == (
                    out.drive_torque_nm, out.damping_nm_s_per_rad), f"{where}, car {i}: motor"
        assert batch.commanded_twist()[0][i] == base.commanded_twist[0]
        assert batch.commanded_twist()[1][i] == base.commanded_twist[1]


def faulty_pair(rng: np.random.Generator, radius: float, ticks_meter: float,
                seed: int) -> tuple[FaultyEncoder, FaultyEncoder]:
    """``Variation.encoders``' pair: off scale, jittered and slipping, one generator."""
    noise, slip = float(rng.choice([0.0, 1.5])), float(rng.choice([0.0, 0.02]))
    scales = rng.uniform(0.9, 1.1, 2)
    shared = np.random.default_rng(seed)
    return tuple(FaultyEncoder(radius, ticks_meter, float(k), noise, slip, shared)
                 for k in scales)


def run_both(seed: int, n: int, mode: str, duration_ms: int, vary: bool = False) -> None:
    """``vary``: the batch is made with other configs, and ``vary`` gives half the cars
    their own (track, motor) and faulty encoders, the scalar bases the same."""
    rng = np.random.default_rng(seed)
    configs = [random_config(rng) for _ in range(n)]
    radius = rng.uniform(0.01, 0.2, n)
    drives = [FakeDrive() for _ in range(n)]
    bases = [ArbotixBase(c, mode, float(r), drive=d)
             for c, r, d in zip(configs, radius, drives, strict=True)]
    if not vary:
        batch = BatchedArbotix(configs, mode, radius)
    else:
        made = [dataclasses.replace(c, base_width_m=c.base_width_m * 1.3, motor=MotorConfig())
                for c in configs]
        batch = BatchedArbotix(made, mode, radius)
        for i in range(0, n, 2):
            pair_seed = int(rng.integers(2**31))
            state = rng.bit_generator.state
            bases[i].encoders = faulty_pair(rng, float(radius[i]), configs[i].ticks_meter,
                                             pair_seed)
            rng.bit_generator.state = state  # the same pair again, for the batch
            batch.vary(i, configs[i], faulty_pair(rng, float(radius[i]),
                                                  configs[i].ticks_meter, pair_seed))
        for i in range(1, n, 2):
            batch.vary(i, configs[i])
    angles = rng.uniform(-1e3, 1e3, (n, 2))
    period_ns = np.array([round(1e9 / c.rate_hz) for c in configs])
    next_ns = period_ns.copy()
    start_ms = np.zeros(n, dtype=np.int64)
    cmd_rate = rng.choice([0.02, 0.001], n)  # the rare talkers time out between commands

    def push_angles() -> None:
        for i, d in enumerate(drives):
            d.angles = (float(angles[i, 0]), float(angles[i, 1]))

    push_angles()
    for base in bases:
        base.reset(0.0)
    batch.reset(0.0, angles)
    assert_same(bases, drives, batch, "reset")
    for t_ms in range(1, duration_ms):
        now_ns = t_ms * 1_000_000
        now_s = now_ns / 1e9
        # the wheels turn: noise, drift, and now and then a jump (32-bit counter wrap)
        angles += rng.normal(0, 0.05, (n, 2)) + rng.uniform(-0.5, 0.5, (n, 1))
        jump = rng.random((n, 2)) < 0.002
        angles[jump] += rng.choice([-1, 1], jump.sum()) * rng.uniform(1e3, 1e7, jump.sum())
        push_angles()
        # a few cars are powered up afresh
        again = rng.random(n) < 0.001
        for i in np.flatnonzero(again):
            bases[i].reset(now_s)
            next_ns[i] = now_ns + period_ns[i]
            start_ms[i] = t_ms
        batch.reset(now_s, angles, again)
        # cmd_vel now and then: slow, fast, huge (16-bit target wrap), zero (stop)
        cmd = rng.random(n) < cmd_rate
        speed = rng.choice([0.0, 0.3, 5.0, 100.0], n)
        lx = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(-1, 1, n) * speed)
        az = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(-1, 1, n) * speed * 4)
        for i in np.flatnonzero(cmd):
            bases[i].cmd_vel(float(lx[i]), float(az[i]), now_s)
        batch.cmd_vel(lx, az, now_s, cmd)
        # the controller fires when due, then the board runs a frame if due
        due = now_ns >= next_ns
        for i in np.flatnonzero(due):
            bases[i].update(now_s)
        batch.update(now_s, angles, due)
        next_ns[due] += period_ns[due]
        for base in bases:
            base.board_tick(now_s)
        batch.board_tick(now_s, angles)
        assert_same(bases, drives, batch, f"t = {t_ms} ms")


@pytest.fixture(params=["numpy", "compiled"])
def path(request, monkeypatch):
    """Each test on BatchedArbotix's numpy code and on its compiled loops (the fast extra)."""
    if request.param == "compiled" and not compiled.COMPILED:
        pytest.skip("the compiled path needs numba (the fast extra)")
    monkeypatch.setattr(compiled, "COMPILED", request.param == "compiled")
    return request.param


@pytest.mark.slow
@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32 - 1))
def test_hardware_mode_matches_the_scalar_emulation_every_frame(path, seed):
    run_both(seed, n=6, mode="hardware", duration_ms=1000)


@pytest.mark.parametrize("seed", [3, 11])
def test_hardware_mode_matches_every_frame_on_both_paths(path, seed):
    """Fixed seeds on every run (the hypothesis test above is marked slow)."""
    run_both(seed, n=5, mode="hardware", duration_ms=400)


@pytest.mark.parametrize("seed", [5, 23])
def test_varied_cars_match_the_scalar_emulation_every_frame(path, seed):
    """``vary``: a car's own track, motor and faulty encoders (scale, jitter, slip drawn from
    its generator) are the scalar base's with them, on either path (the batch counts faulty
    encoders with numpy's arithmetic)."""
    run_both(seed, n=5, mode="hardware", duration_ms=400, vary=True)


def test_vary_refuses_what_a_variation_does_not_change():
    config = ArbotixConfig(ticks_meter=4100.0, base_width_m=0.2)
    batch = BatchedArbotix(config, "hardware", 0.03, num_cars=2)
    with pytest.raises(ValueError, match=r"^car 1: a varied config may change the track and "
                                         r"motor only, not ticks_meter, max_accel, gains"):
        batch.vary(1, dataclasses.replace(config, ticks_meter=config.ticks_meter * 2, kp=7))
    batch.vary(1, dataclasses.replace(config, base_width_m=0.5))
    assert batch.base_width.tolist() == [config.base_width_m, 0.5] and not batch.faulty


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_sim_mode_matches_the_scalar_emulation_every_frame(seed):
    run_both(seed, n=6, mode="sim", duration_ms=600)


def test_the_board_really_runs_frames_and_wraps(path):
    """The scenario above is not vacuous: PWM saturates, counters and targets wrap."""
    rng = np.random.default_rng(7)
    config = ArbotixConfig(ticks_meter=9e5, base_width_m=0.26, kp=20, ko=2, frame_ms=5,
                           accel_limit=1e4)
    batch = BatchedArbotix(config, "hardware", 0.025, num_cars=2)
    angles = np.zeros((2, 2))
    batch.reset(0.0, angles)
    batch.cmd_vel(np.array([0.5, 2000.0]), 0.0, 0.0)  # car 1: 2000*9e5/30 wraps in 16 bits
    frames = 0
    for t_ms in range(1, 400):
        angles += rng.uniform(0, 1e-3, (2, 2))
        if t_ms % 100 == 0:
            batch.update(t_ms / 1000, angles)
        frames += int(batch.board_tick(t_ms / 1000, angles).sum())
    assert frames > 50
    assert abs(batch.output[0, 0]) == 255
    assert batch.velocity[1, 0] == wrap16(int(2000.0 * 9e5 / 30.0))
    assert batch.velocity[1, 0] != int(2000.0 * 9e5 / 30.0)
    assert batch.v_des[1, 0] != 0
    for t_ms in range(400, 1500, 100):  # no cmd_vel for over the 1 s timeout
        batch.update(t_ms / 1000, angles)
    assert np.all(batch.v_des == 0) and np.all(batch.v == 0)


@settings(max_examples=200, deadline=None)
@given(a=st.integers(-(2**40), 2**40), b=st.integers(1, 255))
def test_integer_helpers_match_the_scalar_ones(a, b):
    arr = np.array([a], dtype=np.int64)
    assert wrap_int16(arr)[0] == wrap16(a)
    assert wrap_int32(arr)[0] == wrap32(a)
    assert c_div(arr, np.array([b]))[0] == c_div1(a, b)


def test_bad_input_is_refused(path):
    config = ArbotixConfig(ticks_meter=4100.0, base_width_m=0.26)
    with pytest.raises(ValueError, match="num_cars is needed"):
        BatchedArbotix(config, "hardware", 0.025)
    with pytest.raises(ValueError, match="mode must be one of"):
        BatchedArbotix(config, "fast", 0.025, num_cars=1)
    batch = BatchedArbotix(config, "hardware", 0.025, num_cars=2)
    with pytest.raises(RuntimeError, match="reset"):
        batch.update(0.1, np.zeros((2, 2)))
    batch.reset(0.0, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="finite"):
        batch.cmd_vel(np.array([math.nan, 0.0]), 0.0, 0.0)
    batch.cmd_vel(0.3, 0.0, 0.0)
    batch.update(0.1, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="time went backwards"):
        batch.update(0.05, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="not finite"):
        batch.update(0.2, np.array([[0.0, math.inf], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="not finite"):
        batch.board_tick(0.3, np.array([[math.nan, 0.0], [0.0, 0.0]]))
    assert batch.then[0] == 0.1  # refused before anything changed


@pytest.mark.skipif(not compiled.COMPILED, reason="the threads split the compiled loops (fast "
                                                  "extra)")
def test_the_compiled_loops_give_the_same_bits_on_one_thread_or_two(monkeypatch):
    """``threads``: the compiled ``update`` and ``board_tick`` split the cars over threads
    (``parallel.run_chunks``; here 64 cars, in chunks of 8). Each car is its own, so random
    cars with random commands, encoder streams and updates give the same numbers every
    millisecond on 1 or 2 threads, and a call that one car makes refuse changes no car on
    either."""
    monkeypatch.setattr(compiled, "MIN_CHUNK_CARS", 8)
    rng = np.random.default_rng(29)
    n = 64
    configs = [random_config(rng) for _ in range(n)]
    radius = rng.uniform(0.01, 0.2, n)
    angles = rng.uniform(-1e3, 1e3, (n, 2))
    batches = [BatchedArbotix(configs, "hardware", radius, threads=t) for t in (1, 2)]
    for batch in batches:
        batch.reset(0.0, angles)
    frames = 0
    for t_ms in range(1, 400):
        now_s = t_ms / 1000
        angles += rng.normal(0, 0.05, (n, 2)) + rng.uniform(-0.5, 0.5, (n, 1))
        cmd, due = rng.random(n) < 0.05, rng.random(n) < 0.1
        lx, az = rng.uniform(-1, 1, n), rng.uniform(-4, 4, n)
        ran = []
        for batch in batches:
            batch.cmd_vel(lx, az, now_s, cmd)
            batch.update(now_s, angles, due)
            ran.append(batch.board_tick(now_s, angles))
        assert np.array_equal(*ran)
        frames += int(ran[0].sum())
        for block in ("floats", "ints", "flags"):
            assert np.array_equal(getattr(batches[0], block), getattr(batches[1], block)), \
                f"t = {t_ms} ms: {block}"
    assert frames > 1000  # the boards ran
    angles[n - 1, 0] = math.nan  # the last car's chunk refuses; the first chunks' cars wait
    for batch in batches:
        saved = [batch.floats.copy(), batch.ints.copy(), batch.flags.copy()]
        for call in (batch.update, batch.board_tick):
            with pytest.raises(ValueError, match="not finite"):
                call(0.5, angles)
            assert all(np.array_equal(a, b) for a, b in zip(
                saved, (batch.floats, batch.ints, batch.flags), strict=True))
