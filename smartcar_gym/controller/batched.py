"""The ArbotiX emulation on arrays of N cars: ``ArbotixBase`` in numpy, bit for bit per car.

``BatchedArbotix`` holds the state of N host controllers, N boards, 2N encoders and 2N motors in
arrays, and runs each operation of ``ArbotixBase`` on the cars a boolean ``mask`` selects. Every
number is computed with the scalar emulation's operations in the same order: floats in float64,
the board's ``int``/``long`` as int64 wrapped to 16/32 bits with truncating division, as on the
AVR. ``tests/test_controller_batched.py`` drives random configurations with random commands and
encoder streams through both and compares every frame.

Each car may have its own ``ArbotixConfig`` (domain randomisation: ``vary`` gives a car the
track, motor and encoders of a ``Variation``). Times are per car too (cars reset at different
instants). A car's ``FaultyEncoder`` s (off scale, noise, slip) count in Python, the scalar
class itself, so their generators draw as the single robot's; the batch then runs numpy's
arithmetic, not the compiled loop. Not here: ``CommandDelay`` latency (the robot's, kept per
car by the batched env) and the failed encoder read of ``DiffController.update(encoders=None)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from smartcar_gym.controller import columns, compiled
from smartcar_gym.controller.board import BOOT_GAINS, MAX_OUTPUT
from smartcar_gym.controller.config import ArbotixConfig
from smartcar_gym.controller.diff_controller import FRAMES_PER_S, HARDWARE, KINEMATIC, MODES, Mode
from smartcar_gym.controller.encoder import WheelEncoder
from smartcar_gym.controller.motor import MAX_PWM

_I32 = 0x8000_0000
_I16 = 0x8000


def wrap_int16(n: np.ndarray) -> np.ndarray:
    """``_cint.wrap_int16`` on an int64 array."""
    return ((n + _I16) & 0xFFFF) - _I16


def wrap_int32(n: np.ndarray) -> np.ndarray:
    """``_cint.wrap_int32`` on an int64 array."""
    return ((n + _I32) & 0xFFFF_FFFF) - _I32


def c_div(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``_cint.c_div`` (C's truncating ``/``) on int64 arrays, ``b`` > 0."""
    q = np.abs(a) // b
    return np.where(a >= 0, q, -q)


def seconds_to_ns(t_s: np.ndarray) -> np.ndarray:
    """``diff_controller._ns``: ``round(t * 1e9)`` (half to even) as int64."""
    return np.rint(np.asarray(t_s, dtype=np.float64) * 1e9).astype(np.int64)


def board_millis(now_s: np.ndarray) -> np.ndarray:
    """``base.board_millis``: ``int(now_s * 1000.0 + 1e-6)`` for times >= 0."""
    return np.trunc(np.asarray(now_s, dtype=np.float64) * 1000.0 + 1e-6).astype(np.int64)


def _all(mask: np.ndarray | None, n: int) -> np.ndarray:
    return np.ones(n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)


def cars_index(m: np.ndarray) -> slice | np.ndarray:
    """A boolean mask of cars as an index: a slice when it selects every car (views instead
    of copies: the same numbers, a third of the work at thousands of cars)."""
    return slice(None) if m.all() else m


def _sel(mask: np.ndarray | None) -> slice | np.ndarray:
    """The cars to act on as an index: every car (a slice, no copies) or a boolean mask."""
    return slice(None) if mask is None else np.asarray(mask, dtype=bool)


