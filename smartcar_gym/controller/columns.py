"""Where ``BatchedArbotix`` keeps each quantity: rows of three blocks of N cars.

Every per-car number of the batched emulation lives in one of three arrays: ``floats``
(float64), ``ints`` (int64: the board's and the host's integers) and ``flags`` (bool), each of
shape ``(rows, N)``. ``BatchedArbotix``'s named arrays (``x``, ``v_des``, ``output``, ...) are
views of these rows: a quantity of width 1 is a row (shape ``(N,)``), one of width k is k rows
seen as ``(N, k)``. So numpy code reads and writes the named views, and the compiled loops
(``compiled.py``) take the three blocks and address a car's numbers by these row indices.
"""

from __future__ import annotations

import numpy as np

#: (name, width) of each quantity, block by block, in row order
FLOATS = (("x", 1), ("y", 1), ("theta", 1), ("dx", 1), ("dr", 1), ("odom_v", 1),
          ("odom_w", 1), ("then", 1), ("last_cmd", 1), ("stamp", 1), ("zero_angle", 2),
          ("drive_torque", 2), ("damping", 2), ("ticks_meter", 1), ("base_width", 1),
          ("stall", 1), ("back_emf", 1), ("wheel_radius", 1))
INTS = (("v_des", 2), ("v", 2), ("enc", 2), ("f_time", 1), ("velocity", 2), ("encoder", 2),
        ("prev_enc", 2), ("prev_err", 2), ("ierror", 2), ("output", 2), ("ticks", 2),
        ("applied_pwm", 2), ("board_gains", 4), ("timeout_ns", 1), ("max_accel", 1),
        ("frame_ms", 1), ("gains", 4))
FLAGS = (("enc_valid", 1), ("wrote", 1), ("moving", 1), ("pid_mode", 1), ("ready", 1),
         ("coast", 1))


def rows(layout: tuple[tuple[str, int], ...]) -> dict[str, tuple[int, int]]:
    """Each quantity's first row and width."""
    out, row = {}, 0
    for name, width in layout:
        out[name] = (row, width)
        row += width
    return out


def size(layout: tuple[tuple[str, int], ...]) -> int:
    """How many rows the block has."""
    return sum(width for _, width in layout)


def block(layout: tuple[tuple[str, int], ...], n: int, dtype: type) -> np.ndarray:
    """A zeroed ``(rows, n)`` block for ``n`` cars. Its rows are laid out a little longer than
    ``n`` (a view of the first ``n`` columns is returned): rows a power of two bytes apart
    (4,096 cars of 8 bytes) would all fall into the same sets of the CPU's cache, and a loop
    over cars that reads a car's numbers from 40 rows would evict its own lines (measured:
    three times slower at 4,096 cars)."""
    return np.zeros((size(layout), n + 8), dtype=dtype)[:, :n]


_F, _I, _B = rows(FLOATS), rows(INTS), rows(FLAGS)
# the row of each quantity (its first, for those of width > 1), as the compiled loops use them
X, Y, THETA, DX, DR = (_F[k][0] for k in ("x", "y", "theta", "dx", "dr"))
ODOM_V, ODOM_W, THEN, LAST_CMD, STAMP = (_F[k][0] for k in (
    "odom_v", "odom_w", "then", "last_cmd", "stamp"))
ZERO, DRIVE, DAMPING = (_F[k][0] for k in ("zero_angle", "drive_torque", "damping"))
TICKS_METER, BASE_WIDTH, STALL, BACK_EMF, RADIUS = (_F[k][0] for k in (
    "ticks_meter", "base_width", "stall", "back_emf", "wheel_radius"))
V_DES, V, ENC, F_TIME, VELOCITY, ENCODER = (_I[k][0] for k in (
    "v_des", "v", "enc", "f_time", "velocity", "encoder"))
PREV_ENC, PREV_ERR, IERROR, OUTPUT, TICKS, APPLIED = (_I[k][0] for k in (
    "prev_enc", "prev_err", "ierror", "output", "ticks", "applied_pwm"))
BOARD_GAINS, TIMEOUT_NS, MAX_ACCEL, FRAME_MS = (_I[k][0] for k in (
    "board_gains", "timeout_ns", "max_accel", "frame_ms"))
ENC_VALID, WROTE, MOVING, PID_MODE, READY, COAST = (_B[k][0] for k in (
    "enc_valid", "wrote", "moving", "pid_mode", "ready", "coast"))
