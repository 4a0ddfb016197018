"""``BatchedArbotix``'s hardware-mode ``update`` and ``board_tick`` compiled with numba.

numba is the optional ``fast`` extra. Without it (or with ``SMARTCAR_GYM_NUMBA=0``, read at
import) ``BatchedArbotix`` runs its numpy code; with it, these loops over the cars run the
same per-car arithmetic in the same order (Python's ``int``/``float`` semantics: int64 wrapped
to the AVR's 16/32 bits, truncating division, ``math.cos``/``math.sin`` as the scalar
``DiffController``), so both paths give the same numbers bit for bit
(``tests/test_controller_batched.py`` runs each against the scalar emulation).

Why: numpy spends a few microseconds per operation whatever the number of cars, and a
controller update is about 60 of them. Measured (docs/performance.md): the planar batch at
4,096 cars spent as long in these two methods as in its physics; compiled, they take under a
tenth of its step.

The loops that change cars free the GIL and split the cars over ``BatchedArbotix.threads``
(``parallel.run_chunks``, ``MIN_CHUNK_CARS`` or more to a chunk); each car is its own,
so any split gives the same bits. The checks
that refuse a call run first, over every car in the calling thread, so that a refused call
changes no car whatever the split.

``COMPILED`` says whether the compiled loops are in use; ``BatchedArbotix`` reads it at each
call, so a test may switch it off.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from smartcar_gym.controller._cint import c_div as _c_div
from smartcar_gym.controller._cint import wrap_int16 as _wrap16
from smartcar_gym.controller._cint import wrap_int32 as _wrap32
from smartcar_gym.controller.board import MAX_OUTPUT
from smartcar_gym.controller.columns import (
    APPLIED,
    BACK_EMF,
    BASE_WIDTH,
    BOARD_GAINS,
    COAST,
    DAMPING,
    DR,
    DRIVE,
    DX,
    ENC,
    ENC_VALID,
    ENCODER,
    F_TIME,
    FRAME_MS,
    IERROR,
    LAST_CMD,
    MAX_ACCEL,
    MOVING,
    ODOM_V,
    ODOM_W,
    OUTPUT,
    PID_MODE,
    PREV_ENC,
    PREV_ERR,
    RADIUS,
    READY,
    STALL,
    STAMP,
    THEN,
    THETA,
    TICKS,
    TICKS_METER,
    TIMEOUT_NS,
    V_DES,
    VELOCITY,
    WROTE,
    ZERO,
    V,
    X,
    Y,
)
from smartcar_gym.controller.motor import MAX_PWM
from smartcar_gym.parallel import run_chunks

if TYPE_CHECKING:
    from smartcar_gym.controller.batched import BatchedArbotix

try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"

#: cars per chunk below which a split costs more than it saves: a car's update or PID frame
#: takes some 40 ns, a split and a worker's wake-up more than it saves on small chunks.
#: Measured on the quiet 2-core machine, the planar batch at 4,096 cars, ms a step of the
#: PID frames / the whole step: chunks of 1,024 cars 0.98-1.03 / 7.58-7.78, unsplit
#: 0.82-0.83 / 7.20-7.33; at 16,384 cars the split pays (2.6-2.8 against 3.2-3.6 ms)
MIN_CHUNK_CARS = 4096
#: what a compiled call found wrong before it changed anything (0: nothing)
NOT_READY, BACKWARDS, NOT_FINITE = 1, 2, 3
MESSAGES = {
    NOT_READY: (RuntimeError,
                "BatchedArbotix.reset() must be called before use in hardware mode"),
    BACKWARDS: (ValueError, "time went backwards for some car"),
    NOT_FINITE: (ValueError, "a wheel angle gives no encoder count (not finite)"),
}


def _ns(t):
    return np.int64(np.rint(t * 1e9))


def _count(angle, zero, radius, ticks_meter):
    """``WheelEncoder.count``: the wheel's travel in whole ticks, wrapped to 32 bits."""
    return _wrap32(np.int64(math.floor((angle - zero) * radius * ticks_meter)))


def _refused(i, a_left, a_right, f, b):
    """What is wrong with running car ``i`` on these encoder angles (0: nothing)."""
    if not b[READY, i]:
        return NOT_READY
    scale = f[RADIUS, i]
    if not (math.isfinite((a_left - f[ZERO, i]) * scale * f[TICKS_METER, i])
            and math.isfinite((a_right - f[ZERO + 1, i]) * scale * f[TICKS_METER, i])):
        return NOT_FINITE
    return 0


