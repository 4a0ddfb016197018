"""The planar batch's compiled loop in lanes: ``LANES`` cars at once, each operation of
``dynamics.substep`` done for a block of cars in turn, so that the compiler computes it in the
CPU's vector registers (SIMD) instead of one car after the other.

The arithmetic is ``dynamics.make_solve`` and ``make_substep``'s, written out over a block:
the same operations in the same order for each car, with IEEE's correctly rounded ``+ - * /``
and square root whether scalar or vector (numba fuses no multiply-add), so every car is bit
for bit the car ``dynamics.substep`` steps alone (``tests/test_planar_lanes.py``). A change to
the substep must be made here too; that test fails until it is.

**Blocks.** A block's numbers sit in one flat buffer, row r of lane j at ``r LANES + j`` (its
state, drive and clock copied in, and a row per temporary value): the compiler then sees one
array whose rows lie a whole block apart, and vectorizes each loop over the lanes without
checking at run time whether arrays overlap. The names below (``DT``, ``SX``, ...) are those
rows' offsets. The parameters and contacts are read from ``blocked``'s copy, laid out the same
way (made once per ``set_model``). A car with fewer substeps than its block's most (or a
padding lane past the last car) keeps its state: each substep is computed for every lane and
written only to the lanes still stepping. A block none of whose cars steps is not copied in or
out at all (parked cars, cars with no time to go).

**Solving again.** Where a car's tangent step carries a slip through zero, ``dynamics`` solves
that car again (about one car in eight at a substep, in random driving): a block would solve
again whenever any of its 16 cars needs it, nearly always. So ``PASS`` blocks take each
substep together: each solves once, the lanes that must solve again are copied into a queue
block, solved there again, and their results copied back, before each block finishes its
substep.

Used only where numba is installed (``dynamics.COMPILED``); without it the batch steps numpy
arrays (``dynamics.substep_arrays``).
"""

from __future__ import annotations

import math

import numpy as np

from smartcar_gym.sim.planar.dynamics import COMPILED
from smartcar_gym.sim.planar.layout import (
    ANGLE,
    COS,
    CX,
    CY,
    EPS2,
    EPS_W2,
    FRICTION_X,
    FRICTION_Y,
    HEIGHT,
    INERTIA,
    LOAD,
    LOAD_PER_PITCH,
    LOAD_PER_ROLL,
    MASS,
    NC,
    ROLL_X,
    ROLL_Y,
    SIN,
    VX,
    VY,
    YAW_INERTIA,
    YAW_RATE,
    X,
    Y,
    car_rows,
    state_rows,
)

#: cars a block: 16 float64 are two AVX-512 registers or four AVX2 ones (8 and 32 were no
#: faster at 4,096 cars)
LANES = 16
#: blocks that take a substep together, sharing a queue of the lanes that solve again
PASS = 16

# a block's rows, as offsets into its buffer: the lanes' clock and substeps, the body-frame
# velocity, the solve's sums and the body's changes, one contact's values while its sums are
# taken, then the block's state (S rows: STATE + its row), drive (2 G rows) and each wheel
# group's values (GROUP rows a group: FG ... FIRST)
(DT, STEPS, BODY_VX, BODY_VY, STEPPING, CROSSED,
 F1, F2, F3, A11, A12, A13, A22, A23, A33,
 S11, S12, S13, S22, S23, S33, R1, R2, R3,
 DU, DV, DW, BU, BV, BW, TX, TY,
 SX, SY, UX, UY, E2, LOADS, D11, D22, D12, FX, FY,
 STATE) = range(0, 44 * LANES, LANES)
FG, C1, C2, C3, DG, DIAG, RHS, OUT, FIRST = range(0, 9 * LANES, LANES)
GROUP = 9 * LANES
# the state's rows in the buffer, and the parameters' and a contact's in ``blocked``'s
_X, _Y, _COS, _SIN, _VX, _VY, _W, _ANGLE = (STATE + r * LANES for r in (X, Y, COS, SIN, VX, VY,
                                                                         YAW_RATE, ANGLE))
