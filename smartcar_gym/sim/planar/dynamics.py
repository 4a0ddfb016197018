"""The planar car's equations of motion: plain functions of its state and parameters.

One car is a rigid body in the plane (centre of mass ``x, y``, heading ``(c, s)`` = cos, sin
of its yaw, world-frame velocity ``vx, vy``, yaw rate ``w``) and G wheel groups (a side's
wheels chained 1:1, or a lone wheel), each one rotational degree of freedom (angle ``phi``,
speed ``om``). Every value may be a Python float (one car, the single env) or a numpy array of
N cars (the batch): the functions use nothing but ``+ - * /`` and ``sqrt``, each element
computed with the same operations in the same order, so a car of a batch is bit for bit the
same car stepped alone (``tests/test_planar_dynamics.py``).

**Forces.** Each ground contact k (a wheel's lowest point, or a sliding point such as a
caster ball fixed to the body) at ``(rx, ry)`` from the centre of mass in the body frame slips
with velocity ``s = v + w x r + rolling * om_g`` (``rolling``: the contact point's velocity
relative to the body per unit of its wheel group's speed, ``(0, 0)`` for a sliding contact).
The ground pushes back with a regularised Coulomb force, the gradient of the dissipation
``D(s) = N_k sqrt(mx^2 sx^2 + my^2 sy^2 + mx^2 eps^2)``:

    F = -N_k (mx^2 sx, my^2 sy) / sqrt(mx^2 sx^2 + my^2 sy^2 + mx^2 eps^2)

(``N_k``: the contact's static normal load; ``mx``, ``my``: its friction coefficients along
and across the body's x axis; ``eps``: the slip speed at which friction reaches 71 % of its
Coulomb bound, i.e. the slip stiffness is ``mx N_k / eps``). With ``mx = my`` it is isotropic
Coulomb friction (the force opposes the slip in any direction, as the physics engines' friction
cones do); with ``my > mx`` an elliptic cone, whose tyre resists sliding sideways more than
along its rolling direction. The curve is smooth, tends to Coulomb friction as ``eps`` -> 0,
and, being a gradient, has a symmetric Jacobian. A wheel group feels its motor (drive torque
``tau``, back-EMF damping ``b``), the reaction of its contacts, and Coulomb friction ``T`` (the
gearbox's and the rolling resistance, regularised the same way over ``eps_w`` rad/s).

**Integration.** Linearly implicit (Rosenbrock-) Euler on the velocities: with ``J`` the
Jacobian of the forces at the start of the substep, ``(M - dt J) du = dt f(u)``. ``M - dt J``
is symmetric positive definite (friction and damping only take energy out), so the step is
stable at any ``dt`` however stiff the slip curve; the stiff slip modes are damped toward
their quasi-steady state instead of ringing. The system is solved exactly: the wheel groups
couple only through the body, so they are eliminated first (a Schur complement) and the 3x3
body system is solved by cofactors. Positions follow with the new velocities (symplectic
Euler); the heading turns by ``dt w`` as a Cayley rotation (``(c, s)`` stays a unit vector,
to rounding, without a trigonometric call, whose last bit numpy's vector code and libm may
disagree on).

**Stops.** Where a slip saturates, its tangent stiffness along the slip is nearly zero, so a
tyre (or a gearbox) that stops within the substep is carried through zero by its whole
Coulomb force and lands sliding the other way: the 20 ms step overshot the end of every
turn. A car whose tangent step reverses any slip (a contact's, in the metric of its friction
ellipse, or a wheel group's speed) is therefore solved again from the start, each reversed
force now entering by its *secant* stiffness ``A`` at the point of its slip's path nearest
zero: the force ``-A s``, linear in the new slip, under which a slip cannot change sign. For a
stop this is the fully implicit (backward Euler) step: in one dimension the new slip
``s / (1 + dt A / m)`` with ``A = mu N / eps`` is what ``m (s' - s) = -dt mu N s' /
sqrt(s'^2 + eps^2)`` gives when ``s'`` comes to rest. The other forces keep their tangents;
a car that reverses nothing keeps the first solve, bit for bit.

**Load transfer.** A contact's normal load is its static share of the weight plus its share of
the pitch and roll moments about the centre of mass that the loads carry, as the body neither
pitches nor rolls (``load_per_pitch``, ``load_per_roll``: the same least-squares split as the
static loads), from the previous substep: the moment of the ground's force, which acts the
centre of mass's ``height`` below it (the force the substep applied, ``m dv / dt``), less the
rate of change of the wheel groups' angular momentum (``spin_x``, ``spin_y`` per rad/s: the
axle's direction times the spin inertia that reacts on the body), spun up or down along their
axles and turned with the body. A load that would pull is zero. Braking moves load forward,
turning moves it outward, and so do wheels braking and spinning forward in a turn.

**Layout.** A car is three flat sequences (``state``, ``car``, ``contacts``) and its motors'
``drive``, indexed by the names ``layout`` defines (a table of each, with units), the same
whether they hold floats (a Python list: one car), ``(N,)`` arrays (rows of an ``(S, N)``
array: N cars at once in numpy) or float64 scalars (one car's row in the compiled loops,
``run_car`` where ``COMPILED``: numba installed and ``SMARTCAR_GYM_NUMBA`` not ``0``; the
batch's compiled loop is ``lanes``, the same arithmetic over blocks of cars); ``groups``: each
contact's wheel group (-1: sliding), shared by all cars.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

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
    ROLL_X,
    ROLL_Y,
    SIN,
    TORQUE,
    VX,
    VY,
    YAW_INERTIA,
    YAW_RATE,
    X,
    Y,
    car_rows,
    damping_row,
    group_count,
    state_rows,
)

Value = Any  # a float, or an (N,) float64 array of cars
#: the scratch rows ``substep`` works in (``SCRATCH_ROWS`` rows of G values): solve's sums per
#: group (force, its coupling to the body's three velocities, its own stiffness), the
#: eliminated groups' inverse diagonal and right-hand side, the groups' speed changes (``OUT``)
#: and, while solving again, the first solve's (``FIRST``)
FORCE, COUPLE_X, COUPLE_Y, COUPLE_W, STIFF, DIAG, RHS, OUT, FIRST = range(9)
SCRATCH_ROWS = FIRST + 1


def make_solve(sqrt: Callable[[Value], Value],
               where: Callable[[Value, Value, Value], Value]) -> Callable[..., tuple]:
    """One linearly implicit solve with this ``sqrt`` and ``where`` (see ``make_substep``)."""

    def solve(state: Any, car: Any, contacts: Any, groups: Sequence[int], drive: Any,
              dt: Value, scratch: Any, rows: tuple, vx: Value, vy: Value, w: Value,
              again: bool, du: Value, dv: Value, dw: Value) -> tuple:
        """The velocity change ``(du, dv, dw)`` of the body (body frame) over ``dt`` from
        ``(vx, vy, w)`` and the groups' speeds in ``state``; each group's goes to scratch row
        ``OUT``. ``rows``: the number of groups and their blocks' offsets, ``(G, speed, pitch,
        roll, coulomb, damping)`` (``layout``; ``substep`` finds them once).

        Each force enters by its tangent (its Jacobian at the start) or, ``again`` after a
        first solve whose changes were ``(du, dv, dw)`` and scratch row ``FIRST``, where that
        solve carried its slip through zero: by its secant stiffness ``A`` at the point of that
        solve's slip path nearest zero, the force ``-A s`` linear in the new slip.
        """
        eps2 = car[EPS2]
        ng, speed, pitch_at, roll_at, coulomb_at, damping_at = rows
        pitch = state[pitch_at]  # the moments the loads carried at the last substep
        roll = state[roll_at]
        f1 = f2 = f3 = 0.0
        a11 = a12 = a13 = a22 = a23 = a33 = 0.0
        fg, c1, c2, c3, dg, diag, rhs = (scratch[FORCE], scratch[COUPLE_X], scratch[COUPLE_Y],
                                         scratch[COUPLE_W], scratch[STIFF], scratch[DIAG],
                                         scratch[RHS])
        first = scratch[FIRST]
        for g in range(ng):
            fg[g] = c1[g] = c2[g] = c3[g] = dg[g] = 0.0 * vx
        for k in range(len(groups)):
            row = contacts[k]
            g = groups[k]
            rx, ry, kx, ky = row[CX], row[CY], row[FRICTION_X], row[FRICTION_Y]
            sx = vx - w * ry
            sy = vy + w * rx
            if g >= 0:
                sx = sx + row[ROLL_X] * state[speed + g]
                sy = sy + row[ROLL_Y] * state[speed + g]
            ux = kx * sx
            uy = ky * sy
            e2 = kx * kx * eps2
            q2 = ux * ux + uy * uy + e2
            load = row[LOAD] + row[LOAD_PER_PITCH] * pitch + row[LOAD_PER_ROLL] * roll
            load = 0.5 * (load + abs(load))  # a wheel lifted off carries nothing
            a = load / sqrt(q2)
            h = a / q2
            d11 = kx * kx * h * (uy * uy + e2)
            d22 = ky * ky * h * (ux * ux + e2)
            d12 = -kx * ky * h * ux * uy
            fx = -a * kx * ux
            fy = -a * ky * uy
            if again:
                px = du - dw * ry  # the first solve's change of this slip (scaled)
                py = dv + dw * rx
                if g >= 0:
                    px = px + row[ROLL_X] * first[g]
                    py = py + row[ROLL_Y] * first[g]
                px = kx * px
                py = ky * py
                along = ux * px + uy * py
                crossed = ux * ux + uy * uy + along < 0.0
                t = -along / (px * px + py * py + e2)  # nearest zero on u + t p
                nx = ux + t * px
                ny = uy + t * py
                sec = load / sqrt(nx * nx + ny * ny + e2)
                d11 = where(crossed, kx * kx * sec, d11)
                d22 = where(crossed, ky * ky * sec, d22)
                d12 = where(crossed, 0.0 * sec, d12)
                fx = where(crossed, -sec * kx * ux, fx)
                fy = where(crossed, -sec * ky * uy, fy)
            e1 = d12 * rx - d11 * ry
            e2 = d22 * rx - d12 * ry
            f1 = f1 + fx
            f2 = f2 + fy
            f3 = f3 + (rx * fy - ry * fx)
            a11 = a11 + d11
            a12 = a12 + d12
            a22 = a22 + d22
            a13 = a13 + e1
            a23 = a23 + e2
            a33 = a33 + (rx * e2 - ry * e1)
            if g >= 0:
                wx, wy = row[ROLL_X], row[ROLL_Y]
                k1 = d11 * wx + d12 * wy
                k2 = d12 * wx + d22 * wy
                fg[g] = fg[g] + (wx * fx + wy * fy)
                c1[g] = c1[g] + k1
                c2[g] = c2[g] + k2
                c3[g] = c3[g] + (rx * k2 - ry * k1)
                dg[g] = dg[g] + (wx * k1 + wy * k2)
        # the body's 3x3 block with the wheel groups eliminated (a Schur complement)
        s11 = car[MASS] + dt * a11
        s12 = dt * a12
        s13 = dt * a13
        s22 = car[MASS] + dt * a22
        s23 = dt * a23
        s33 = car[YAW_INERTIA] + dt * a33
        r1 = dt * f1
        r2 = dt * f2
        r3 = dt * f3
        eps_w2 = car[EPS_W2]
        for g in range(ng):
            o = state[speed + g]
            coulomb = car[coulomb_at + g]
            b = drive[damping_at + g]
            q2 = o * o + eps_w2
            root = sqrt(q2)
            friction = coulomb * o / root
            stiff = coulomb * eps_w2 / (q2 * root)
            if again:  # a gearbox carried through zero: its secant at zero speed
                crossed = o * (o + first[g]) < 0.0
                sec = coulomb / sqrt(eps_w2)
                friction = where(crossed, sec * o, friction)
                stiff = where(crossed, sec, stiff)
            rg = dt * (fg[g] + drive[TORQUE + g] - b * o - friction)
            dgg = car[INERTIA + g] + dt * (dg[g] + b + stiff)
            inv = 1.0 / dgg
            x1 = dt * c1[g]
            x2 = dt * c2[g]
            x3 = dt * c3[g]
            y1 = x1 * inv
            y2 = x2 * inv
            y3 = x3 * inv
            s11 = s11 - x1 * y1
            s12 = s12 - x1 * y2
            s13 = s13 - x1 * y3
            s22 = s22 - x2 * y2
            s23 = s23 - x2 * y3
            s33 = s33 - x3 * y3
            r1 = r1 - y1 * rg
            r2 = r2 - y2 * rg
            r3 = r3 - y3 * rg
            diag[g] = inv
            rhs[g] = rg
        k11 = s22 * s33 - s23 * s23
        k12 = s13 * s23 - s12 * s33
        k13 = s12 * s23 - s13 * s22
        k22 = s11 * s33 - s13 * s13
        k23 = s12 * s13 - s11 * s23
        k33 = s11 * s22 - s12 * s12
        inv_det = 1.0 / (s11 * k11 + s12 * k12 + s13 * k13)
        du = (k11 * r1 + k12 * r2 + k13 * r3) * inv_det
        dv = (k12 * r1 + k22 * r2 + k23 * r3) * inv_det
        dw = (k13 * r1 + k23 * r2 + k33 * r3) * inv_det
        out = scratch[OUT]
        for g in range(ng):
            out[g] = (rhs[g] - dt * (c1[g] * du + c2[g] * dv + c3[g] * dw)) * diag[g]
        return du, dv, dw

    return solve


def make_substep(sqrt: Callable[[Value], Value], solve: Callable[..., tuple],
                 where: Callable[[Value, Value, Value], Value],
                 anywhere: Callable[[Value], bool]) -> Callable[..., None]:
    """The substep function with this ``sqrt`` (``math.sqrt`` for floats and the compiled
    loop, ``numpy.sqrt`` for arrays of cars: both IEEE's correctly rounded square root), this
    ``solve`` (``make_solve(sqrt, where)``, compiled alongside), and ``where`` / ``anywhere``:
    a choice per car and whether any car chose (for floats ``a if c else b`` and ``c``; for
    arrays ``numpy.where`` and ``numpy.any``)."""

    def substep(state: Any, car: Any, contacts: Any, groups: Sequence[int], drive: Any,
                dt: Value, scratch: Any) -> None:
        """Advance ``state`` (in place) by ``dt`` s with ``drive``'s motor torques;
        ``scratch``: ``SCRATCH_ROWS`` rows of G values to work in (``new_scratch``)."""
        c, s, vxw, vyw, w = state[COS], state[SIN], state[VX], state[VY], state[YAW_RATE]
        vx = c * vxw + s * vyw  # body-frame velocity of the centre of mass
        vy = c * vyw - s * vxw
        ng = group_count(len(car))
        speed, pitch_at, roll_at = state_rows(ng)
        coulomb_at, spin_x, spin_y = car_rows(ng)
        rows = (ng, speed, pitch_at, roll_at, coulomb_at, damping_row(ng))
        zero = 0.0 * vx
        du, dv, dw = solve(state, car, contacts, groups, drive, dt, scratch, rows,
                           vx, vy, w, False, zero, zero, zero)
        # did the tangent step carry a slip through zero (a tyre's, or a gearbox's speed)?
        out, first = scratch[OUT], scratch[FIRST]
        crossed = zero > zero  # False: no car yet
        for g in range(ng):
            o = state[speed + g]
            first[g] = out[g]
            crossed = crossed | (o * (o + out[g]) < 0.0)
        for k in range(len(groups)):
            row = contacts[k]
            g = groups[k]
            sx = vx - w * row[CY]
            sy = vy + w * row[CX]
            px = du - dw * row[CY]
            py = dv + dw * row[CX]
            if g >= 0:
                sx = sx + row[ROLL_X] * state[speed + g]
                sy = sy + row[ROLL_Y] * state[speed + g]
                px = px + row[ROLL_X] * out[g]
                py = py + row[ROLL_Y] * out[g]
            kx2 = row[FRICTION_X] * row[FRICTION_X]
            ky2 = row[FRICTION_Y] * row[FRICTION_Y]
            crossed = crossed | (kx2 * sx * (sx + px) + ky2 * sy * (sy + py) < 0.0)
        if anywhere(crossed):
            # there the tangent overshoots the stop: solve again from the start, those forces
            # by their secants where their slips pass nearest zero (a slip cannot cross zero)
            bu, bv, bw = solve(state, car, contacts, groups, drive, dt, scratch, rows,
                               vx, vy, w, True, du, dv, dw)
            du = where(crossed, bu, du)
            dv = where(crossed, bv, dv)
            dw = where(crossed, bw, dw)
            for g in range(ng):
                out[g] = where(crossed, out[g], first[g])
        w = w + dw
        # the wheels' angular momentum (body frame) changes at (tx, ty): spun up or down
        # along their axles, and turned with the body (gyroscopic); the ground's loads supply
        # that moment, as they do the moment of the ground's force about the centre of mass
        tx = zero
        ty = zero
        for g in range(ng):
            o = state[speed + g] + out[g]
            state[speed + g] = o
            state[ANGLE + g] = state[ANGLE + g] + dt * o
            hx = car[spin_x + g]
            hy = car[spin_y + g]
            rate = out[g] / dt
            tx = tx + (hx * rate - w * hy * o)
            ty = ty + (hy * rate + w * hx * o)
        vxw = vxw + (c * du - s * dv)
        vyw = vyw + (s * du + c * dv)
        half = 0.5 * dt * w
        h2 = half * half
        scale = 1.0 / (1.0 + h2)
        lever = car[HEIGHT] * car[MASS] / dt  # the ground's force over the substep: m du / dt
        state[pitch_at] = -lever * du - ty  # the pitch moment the loads carry
        state[roll_at] = -lever * dv + tx  # and the roll moment
        turned_c = (c * (1.0 - h2) - 2.0 * half * s) * scale  # c, s may be views of state
        turned_s = (s * (1.0 - h2) + 2.0 * half * c) * scale
        state[X] = state[X] + dt * vxw
        state[Y] = state[Y] + dt * vyw
        state[COS] = turned_c
        state[SIN] = turned_s
        state[VX] = vxw
        state[VY] = vyw
        state[YAW_RATE] = w

    return substep


def _where(choose: bool, a: float, b: float) -> float:
    return a if choose else b


def _anywhere(choose: bool) -> bool:
    return choose


def _anywhere_arrays(choose: np.ndarray) -> bool:
    return bool(np.any(choose))


#: one car in Python floats (lists), and N cars in numpy arrays (rows of (S, N) arrays)
substep = make_substep(math.sqrt, make_solve(math.sqrt, _where), _where, _anywhere)
substep_arrays = make_substep(np.sqrt, make_solve(np.sqrt, np.where), np.where,
                              _anywhere_arrays)


def new_scratch(groups: int) -> list[list[Any]]:
    """The working rows ``substep`` takes for floats and for arrays (numba's loop takes a
    ``(SCRATCH_ROWS, G)`` array instead)."""
    return [[0.0] * groups for _ in range(SCRATCH_ROWS)]


# -- numba's compiled loops (jit.py). They live here, with the function they compile: numba
# keeps compiled code on disk until the file of the cached function changes, so a change to
# the substep function must change this file's stamp too.
try:  # pragma: no branch - one of the two, per installation
    import numba
except ImportError:  # the fast extra is not installed: Python floats and numpy arrays
    numba = None

#: whether the compiled loops below are used (numba installed and not switched off)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"

if COMPILED:
    _jit_where = numba.njit(cache=True)(_where)
    _compiled_substep = numba.njit(cache=True)(make_substep(
        math.sqrt, numba.njit(cache=True)(make_solve(math.sqrt, _jit_where)), _jit_where,
        numba.njit(cache=True)(_anywhere)))

    @numba.njit(cache=True)
    def run_car(state: np.ndarray, car: np.ndarray, contacts: np.ndarray, groups: np.ndarray,
                drive: np.ndarray, dt: float, n: int) -> None:
        """``n`` substeps of ``dt`` s of one car (1D ``state``, ``car``, ``drive``; ``(K, NC)``
        ``contacts``), in place."""
        scratch = np.zeros((SCRATCH_ROWS, group_count(car.shape[0])))
        for _ in range(n):
            _compiled_substep(state, car, contacts, groups, drive, dt, scratch)
else:
    run_car = None

#: substeps of single cars a process takes in Python floats before ``run_car`` (the same
#: numbers): a batch's builder, which only settles its car at a reset (six substeps), then
#: never compiles ``run_car`` (2.5 s the first time, before numba's cache holds it)
PYTHON_SUBSTEPS = 64
_python_left = PYTHON_SUBSTEPS


def compiled_run(n: int) -> bool:
    """Whether a single car's ``n`` substeps run in ``run_car`` (numba installed, and this
    process has taken its ``PYTHON_SUBSTEPS`` in Python floats), else in ``substep``."""
    global _python_left
    if not COMPILED:
        return False
    if _python_left <= 0:
        return True
    _python_left -= n
    return False


def load_transfer(points: np.ndarray) -> np.ndarray:
    """(K, 2): how each contact's load changes per newton-metre of the pitch moment
    (``sum(x_k dN_k)``) and of the roll moment (``sum(y_k dN_k)``) the loads must carry about
    the centre of mass, the loads' sum unchanged (the same least-squares split as
    ``static_loads``). The substep asks them to carry ``-h F`` (the ground's force ``F`` acts
    ``h`` below the centre of mass) less the rate of change of the wheels' angular momentum."""
    points = np.asarray(points, dtype=float)
    a = np.vstack([np.ones(len(points)), points[:, 0], points[:, 1]])
    moments = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    return a.T @ np.linalg.solve(a @ a.T, moments)


def static_loads(points: np.ndarray, com: np.ndarray, weight: float) -> np.ndarray:
    """Each contact's share of ``weight`` (N) for a rigid body at rest on ``points`` ((K, 2),
    m): force and moment balance about the centre of mass ``com`` (2,), the least-squares
    (equal springs) split when more than three points share the load.

    ValueError when the points cannot carry the body: fewer than three not on one line, or
    the centre of mass outside them (a contact would have to pull).
    """
    points = np.asarray(points, dtype=float)
    if len(points) < 3:
        raise ValueError(f"{len(points)} ground contacts cannot carry a rigid body in the plane "
                         "(at least three, not on one line)")
    a = np.vstack([np.ones(len(points)), points[:, 0], points[:, 1]])
    gram = a @ a.T
    if np.linalg.cond(gram) > 1e12:
        raise ValueError("the ground contacts lie on one line: the body would tip over")
    loads = a.T @ np.linalg.solve(gram, weight * np.array([1.0, com[0], com[1]]))
    if np.any(loads < -1e-9 * weight):
        raise ValueError(f"the centre of mass ({com[0]:.4f}, {com[1]:.4f}) m lies outside the "
                         "ground contacts: the body would tip over")
    return np.maximum(loads, 0.0)