def _apply_pwm(i, f, n, b):
    """``ArbotixBase._apply_pwm``: the motors' outputs, if car ``i``'s PWM changed."""
    if n[OUTPUT, i] != n[APPLIED, i] or n[OUTPUT + 1, i] != n[APPLIED + 1, i]:
        for k in range(2):  # DCMotor.output
            p = n[OUTPUT + k, i]
            clipped = float(min(max(p, -MAX_PWM), MAX_PWM))
            f[DRIVE + k, i] = f[STALL, i] * clipped / MAX_PWM
            f[DAMPING + k, i] = 0.0 if (p == 0 and b[COAST, i]) else f[BACK_EMF, i]
            n[APPLIED + k, i] = p


def update_car(i, t, a_left, a_right, f, n, b):
    """``BatchedArbotix.update`` (hardware) of car ``i`` at ``t`` s with these encoder wheel
    angles; ``f``, ``n``, ``b``: its ``floats``, ``ints`` and ``flags`` (``_refused`` and
    time going backwards checked)."""
    elapsed = t - f[THEN, i]
    f[THEN, i] = t
    # odometry from the encoders (DiffController.update)
    tm = f[TICKS_METER, i]
    n[TICKS, i] = _count(a_left, f[ZERO, i], f[RADIUS, i], tm)
    n[TICKS + 1, i] = _count(a_right, f[ZERO + 1, i], f[RADIUS, i], tm)
    d_left = float(n[TICKS, i] - n[ENC, i]) / tm if b[ENC_VALID, i] else 0.0
    d_right = float(n[TICKS + 1, i] - n[ENC + 1, i]) / tm if b[ENC_VALID, i] else 0.0
    n[ENC, i], n[ENC + 1, i] = n[TICKS, i], n[TICKS + 1, i]
    b[ENC_VALID, i] = True
    d = (d_left + d_right) / 2
    th = (d_right - d_left) / f[BASE_WIDTH, i]
    if elapsed > 0:
        f[DX, i], f[DR, i] = d / elapsed, th / elapsed
    else:
        f[DX, i], f[DR, i] = 0.0, 0.0
    if d != 0:
        fx, fy = math.cos(th) * d, -math.sin(th) * d
        theta = f[THETA, i]
        cos, sin = math.cos(theta), math.sin(theta)
        f[X, i] = f[X, i] + (cos * fx - sin * fy)
        f[Y, i] = f[Y, i] + (sin * fx + cos * fy)
    if th != 0:
        f[THETA, i] = f[THETA, i] + th
    f[STAMP, i] = t
    f[ODOM_V, i], f[ODOM_W, i] = f[DX, i], f[DR, i]
    if _ns(t) > _ns(f[LAST_CMD, i]) + n[TIMEOUT_NS, i]:
        n[V_DES, i], n[V_DES + 1, i] = 0, 0
    # the ramp, then the write to the board (ArbotixBoard.write)
    for k in range(2):
        v, v_des = n[V + k, i], n[V_DES + k, i]
        if v < v_des:
            n[V + k, i] = min(v + n[MAX_ACCEL, i], v_des)
        else:
            n[V + k, i] = max(v - n[MAX_ACCEL, i], v_des)
    b[WROTE, i] = True
    left, right = _wrap16(n[V, i]), _wrap16(n[V + 1, i])
    if left == 0 and right == 0:
        b[PID_MODE, i] = b[MOVING, i] = False
        for k in range(2):
            n[PREV_ERR + k, i] = n[IERROR + k, i] = n[OUTPUT + k, i] = 0
    elif n[VELOCITY, i] == 0 and n[VELOCITY + 1, i] == 0:
        b[PID_MODE, i] = b[MOVING, i] = True
        for k in range(2):
            n[PREV_ENC + k, i] = _wrap32(n[TICKS + k, i])
    n[VELOCITY, i], n[VELOCITY + 1, i] = left, right
    _apply_pwm(i, f, n, b)


def frame_due(i, t, n, b):
    """Would car ``i``'s board run a PID frame at ``t`` s (``updatePID``'s test). Written
    without branches (``&``, not ``and``): numba then drops the reference counting of the
    arrays around each call (measured: the loop over 4,096 cars 3.5x faster)."""
    return b[MOVING, i] & b[PID_MODE, i] & \
        (np.int64(math.trunc(t * 1000.0 + 1e-6)) > n[F_TIME, i])