_MASS, _YAW_INERTIA, _EPS2, _EPS_W2, _HEIGHT, _INERTIA = (
    r * LANES for r in (MASS, YAW_INERTIA, EPS2, EPS_W2, HEIGHT, INERTIA))
_CX, _CY, _ROLL_X, _ROLL_Y, _LOAD, _FRICTION_X, _FRICTION_Y, _PER_PITCH, _PER_ROLL = (
    r * LANES for r in (CX, CY, ROLL_X, ROLL_Y, LOAD, FRICTION_X, FRICTION_Y, LOAD_PER_PITCH,
                        LOAD_PER_ROLL))


def blocked(car: np.ndarray, contacts: np.ndarray) -> np.ndarray:
    """The parameters ``(P, N)`` and contacts ``(K, NC, N)`` of N cars laid out by block of
    ``LANES`` cars: ``(ceil(N / LANES), (P + K NC) LANES)``, a block's row r lane j at ``r
    LANES + j``; the last block's padding a copy of its first car (numbers that step like a
    car's, and are never written back)."""
    n = car.shape[1]
    rows = np.concatenate([car, contacts.reshape(-1, n)])
    blocks = -(-n // LANES)
    padded = np.empty((rows.shape[0], blocks * LANES))
    padded[:, :n] = rows
    padded[:, n:] = rows[:, (blocks - 1) * LANES][:, None]
    by_block = padded.reshape(rows.shape[0], blocks, LANES).transpose(1, 0, 2)
    return np.ascontiguousarray(by_block).reshape(blocks, -1)


if COMPILED:
    import numba

    _jit = numba.njit(cache=True, nogil=True, error_model="numpy")
    # the solve and the queue's take their types from a signature, compiled when this module
    # is imported (the batch's first use): called with constants (the first solve or the
    # second, a queue of 0 cars), numba would type and compile them once per constant, the
    # solve twice (measured: compiling the lanes the first time took 7.3 s, 5.9 s with these)
    _typed = {"cache": True, "nogil": True, "error_model": "numpy"}

    @_jit
    def _layout(ng: int) -> tuple[int, int, int, int, int, int]:
        """The rows of a block of cars with ``ng`` wheel groups: the groups' speeds, the
        pitch and roll moments, the drive, the groups' values; the contacts' first row in
        the parameters."""
        speed, pitch, roll = state_rows(ng)
        drive = STATE + (roll + 1) * LANES
        return (STATE + speed * LANES, STATE + pitch * LANES, STATE + roll * LANES, drive,
                drive + 2 * ng * LANES, (INERTIA + 4 * ng) * LANES)

    @numba.njit("void(float64[::1], float64[::1], int64[::1], int64, boolean, int64)",
                **_typed)
    def _solve(b: np.ndarray, prm: np.ndarray, groups: np.ndarray, ng: int,
               again: bool, out: int) -> None:
        """``dynamics.make_solve``'s solve for every lane: the body's changes to rows ``out``
        .. ``out + 2``, each group's to its ``OUT`` row. ``again``: the second solve, after a
        first whose changes are in ``DU`` .. ``DW`` and the ``FIRST`` rows."""
        speed, pitch_at, roll_at, drive, gr, kc = _layout(ng)
        coulomb_at = car_rows(ng)[0] * LANES
        for j in range(LANES):
            b[F1 + j] = b[F2 + j] = b[F3 + j] = 0.0
            b[A11 + j] = b[A12 + j] = b[A13 + j] = 0.0
            b[A22 + j] = b[A23 + j] = b[A33 + j] = 0.0
        for g in range(ng):
            at = gr + g * GROUP
            for j in range(LANES):
                zero = 0.0 * b[BODY_VX + j]
                b[at + FG + j] = b[at + C1 + j] = b[at + C2 + j] = zero
                b[at + C3 + j] = b[at + DG + j] = zero
        for k in range(groups.shape[0]):
            c = kc + k * NC * LANES
            g = groups[k]
            om = speed + g * LANES
            for j in range(LANES):  # the contact's slip
                w = b[_W + j]
                b[SX + j] = b[BODY_VX + j] - w * prm[c + _CY + j]
                b[SY + j] = b[BODY_VY + j] + w * prm[c + _CX + j]
            if g >= 0:
                for j in range(LANES):
                    b[SX + j] = b[SX + j] + prm[c + _ROLL_X + j] * b[om + j]
                    b[SY + j] = b[SY + j] + prm[c + _ROLL_Y + j] * b[om + j]
            for j in range(LANES):  # its force and tangent stiffness
                kx, ky = prm[c + _FRICTION_X + j], prm[c + _FRICTION_Y + j]
                ux = kx * b[SX + j]
                uy = ky * b[SY + j]
                e2 = kx * kx * prm[_EPS2 + j]
                q2 = ux * ux + uy * uy + e2
                load = (prm[c + _LOAD + j] + prm[c + _PER_PITCH + j] * b[pitch_at + j]
                        + prm[c + _PER_ROLL + j] * b[roll_at + j])
                load = 0.5 * (load + abs(load))
                a = load / math.sqrt(q2)
                h = a / q2
                b[D11 + j] = kx * kx * h * (uy * uy + e2)
                b[D22 + j] = ky * ky * h * (ux * ux + e2)
                b[D12 + j] = -kx * ky * h * ux * uy
                b[FX + j] = -a * kx * ux
                b[FY + j] = -a * ky * uy
                b[UX + j], b[UY + j], b[E2 + j], b[LOADS + j] = ux, uy, e2, load
            if again:  # where the first solve carried the slip through zero: its secant
                first = gr + g * GROUP + FIRST
                for j in range(LANES):
                    b[SX + j] = b[DU + j] - b[DW + j] * prm[c + _CY + j]
                    b[SY + j] = b[DV + j] + b[DW + j] * prm[c + _CX + j]
                if g >= 0:
                    for j in range(LANES):
                        b[SX + j] = b[SX + j] + prm[c + _ROLL_X + j] * b[first + j]
                        b[SY + j] = b[SY + j] + prm[c + _ROLL_Y + j] * b[first + j]
                for j in range(LANES):
                    kx, ky = prm[c + _FRICTION_X + j], prm[c + _FRICTION_Y + j]
                    ux, uy, e2 = b[UX + j], b[UY + j], b[E2 + j]
                    px = kx * b[SX + j]
                    py = ky * b[SY + j]
                    along = ux * px + uy * py
                    crossed = ux * ux + uy * uy + along < 0.0
                    t = -along / (px * px + py * py + e2)
                    nx = ux + t * px
                    ny = uy + t * py
                    sec = b[LOADS + j] / math.sqrt(nx * nx + ny * ny + e2)
                    b[D11 + j] = kx * kx * sec if crossed else b[D11 + j]
                    b[D22 + j] = ky * ky * sec if crossed else b[D22 + j]
                    b[D12 + j] = 0.0 * sec if crossed else b[D12 + j]
                    b[FX + j] = -sec * kx * ux if crossed else b[FX + j]
                    b[FY + j] = -sec * ky * uy if crossed else b[FY + j]
            for j in range(LANES):  # the body's sums
                rx, ry = prm[c + _CX + j], prm[c + _CY + j]
                d11, d22, d12 = b[D11 + j], b[D22 + j], b[D12 + j]
                fx, fy = b[FX + j], b[FY + j]
                e1 = d12 * rx - d11 * ry
                e2 = d22 * rx - d12 * ry
                b[F1 + j] = b[F1 + j] + fx
                b[F2 + j] = b[F2 + j] + fy
                b[F3 + j] = b[F3 + j] + (rx * fy - ry * fx)
                b[A11 + j] = b[A11 + j] + d11
                b[A12 + j] = b[A12 + j] + d12
                b[A22 + j] = b[A22 + j] + d22
                b[A13 + j] = b[A13 + j] + e1
                b[A23 + j] = b[A23 + j] + e2
                b[A33 + j] = b[A33 + j] + (rx * e2 - ry * e1)
            if g >= 0:  # and its group's
                at = gr + g * GROUP
                for j in range(LANES):
                    rx, ry = prm[c + _CX + j], prm[c + _CY + j]
                    wx, wy = prm[c + _ROLL_X + j], prm[c + _ROLL_Y + j]
                    d11, d22, d12 = b[D11 + j], b[D22 + j], b[D12 + j]
                    k1 = d11 * wx + d12 * wy
                    k2 = d12 * wx + d22 * wy
                    b[at + FG + j] = b[at + FG + j] + (wx * b[FX + j] + wy * b[FY + j])
                    b[at + C1 + j] = b[at + C1 + j] + k1
                    b[at + C2 + j] = b[at + C2 + j] + k2
                    b[at + C3 + j] = b[at + C3 + j] + (rx * k2 - ry * k1)
                    b[at + DG + j] = b[at + DG + j] + (wx * k1 + wy * k2)
        # the body's 3x3 block with the wheel groups eliminated (a Schur complement)
        for j in range(LANES):
            dt = b[DT + j]
            b[S11 + j] = prm[_MASS + j] + dt * b[A11 + j]
            b[S12 + j] = dt * b[A12 + j]
            b[S13 + j] = dt * b[A13 + j]
            b[S22 + j] = prm[_MASS + j] + dt * b[A22 + j]
            b[S23 + j] = dt * b[A23 + j]
            b[S33 + j] = prm[_YAW_INERTIA + j] + dt * b[A33 + j]
            b[R1 + j] = dt * b[F1 + j]
            b[R2 + j] = dt * b[F2 + j]
            b[R3 + j] = dt * b[F3 + j]
        for g in range(ng):
            at = gr + g * GROUP
            om = speed + g * LANES
            for j in range(LANES):
                dt = b[DT + j]
                o = b[om + j]
                eps_w2 = prm[_EPS_W2 + j]
                coulomb = prm[coulomb_at + g * LANES + j]
                damping = b[drive + (ng + g) * LANES + j]
                q2 = o * o + eps_w2
                root = math.sqrt(q2)
                friction = coulomb * o / root
                stiff = coulomb * eps_w2 / (q2 * root)
                if again:  # a gearbox carried through zero: its secant at zero speed
                    sec = coulomb / math.sqrt(eps_w2)
                    crossed = o * (o + b[at + FIRST + j]) < 0.0
                    friction = sec * o if crossed else friction
                    stiff = sec if crossed else stiff
                torque = b[drive + g * LANES + j]
                rg = dt * (b[at + FG + j] + torque - damping * o - friction)
                dgg = prm[_INERTIA + g * LANES + j] + dt * (b[at + DG + j] + damping + stiff)
                inv = 1.0 / dgg
                x1 = dt * b[at + C1 + j]
                x2 = dt * b[at + C2 + j]
                x3 = dt * b[at + C3 + j]
                y1 = x1 * inv
                y2 = x2 * inv
                y3 = x3 * inv
                b[S11 + j] = b[S11 + j] - x1 * y1
                b[S12 + j] = b[S12 + j] - x1 * y2
                b[S13 + j] = b[S13 + j] - x1 * y3
                b[S22 + j] = b[S22 + j] - x2 * y2
                b[S23 + j] = b[S23 + j] - x2 * y3
                b[S33 + j] = b[S33 + j] - x3 * y3
                b[R1 + j] = b[R1 + j] - y1 * rg
                b[R2 + j] = b[R2 + j] - y2 * rg
                b[R3 + j] = b[R3 + j] - y3 * rg
                b[at + DIAG + j] = inv
                b[at + RHS + j] = rg
        for j in range(LANES):
            s11, s12, s13 = b[S11 + j], b[S12 + j], b[S13 + j]
            s22, s23, s33 = b[S22 + j], b[S23 + j], b[S33 + j]
            r1, r2, r3 = b[R1 + j], b[R2 + j], b[R3 + j]
            k11 = s22 * s33 - s23 * s23
            k12 = s13 * s23 - s12 * s33
            k13 = s12 * s23 - s13 * s22
            k22 = s11 * s33 - s13 * s13
            k23 = s12 * s13 - s11 * s23
            k33 = s11 * s22 - s12 * s12
            inv_det = 1.0 / (s11 * k11 + s12 * k12 + s13 * k13)
            b[out + j] = (k11 * r1 + k12 * r2 + k13 * r3) * inv_det
            b[out + LANES + j] = (k12 * r1 + k22 * r2 + k23 * r3) * inv_det
            b[out + 2 * LANES + j] = (k13 * r1 + k23 * r2 + k33 * r3) * inv_det
        for g in range(ng):
            at = gr + g * GROUP
            for j in range(LANES):
                du, dv, dw = b[out + j], b[out + LANES + j], b[out + 2 * LANES + j]
                coupled = b[at + C1 + j] * du + b[at + C2 + j] * dv + b[at + C3 + j] * dw
                b[at + OUT + j] = (b[at + RHS + j] - b[DT + j] * coupled) * b[at + DIAG + j]

    @_jit
    def _begin(b: np.ndarray, prm: np.ndarray, groups: np.ndarray, ng: int, sub: int) -> bool:
        """The first half of ``dynamics.make_substep``'s substep, for every lane: the tangent
        solve, and whether it carried a slip through zero (row ``CROSSED``); whether any lane
        still stepping must solve again."""
        speed, pitch_at, roll_at, drive, gr, kc = _layout(ng)
        for j in range(LANES):
            c, s = b[_COS + j], b[_SIN + j]
            vxw, vyw = b[_VX + j], b[_VY + j]
            b[BODY_VX + j] = c * vxw + s * vyw  # body-frame velocity of the centre of mass
            b[BODY_VY + j] = c * vyw - s * vxw
            b[STEPPING + j] = 1.0 if b[STEPS + j] > sub else 0.0
            b[CROSSED + j] = 0.0
        _solve(b, prm, groups, ng, False, DU)
        for g in range(ng):  # a gearbox's speed through zero?
            at = gr + g * GROUP
            om = speed + g * LANES
            for j in range(LANES):
                o = b[om + j]
                b[at + FIRST + j] = b[at + OUT + j]
                turned = o * (o + b[at + OUT + j]) < 0.0
                b[CROSSED + j] = 1.0 if turned else b[CROSSED + j]
        for k in range(groups.shape[0]):  # a tyre's slip? (its change to rows UX, UY here)
            c = kc + k * NC * LANES
            g = groups[k]
            for j in range(LANES):
                w = b[_W + j]
                b[SX + j] = b[BODY_VX + j] - w * prm[c + _CY + j]
                b[SY + j] = b[BODY_VY + j] + w * prm[c + _CX + j]
                b[UX + j] = b[DU + j] - b[DW + j] * prm[c + _CY + j]
                b[UY + j] = b[DV + j] + b[DW + j] * prm[c + _CX + j]
            if g >= 0:
                om = speed + g * LANES
                out = gr + g * GROUP + OUT
                for j in range(LANES):
                    wx, wy = prm[c + _ROLL_X + j], prm[c + _ROLL_Y + j]
                    b[SX + j] = b[SX + j] + wx * b[om + j]
                    b[SY + j] = b[SY + j] + wy * b[om + j]
                    b[UX + j] = b[UX + j] + wx * b[out + j]
                    b[UY + j] = b[UY + j] + wy * b[out + j]
            for j in range(LANES):
                kx2 = prm[c + _FRICTION_X + j] * prm[c + _FRICTION_X + j]
                ky2 = prm[c + _FRICTION_Y + j] * prm[c + _FRICTION_Y + j]
                sx, sy = b[SX + j], b[SY + j]
                turned = kx2 * sx * (sx + b[UX + j]) + ky2 * sy * (sy + b[UY + j]) < 0.0
                b[CROSSED + j] = 1.0 if turned else b[CROSSED + j]
        again = False
        for j in range(LANES):
            b[CROSSED + j] = b[CROSSED + j] * b[STEPPING + j]
            again = again or b[CROSSED + j] != 0.0
        return again

    @_jit
    def _finish(b: np.ndarray, prm: np.ndarray, ng: int) -> None:
        """The rest of the substep, from the body's changes ``DU`` .. ``DW`` and the groups'
        ``OUT`` rows: the new state, written to the lanes still stepping."""
        speed, pitch_at, roll_at, drive, gr, kc = _layout(ng)
        spin_x, spin_y = car_rows(ng)[1] * LANES, car_rows(ng)[2] * LANES
        for j in range(LANES):
            b[TX + j] = 0.0 * b[BODY_VX + j]
            b[TY + j] = b[TX + j]
        for g in range(ng):
            out = gr + g * GROUP + OUT
            om = speed + g * LANES
            angle = _ANGLE + g * LANES
            for j in range(LANES):
                dt = b[DT + j]
                w = b[_W + j] + b[DW + j]
                o = b[om + j] + b[out + j]
                hx = prm[spin_x + g * LANES + j]
                hy = prm[spin_y + g * LANES + j]
                rate = b[out + j] / dt
                b[TX + j] = b[TX + j] + (hx * rate - w * hy * o)
                b[TY + j] = b[TY + j] + (hy * rate + w * hx * o)
                stepping = b[STEPPING + j] != 0.0
                b[angle + j] = b[angle + j] + dt * o if stepping else b[angle + j]
                b[om + j] = o if stepping else b[om + j]
        for j in range(LANES):
            dt = b[DT + j]
            c, s = b[_COS + j], b[_SIN + j]
            du, dv = b[DU + j], b[DV + j]
            w = b[_W + j] + b[DW + j]
            vxw = b[_VX + j] + (c * du - s * dv)
            vyw = b[_VY + j] + (s * du + c * dv)
            half = 0.5 * dt * w
            h2 = half * half
            scale = 1.0 / (1.0 + h2)
            lever = prm[_HEIGHT + j] * prm[_MASS + j] / dt
            pitch = -lever * du - b[TY + j]
            roll = -lever * dv + b[TX + j]
            turned_c = (c * (1.0 - h2) - 2.0 * half * s) * scale
            turned_s = (s * (1.0 - h2) + 2.0 * half * c) * scale
            x, y = b[_X + j], b[_Y + j]
            if_stepping = b[STEPPING + j] != 0.0
            b[pitch_at + j] = pitch if if_stepping else b[pitch_at + j]
            b[roll_at + j] = roll if if_stepping else b[roll_at + j]
            b[_X + j] = x + dt * vxw if if_stepping else x
            b[_Y + j] = y + dt * vyw if if_stepping else y
            b[_COS + j] = turned_c if if_stepping else c
            b[_SIN + j] = turned_s if if_stepping else s
            b[_VX + j] = vxw if if_stepping else b[_VX + j]
            b[_VY + j] = vyw if if_stepping else b[_VY + j]
            b[_W + j] = w if if_stepping else b[_W + j]

    @numba.njit("void(float64[::1], float64[::1], int64[:, ::1], int64, float64[:, ::1], "
                "int64[::1], int64)", **_typed)
    def _queue_again(queue: np.ndarray, queue_prm: np.ndarray, who: np.ndarray, queued: int,
                     bufs: np.ndarray, groups: np.ndarray, ng: int) -> None:
        """Solve the ``queued`` lanes of ``queue`` again, and copy their results back to their
        blocks' lanes (``who``: block in the pass, lane)."""
        _solve(queue, queue_prm, groups, ng, True, BU)
        gr = _layout(ng)[4]
        for q in range(queued):
            b = bufs[who[q, 0]]
            j = who[q, 1]
            b[DU + j], b[DV + j], b[DW + j] = queue[BU + q], queue[BV + q], queue[BW + q]
            for g in range(ng):
                b[gr + g * GROUP + OUT + j] = queue[gr + g * GROUP + OUT + q]

    @_jit
    def _most(n: np.ndarray, lo: int, hi: int) -> int:
        """The largest of ``n[lo:hi]`` (integers, ``hi > lo``): ``n[lo:hi].max()``, without
        numba's compiling numpy's ``max`` into ``run_blocks`` (0.7 s of a first run)."""
        most = n[lo]
        for k in range(lo + 1, hi):
            if n[k] > most:
                most = n[k]
        return most

    @_jit
    def run_blocks(state: np.ndarray, blocks: np.ndarray, groups: np.ndarray,
                   drive: np.ndarray, dt: np.ndarray, n: np.ndarray, first: int,
                   last: int) -> None:
        """Blocks ``first`` .. ``last - 1`` of the batch: car i ``n[i]`` substeps of ``dt[i]``
        s, in place. ``state`` ``(S, N)`` and ``drive`` ``(2G, N)`` in the batch's layout,
        ``blocks`` the parameters and contacts by block (``blocked``)."""
        ns, nd, cars = state.shape[0], drive.shape[0], state.shape[1]
        ng = nd // 2
        at_drive = _layout(ng)[3]
        size = at_drive + (nd + ng * 9) * LANES
        bufs = np.zeros((PASS, size))
        queue = np.zeros(size)
        queue_prm = np.zeros(blocks.shape[1])
        who = np.zeros((LANES, 2), dtype=np.int64)
        most = np.zeros(PASS, dtype=np.int64)  # each block's most substeps
        # what the second solve reads of a lane: rows copied to the queue
        copied = np.array([DT, BODY_VX, BODY_VY, DU, DV, DW], dtype=np.int64)
        for start in range(first, last, PASS):
            stop = min(start + PASS, last)
            for block in range(start, stop):  # gather the pass's cars
                base = block * LANES
                width = min(LANES, cars - base)
                most[block - start] = _most(n, base, base + width)
                if most[block - start] == 0:  # no car of it steps: nothing to copy
                    continue
                b = bufs[block - start]
                for j in range(LANES):  # the padding lanes: the first car's, unstepped
                    car = base + j if j < width else base
                    for r in range(ns):
                        b[STATE + r * LANES + j] = state[r, car]
                    for r in range(nd):
                        b[at_drive + r * LANES + j] = drive[r, car]
                    b[DT + j] = dt[car]
                    b[STEPS + j] = n[car] if j < width else 0
            for sub in range(_most(most, 0, stop - start)):
                queued = 0
                for block in range(start, stop):
                    b = bufs[block - start]
                    prm = blocks[block]
                    if most[block - start] <= sub or not _begin(b, prm, groups, ng, sub):
                        continue
                    for j in range(LANES):  # its lanes that solve again, to the queue
                        if b[CROSSED + j] == 0.0:
                            continue
                        for r in copied:
                            queue[r + queued] = b[r + j]
                        for r in range(STATE, size, LANES):  # state, drive, groups' rows
                            queue[r + queued] = b[r + j]
                        for r in range(0, prm.shape[0], LANES):
                            queue_prm[r + queued] = prm[r + j]
                        who[queued, 0], who[queued, 1] = block - start, j
                        queued += 1
                        if queued == LANES:
                            _queue_again(queue, queue_prm, who, queued, bufs, groups, ng)
                            queued = 0
                if queued:
                    _queue_again(queue, queue_prm, who, queued, bufs, groups, ng)
                for block in range(start, stop):
                    if most[block - start] > sub:
                        _finish(bufs[block - start], blocks[block], ng)
            for block in range(start, stop):  # scatter the new states
                if most[block - start] == 0:
                    continue
                b = bufs[block - start]
                base = block * LANES
                for j in range(min(LANES, cars - base)):
                    for r in range(ns):
                        state[r, base + j] = b[STATE + r * LANES + j]