class BatchedArbotix:
    """N emulated ArbotiX bases (``ArbotixBase``) in arrays, one ``mode`` for all.

    Args:
        configs: one ``ArbotixConfig`` for every car, or a sequence of N (one per car).
        mode: ``"hardware"`` or ``"sim"``, as ``ArbotixBase``.
        wheel_radius_m: the encoder wheels' radius, a number or N of them.
        num_cars: N (needed when ``configs`` is a single config).
        threads: the threads the compiled loops split the cars over (``parallel.run_chunks``;
            each car is its own, so any count gives the same bits); numpy's code runs on one.

    The simulator passes encoder wheel angles as an ``(N, 2)`` array (left, right, rad,
    forward-positive) wherever ``ArbotixBase`` would call ``WheelDrive.encoder_angles``; the
    motor outputs are ``drive_torque`` and ``damping`` (``(N, 2)``), valid after each call that
    may change the PWM (``reset``, ``update``, ``board_tick``), as ``set_motor_output`` would be.

    Every method takes per-car arrays (or scalars, broadcast) and an optional boolean ``mask``
    of the cars it acts on (None: all); the other cars are left exactly as they were.
    """

    def __init__(self, configs: ArbotixConfig | Sequence[ArbotixConfig], mode: Mode,
                 wheel_radius_m: float | Sequence[float], num_cars: int | None = None,
                 encoder_phase_ticks: float = 0.0, threads: int = 1) -> None:
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if isinstance(configs, ArbotixConfig):
            if num_cars is None:
                raise ValueError("num_cars is needed with a single ArbotixConfig")
            configs = [configs] * num_cars
        configs = list(configs)
        n = len(configs)
        if n < 1 or (num_cars is not None and num_cars != n):
            raise ValueError(f"need num_cars >= 1 configs, got {n} for num_cars={num_cars}")
        self.n = n
        self.mode: Mode = mode
        self.configs = configs
        self.threads = int(threads)

        def col(f, dtype=np.float64):  # one value per car
            return np.array([f(c) for c in configs], dtype=dtype)

        radius = np.broadcast_to(np.asarray(wheel_radius_m, dtype=np.float64), (n,))
        ticks_meter = col(lambda c: c.ticks_meter)
        if not (np.all(radius > 0) and np.all(ticks_meter > 0)):
            raise ValueError("wheel_radius_m and ticks_meter must be > 0")
        if not 0.0 <= encoder_phase_ticks < 1.0:
            raise ValueError(f"encoder_phase_ticks must be in [0, 1), got "
                             f"{encoder_phase_ticks!r}")
        #: where the encoders start within their first tick (``WheelEncoder.reset``)
        self.encoder_phase_ticks = float(encoder_phase_ticks)
        #: every per-car number, in three blocks of rows (``columns``); the named arrays
        #: below (``x``, ``v_des``, ...) are views of them
        self.floats = columns.block(columns.FLOATS, n, np.float64)
        self.ints = columns.block(columns.INTS, n, np.int64)
        self.flags = columns.block(columns.FLAGS, n, np.bool_)
        self._views()
        # the configuration, per car
        self.ticks_meter[:] = ticks_meter
        self.timeout_ns[:] = seconds_to_ns(col(lambda c: c.timeout_s))
        self.max_accel[:] = col(lambda c: c.max_accel, np.int64)
        self.frame_ms[:] = col(lambda c: c.frame_ms, np.int64)
        self.gains[:] = np.array([c.gains for c in configs], dtype=np.int64)  # (N, 4)
        for i, c in enumerate(configs):
            self._set_plant(i, c)
        self.wheel_radius[:] = radius
        #: per car with encoders that do not count exactly: its (left, right) encoders
        self.faulty: dict[int, tuple[WheelEncoder, WheelEncoder]] = {}
        # the board boots with its own gains (until the driver's setup packet)
        self.board_gains[:] = BOOT_GAINS
        self.ready[:] = self.mode == KINEMATIC

    def _views(self) -> None:
        """The named arrays as views of the blocks' rows. Host (``DiffController``): ``x``,
        ``y``, ``theta``, ``dx``, ``dr``, ``odom_v``/``odom_w`` (the twist of the latest
        published odometry), ``v_des``, ``v``, ``enc`` (and ``enc_valid``: not None),
        ``then``, ``last_cmd``, ``stamp``, ``wrote`` (``last_write`` is not None). Board
        (``ArbotixBoard`` and its two ``WheelPID`` s): ``board_gains``, ``f_time``, ``moving``,
        ``pid_mode``, ``velocity``, ``encoder``, ``prev_enc``, ``prev_err``, ``ierror``,
        ``output``. Encoders and motors: ``zero_angle``, ``ticks``, ``applied_pwm``,
        ``drive_torque``, ``damping``. Configuration: ``ticks_meter``, ``base_width``,
        ``timeout_ns``, ``max_accel``, ``frame_ms``, ``gains``, ``stall``, ``back_emf``,
        ``coast``, ``wheel_radius``."""
        for block, layout in ((self.floats, columns.FLOATS), (self.ints, columns.INTS),
                              (self.flags, columns.FLAGS)):
            for name, (row, width) in columns.rows(layout).items():
                setattr(self, name, block[row] if width == 1 else block[row:row + width].T)

    def __getstate__(self) -> dict:
        """A copy (pickle, ``copy.deepcopy``) keeps the blocks, not their views."""
        names = {name for layout in (columns.FLOATS, columns.INTS, columns.FLAGS)
                 for name, _ in layout}
        return {k: v for k, v in self.__dict__.items() if k not in names}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._views()

    def _set_plant(self, i: int, c: ArbotixConfig) -> None:
        """Car ``i``'s track and motor from ``c``."""
        self.base_width[i] = c.base_width_m
        self.stall[i] = c.motor.stall_torque_nm
        self.back_emf[i] = c.motor.stall_torque_nm / c.motor.no_load_speed_rad_s
        self.coast[i] = c.motor.pwm_zero == "coast"

    def vary(self, car: int, config: ArbotixConfig,
             encoders: tuple[WheelEncoder, WheelEncoder] | None = None) -> None:
        """Car ``car`` becomes a robot's base after ``SmartCarRobot.vary``: its ``config``
        (``Variation.config``: the track and the true motor; the rest must be the batch's),
        and its (left, right) ``encoders`` (``Variation.encoders``, taken as they are: their
        generators go on drawing here) or None for exact ones. Takes effect at the car's next
        ``reset``."""
        old = self.configs[car]
        same = ("ticks_meter", "timeout_s", "max_accel", "frame_ms", "gains")
        changed = [k for k in same if getattr(config, k) != getattr(old, k)]
        if changed:
            raise ValueError(f"car {car}: a varied config may change the track and motor "
                             f"only, not {', '.join(changed)}")
        self.configs[car] = config
        self._set_plant(car, config)
        if encoders is None:
            self.faulty.pop(car, None)
        else:
            self.faulty[car] = encoders

    def _faulty_in(self, m: np.ndarray | slice) -> list[int]:
        """The cars with faulty encoders that ``m`` (a mask or every car) selects."""
        if not self.faulty:
            return []
        if isinstance(m, slice):
            return sorted(self.faulty)
        return [i for i in sorted(self.faulty) if m[i]]

    @property
    def compiled(self) -> bool:
        """Whether the compiled loops (``controller.compiled``) run this batch: numba in use,
        and no car counts with faulty encoders."""
        return compiled.COMPILED and not self.faulty

    # -- lifecycle -----------------------------------------------------------------------------
    def reset(self, now_s: np.ndarray | float = 0.0, angles: np.ndarray | None = None,
              mask: np.ndarray | None = None) -> None:
        """``ArbotixBase.reset`` of the masked cars at ``now_s``; ``angles`` (N, 2): encoder
        wheels (hardware mode)."""
        m = _all(mask, self.n)
        now = np.broadcast_to(np.asarray(now_s, dtype=np.float64), (self.n,))
        for name in ("x", "y", "theta", "dx", "dr", "odom_v", "odom_w"):
            getattr(self, name)[m] = 0.0
        for name in ("v_des", "v", "enc", "f_time", "velocity", "encoder", "prev_enc",
                     "prev_err", "ierror", "output", "ticks", "applied_pwm"):
            getattr(self, name)[m] = 0
        self.enc_valid[m] = self.wrote[m] = False
        self.then[m] = self.last_cmd[m] = self.stamp[m] = now[m]
        self.board_gains[m] = BOOT_GAINS
        self.moving[m] = self.pid_mode[m] = False
        if self.mode == HARDWARE:
            if angles is None:
                raise ValueError("hardware mode: reset needs the encoder wheel angles (N, 2)")
            zero = np.asarray(angles, dtype=np.float64)[m]
            if self.encoder_phase_ticks:  # WheelEncoder.reset's arithmetic
                zero = zero - self.encoder_phase_ticks / (
                    self.wheel_radius[m, None] * self.ticks_meter[m, None])
            self.zero_angle[m] = zero
            for i in self._faulty_in(m):  # ArbotixBase.reset's encoder resets
                for side in (0, 1):
                    self.faulty[i][side].reset(float(angles[i][side]),
                                               self.encoder_phase_ticks)
            self.board_gains[m] = self.gains[m]
            self._set_motors(m, np.zeros((self.n, 2), dtype=np.int64))
        self.ready[m] = True

    # -- host side -----------------------------------------------------------------------------
    def cmd_vel(self, linear_x: np.ndarray, angular_z: np.ndarray, now_s: np.ndarray | float,
                mask: np.ndarray | None = None) -> None:
        """``cmd_vel`` for the masked cars at ``now_s`` (m/s, rad/s; finite)."""
        m = _sel(mask)
        shape = (self.n,)
        lx = np.broadcast_to(np.asarray(linear_x, dtype=np.float64), shape)
        az = np.broadcast_to(np.asarray(angular_z, dtype=np.float64), shape)
        if not (np.all(np.isfinite(lx[m])) and np.all(np.isfinite(az[m]))):
            raise ValueError("cmd_vel must be finite")
        self.last_cmd[m] = np.broadcast_to(np.asarray(now_s, dtype=np.float64), shape)[m]
        if self.mode == KINEMATIC:
            self.dx[m], self.dr[m] = lx[m], az[m]
            return
        half = az * self.base_width / 2.0
        left = np.trunc(((lx - half) * self.ticks_meter) / FRAMES_PER_S)
        right = np.trunc(((lx + half) * self.ticks_meter) / FRAMES_PER_S)
        self.v_des[m, 0] = left[m].astype(np.int64)
        self.v_des[m, 1] = right[m].astype(np.int64)

    def update(self, now_s: np.ndarray | float, angles: np.ndarray | None = None,
               mask: np.ndarray | None = None) -> None:
        """One controller firing of the masked cars (``ArbotixBase.update``): odometry, timeout,
        ramp and (hardware) the write to the board; ``angles`` (N, 2) in hardware mode."""
        if self.compiled and self.mode == HARDWARE and angles is not None:
            compiled.update(self, now_s, angles, mask)
            return
        m = _sel(mask)
        if not np.all(self.ready[m]):
            raise RuntimeError("BatchedArbotix.reset() must be called before use in hardware mode")
        now = np.broadcast_to(np.asarray(now_s, dtype=np.float64), (self.n,))
        elapsed = now - self.then
        if np.any(elapsed[m] < 0):
            raise ValueError("time went backwards for some car")
        if self.mode != KINEMATIC:  # refused (None, not finite) before anything changes
            ticks = self._read_encoders(m, angles)
        self.then[m] = now[m]
        self.wrote[m] = False
        if self.mode == KINEMATIC:
            self._integrate_twist(m, elapsed)
        else:
            self._integrate_encoders(m, ticks, elapsed)
        self.stamp[m] = now[m]
        self.odom_v[m], self.odom_w[m] = self.dx[m], self.dr[m]
        timed_out = seconds_to_ns(now) > seconds_to_ns(self.last_cmd) + self.timeout_ns
        if mask is not None:
            timed_out &= m
        self.v_des[timed_out] = 0
        if self.mode == HARDWARE:
            m = _all(mask, self.n)
            v, v_des, a = self.v[m], self.v_des[m], self.max_accel[m, None]
            self.v[m] = np.where(v < v_des, np.minimum(v + a, v_des), np.maximum(v - a, v_des))
            self.wrote[m] = True
            self._board_write(m)
            self._apply_pwm(m)

    def _integrate_twist(self, m: np.ndarray, elapsed: np.ndarray) -> None:
        th, dx, e = self.theta[m], self.dx[m], elapsed[m]
        self.x[m] += np.cos(th) * dx * e
        self.y[m] += np.sin(th) * dx * e
        self.theta[m] += self.dr[m] * e

    def _integrate_encoders(self, m: np.ndarray, ticks: np.ndarray, elapsed: np.ndarray) -> None:
        tm, valid = self.ticks_meter[m], self.enc_valid[m]
        delta = (ticks[m] - self.enc[m]).astype(np.float64)
        d_left = np.where(valid, delta[:, 0] / tm, 0.0)
        d_right = np.where(valid, delta[:, 1] / tm, 0.0)
        self.enc[m] = ticks[m]
        self.enc_valid[m] = True
        d = (d_left + d_right) / 2
        th = (d_right - d_left) / self.base_width[m]
        e = elapsed[m]
        positive = e > 0
        safe = np.where(positive, e, 1.0)
        self.dx[m] = np.where(positive, d / safe, 0.0)
        self.dr[m] = np.where(positive, th / safe, 0.0)
        x = np.cos(th) * d
        y = -np.sin(th) * d
        theta = self.theta[m]
        c, s = np.cos(theta), np.sin(theta)
        moved = d != 0
        self.x[m] = np.where(moved, self.x[m] + (c * x - s * y), self.x[m])
        self.y[m] = np.where(moved, self.y[m] + (s * x + c * y), self.y[m])
        self.theta[m] = np.where(th != 0, theta + th, theta)

    # -- board side ----------------------------------------------------------------------------
    def frame_due(self, now_s: np.ndarray | float) -> np.ndarray:
        """Per car: would ``updatePID`` run a frame at ``now_s`` (always False in sim mode)."""
        if self.mode == KINEMATIC:
            return np.zeros(self.n, dtype=bool)
        return self.moving & self.pid_mode & (board_millis(now_s) > self.f_time)

    def next_frame_ms(self) -> np.ndarray:
        """Per car: the ``millis()`` of the next PID frame; -1 while idle (or in sim mode)."""
        if self.mode == KINEMATIC:
            return np.full(self.n, -1, dtype=np.int64)
        return np.where(self.moving & self.pid_mode, self.f_time + 1, -1)

    def next_frame_ns(self, now_ns: np.ndarray, never: int) -> np.ndarray:
        """Per car: its next PID frame (ns on its clock, ``now_ns``), not before now, as
        ``SmartCarRobot.next_event_ns`` takes it; ``never`` while idle (or in sim mode)."""
        if compiled.COMPILED and self.mode != KINEMATIC:
            out = np.empty(self.n, dtype=np.int64)
            compiled.next_frame_ns(now_ns, never, self.ints, self.flags, out)
            return out
        frame = self.next_frame_ms()
        return np.where(frame >= 0, np.maximum(now_ns, frame * 1_000_000), never)

    def board_tick(self, now_s: np.ndarray | float, angles: np.ndarray | None = None,
                   mask: np.ndarray | None = None) -> np.ndarray:
        """``ArbotixBase.board_tick`` of the masked cars; returns which cars ran a frame."""
        if self.mode == KINEMATIC:
            return np.zeros(self.n, dtype=bool)
        if self.compiled and angles is not None:
            return compiled.board_tick(self, now_s, angles, mask)
        now_ms = np.broadcast_to(board_millis(now_s), (self.n,))
        m = _all(mask, self.n) & self.moving & self.pid_mode & (now_ms > self.f_time)
        if not m.any():
            return m
        if not np.all(self.ready[m]):
            raise RuntimeError("BatchedArbotix.reset() must be called before use in hardware mode")
        cars = cars_index(m)
        ticks = self._read_encoders(cars, angles)
        self.encoder[cars] = wrap_int32(ticks[cars])
        self._do_pid(cars)
        self.f_time[cars] = now_ms[cars] + self.frame_ms[cars]
        self._apply_pwm(m)
        return m

    def _board_write(self, m: np.ndarray) -> None:
        """``ArbotixBoard.write`` of ``v`` with the encoder counts just read."""
        target = wrap_int16(self.v[m])
        stop = (target[:, 0] == 0) & (target[:, 1] == 0)
        start = ~stop & (self.velocity[m, 0] == 0) & (self.velocity[m, 1] == 0)
        idx = np.flatnonzero(m)
        cleared, started = idx[stop], idx[start]
        self.pid_mode[cleared] = self.moving[cleared] = False
        self.prev_err[cleared] = self.ierror[cleared] = self.output[cleared] = 0
        self.pid_mode[started] = self.moving[started] = True
        self.prev_enc[started] = wrap_int32(self.ticks[started])
        self.velocity[m] = target

    def _do_pid(self, m: np.ndarray) -> None:
        """``DoPid`` on both wheels of the masked cars."""
        kp, kd, ki, ko = (self.board_gains[m, k, None] for k in range(4))
        velocity, encoder = self.velocity[m], self.encoder[m]
        prev_enc, prev_err = self.prev_enc[m], self.prev_err[m]
        ierror, output = self.ierror[m], self.output[m]
        perror = wrap_int32(velocity - wrap_int32(encoder - prev_enc))
        numerator = wrap_int32(
            wrap_int32(kp * perror)
            + wrap_int32(kd * wrap_int32(perror - prev_err))
            + wrap_int16(ki * ierror)
        )
        out = wrap_int32(c_div(numerator, ko) + output)
        self.prev_err[m] = wrap_int16(perror)
        self.prev_enc[m] = encoder
        high, low = out >= MAX_OUTPUT, out <= -MAX_OUTPUT
        free = ~(high | low)
        self.ierror[m] = np.where(free, wrap_int16(ierror + perror), ierror)
        self.output[m] = np.where(high, MAX_OUTPUT, np.where(low, -MAX_OUTPUT, out))

    # -- encoders and motors -------------------------------------------------------------------
    def _read_encoders(self, m: np.ndarray, angles: np.ndarray | None) -> np.ndarray:
        """``WheelEncoder.count`` of both encoder wheels of the masked cars (into ``ticks``)."""
        if angles is None:
            raise ValueError("hardware mode needs the encoder wheel angles (N, 2)")
        angle = np.asarray(angles, dtype=np.float64)[m] - self.zero_angle[m]
        travel = angle * self.wheel_radius[m, None] * self.ticks_meter[m, None]
        if not np.all(np.isfinite(travel)):
            raise ValueError("a wheel angle gives no encoder count (not finite)")
        self.ticks[m] = wrap_int32(np.floor(travel).astype(np.int64))
        for i in self._faulty_in(m):  # ArbotixBase._read_encoders: left, then right
            left, right = self.faulty[i]
            self.ticks[i] = (left.count(float(angles[i][0])), right.count(float(angles[i][1])))
        return self.ticks

    def _apply_pwm(self, m: np.ndarray) -> None:
        """Motor outputs of the masked cars whose PWM changed (``ArbotixBase._apply_pwm``)."""
        changed = m & np.any(self.output != self.applied_pwm, axis=1)
        if changed.any():
            self._set_motors(cars_index(changed), self.output)

    def _set_motors(self, m: np.ndarray, pwm: np.ndarray) -> None:
        """``DCMotor.output`` for each side's PWM of the masked cars."""
        p = pwm[m]
        clipped = np.clip(p, -MAX_PWM, MAX_PWM).astype(np.float64)
        self.drive_torque[m] = self.stall[m, None] * clipped / MAX_PWM
        off = (p == 0) & self.coast[m, None]
        self.damping[m] = np.where(off, 0.0, self.back_emf[m, None])
        self.applied_pwm[m] = p

    # -- views ---------------------------------------------------------------------------------
    @property
    def pwm(self) -> np.ndarray:
        """(N, 2) signed PWM on the (left, right) motor channels."""
        return self.output

    def commanded_twist(self) -> tuple[np.ndarray, np.ndarray]:
        """``ArbotixBase.commanded_twist`` per car: (v m/s, w rad/s)."""
        if self.mode == KINEMATIC:
            return self.dx, self.dr
        scale = FRAMES_PER_S / self.ticks_meter
        left, right = self.v[:, 0] * scale, self.v[:, 1] * scale
        return (left + right) / 2.0, (right - left) / self.base_width