def next_frame_car(i, now, never, n, b):
    """Car ``i``'s next PID frame (ns on its clock, ``now`` ns), not before now; ``never``
    while its board is idle."""
    frame = n[F_TIME, i] + 1
    if b[MOVING, i] & b[PID_MODE, i] and frame >= 0:
        return max(now, frame * 1_000_000)
    return never


def next_frame_ns(now, never, n, b, out):
    """Each car's next PID frame (ns on its clock ``now``), not before now; ``never`` while
    its board is idle (``BatchedArbotix.next_frame_ns``)."""
    for i in range(out.shape[0]):
        out[i] = next_frame_car(i, now[i], never, n, b)


def board_tick_car(i, t, a_left, a_right, f, n, b):
    """One PID frame of car ``i``'s board at ``t`` s (``frame_due`` and ``_refused``
    checked): ``DoPid`` on each wheel, then the motors."""
    kp, kd = n[BOARD_GAINS, i], n[BOARD_GAINS + 1, i]
    ki, ko = n[BOARD_GAINS + 2, i], n[BOARD_GAINS + 3, i]
    for k in range(2):
        n[TICKS + k, i] = _count(a_left if k == 0 else a_right, f[ZERO + k, i], f[RADIUS, i],
                                 f[TICKS_METER, i])
        encoder = _wrap32(n[TICKS + k, i])
        n[ENCODER + k, i] = encoder
        perror = _wrap32(n[VELOCITY + k, i] - _wrap32(encoder - n[PREV_ENC + k, i]))
        numerator = _wrap32(_wrap32(kp * perror)
                            + _wrap32(kd * _wrap32(perror - n[PREV_ERR + k, i]))
                            + _wrap16(ki * n[IERROR + k, i]))
        out = _wrap32(_c_div(numerator, ko) + n[OUTPUT + k, i])
        n[PREV_ERR + k, i] = _wrap16(perror)
        n[PREV_ENC + k, i] = encoder
        if out >= MAX_OUTPUT:
            n[OUTPUT + k, i] = MAX_OUTPUT
        elif out <= -MAX_OUTPUT:
            n[OUTPUT + k, i] = -MAX_OUTPUT
        else:
            n[IERROR + k, i] = _wrap16(n[IERROR + k, i] + perror)
            n[OUTPUT + k, i] = out
    n[F_TIME, i] = np.int64(math.trunc(t * 1000.0 + 1e-6)) + n[FRAME_MS, i]
    _apply_pwm(i, f, n, b)


def _update_refused(mask, now, angles, f, b):
    """What is wrong with updating the masked cars (0: nothing; else the first such car's)."""
    for i in range(mask.shape[0]):
        if mask[i]:
            code = _refused(i, angles[i, 0], angles[i, 1], f, b)
            if code:
                return code
            if now[i] - f[THEN, i] < 0:
                return BACKWARDS
    return 0


def _update_cars(start, stop, mask, now, angles, f, n, b):
    for i in range(start, stop):
        if mask[i]:
            update_car(i, now[i], angles[i, 0], angles[i, 1], f, n, b)


def _frames_refused(mask, now, angles, ran, f, n, b):
    """Which masked cars run a frame (into ``ran``), and what is wrong with running them (as
    ``_update_refused``)."""
    for i in range(mask.shape[0]):
        ran[i] = mask[i] and frame_due(i, now[i], n, b)
        if ran[i]:
            code = _refused(i, angles[i, 0], angles[i, 1], f, b)
            if code:
                return code
    return 0


def _frame_cars(start, stop, now, angles, ran, f, n, b):
    for i in range(start, stop):
        if ran[i]:
            board_tick_car(i, now[i], angles[i, 0], angles[i, 1], f, n, b)


def fire_car(i, t, a_left, a_right, update, f, n, b):
    """Car ``i``'s board events at ``t`` s, as ``update`` then ``board_tick`` run them for
    it: the controller's update where ``update``, then the PID frame if one is due; each
    refused (``_refused``, time going backwards) before it changes the car. Returns the code
    of what was refused (0: nothing)."""
    if update:
        code = _refused(i, a_left, a_right, f, b)
        if code:
            return code
        if t - f[THEN, i] < 0:
            return BACKWARDS
        update_car(i, t, a_left, a_right, f, n, b)
    if frame_due(i, t, n, b):
        code = _refused(i, a_left, a_right, f, b)
        if code:
            return code
        board_tick_car(i, t, a_left, a_right, f, n, b)
    return 0


if COMPILED:
    _jit = numba.njit(cache=True)  # the scalar emulation's own integer helpers too
    _wrap16, _wrap32, _c_div, _ns, _count, _refused, _apply_pwm = (
        _jit(f) for f in (_wrap16, _wrap32, _c_div, _ns, _count, _refused, _apply_pwm))
    update_car, frame_due, board_tick_car = (
        _jit(f) for f in (update_car, frame_due, board_tick_car))
    _update_refused, _frames_refused = _jit(_update_refused), _jit(_frames_refused)
    # inlined by numba into ``next_frame_ns`` and ``period``'s loop (a function of its own
    # is compiled again in each caller)
    next_frame_car = numba.njit(cache=True, inline="always")(next_frame_car)
    next_frame_ns, fire_car = _jit(next_frame_ns), _jit(fire_car)
    # the loops over a chunk of cars free the GIL: ``run_chunks`` runs chunks side by side
    _update_cars, _frame_cars = (numba.njit(cache=True, nogil=True)(f)
                                 for f in (_update_cars, _frame_cars))


def _checked(code: int) -> None:
    if code:
        error, message = MESSAGES[code]
        raise error(message)


def _per_car(b: BatchedArbotix, now_s: np.ndarray | float, angles: np.ndarray,
             mask: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = b.n
    now = np.asarray(now_s, dtype=np.float64)
    now = np.full(n, float(now)) if now.ndim == 0 else np.ascontiguousarray(now)
    mask = np.ones(n, dtype=bool) if mask is None else np.ascontiguousarray(mask, dtype=bool)
    angles = np.ascontiguousarray(angles, dtype=np.float64)
    if now.shape != (n,) or mask.shape != (n,) or angles.shape != (n, 2):
        raise ValueError(f"expected now_s of ({n},), angles of ({n}, 2) and a mask of ({n},), "
                         f"got {now.shape}, {angles.shape}, {mask.shape}")
    return now, angles, mask


def update(b: BatchedArbotix, now_s: np.ndarray | float, angles: np.ndarray,
           mask: np.ndarray | None) -> None:
    """``BatchedArbotix.update`` in hardware mode, compiled."""
    now, angles, mask = _per_car(b, now_s, angles, mask)
    f, n, flags = b.floats, b.ints, b.flags
    _checked(_update_refused(mask, now, angles, f, flags))  # before any car changes
    run_chunks(lambda i, j: _update_cars(i, j, mask, now, angles, f, n, flags), b.n, b.threads,
               MIN_CHUNK_CARS)


def board_tick(b: BatchedArbotix, now_s: np.ndarray | float, angles: np.ndarray,
               mask: np.ndarray | None) -> np.ndarray:
    """``BatchedArbotix.board_tick`` in hardware mode, compiled; which cars ran a frame."""
    now, angles, mask = _per_car(b, now_s, angles, mask)
    ran = np.zeros(b.n, dtype=bool)
    f, n, flags = b.floats, b.ints, b.flags
    _checked(_frames_refused(mask, now, angles, ran, f, n, flags))  # before any car changes
    run_chunks(lambda i, j: _frame_cars(i, j, now, angles, ran, f, n, flags), b.n, b.threads,
               MIN_CHUNK_CARS)
    return ran


def compile_loops() -> bool:
    """Compile the loops above now, or load them from numba's cache: a throwaway one-car
    board through the calls a batch makes (reset, ``cmd_vel``, update, next frame, frame), so
    with the types a batch gives them. A process that will step boards later can run it ahead,
    on a core that is idle: a batched training's evaluation process does
    (``agents.eval_worker``) while the training compiles its physics, which comes first (the
    boards were 2 s of a first run's compiling on the 2-core machine; the training now loads
    them from the cache). False where numba is not in use (nothing to compile)."""
    if not COMPILED:
        return False
    from smartcar_gym.controller.batched import BatchedArbotix  # it imports this module
    from smartcar_gym.controller.config import load_controller_config
    from smartcar_gym.controller.diff_controller import HARDWARE

    board = BatchedArbotix(load_controller_config(), HARDWARE, 0.03, num_cars=1)
    angles = np.zeros((1, 2))
    board.reset(0.0, angles)
    board.cmd_vel(np.ones(1), np.zeros(1), 0.0)
    board.update(0.02, angles)
    board.next_frame_ns(np.zeros(1, dtype=np.int64), int(np.iinfo(np.int64).max))
    board.board_tick(0.05, angles)
    return True
