"""N planar cars in arrays: the batch behind the planar vector envs and the fit's replays.

Each car is a column: its state ``(S, N)``, its parameters ``(P, N)`` and contacts
``(K, NC, N)`` in ``dynamics``' layout (every car has the template's wheel groups and contacts;
the values may differ per car), its motors' drive ``(2G, N)``. ``step`` gives every listed car
its own number of substeps of its own length, as its single env's clock would: numba's
loop in lanes (``lanes.run_blocks``, 16 cars at once in the CPU's vector registers, reading
the parameters laid out by block: ``blocks``; the blocks split over ``threads`` threads) when
installed, else ``dynamics.substep_arrays`` over the cars still stepping (their columns taken
out and put back). A car of the batch is the same car as ``PlanarBody`` steps alone, bit for
bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from smartcar_gym.parallel import run_chunks
from smartcar_gym.sim.planar import dynamics, lanes
from smartcar_gym.sim.planar.body import PlanarBody, yaw_quaternion
from smartcar_gym.sim.planar.dynamics import new_scratch, substep_arrays
from smartcar_gym.sim.planar.layout import (
    ANGLE,
    COS,
    NC,
    SIN,
    TORQUE,
    VX,
    VY,
    X,
    Y,
    damping_row,
    drive_size,
    speed_row,
)
from smartcar_gym.sim.planar.model import PlanarCar

#: cars per chunk below which splitting the dynamics over threads costs more than it saves (a
#: car's substeps take under a microsecond; a split and a thread's wake-up cost more). Measured
#: on 2 threads, interleaved, ms a batch step: 16 cars 0.84-0.97 split in 4 against 0.51-0.55
#: unsplit; 1,024 cars 5.34 split in 2 against 5.15; 2,048 cars 9.84 against 11.13; 4,096
#: cars 13.95 against 16.33. In lanes (2026-11-30), 2,048 cars: physics 1.50-1.75 ms a step
#: split, 2.0 unsplit. The boards split from 8,192 cars (``controller.compiled``).
MIN_CHUNK_CARS = 1024


class PlanarBatch:
    """``n`` copies of a compiled ``PlanarBody`` (the template's robot at its spawn pose)."""

    def __init__(self, body: PlanarBody, n: int, threads: int = 1) -> None:
        model = body.compiled()
        self.n = int(n)
        #: threads numba's loop splits the cars over (``parallel.run_chunks``; each car is
        #: stepped alone, so any split gives the same bits)
        self.threads = int(threads)
        self.groups = model.groups
        self.ng = len(model.groups.members)
        self.contact_groups = np.array(model.contact_groups, dtype=np.int64)
        #: each car's centre of mass in base_link's frame, x and y (m)
        self.com_x = np.full(self.n, float(model.com[0]))
        self.com_y = np.full(self.n, float(model.com[1]))
        self._tables: dict[tuple, tuple] = {}  # ``_joint_rows``' arrays by joints
        #: each car's base_link height above the ground (m)
        self.height = np.full(self.n, float(body.height))
        self.initial = np.array(body.state, dtype=np.float64)
        self.state = _columns(self.initial, self.n)
        self.car = _columns(np.array(model.car, dtype=np.float64), self.n)
        self.contacts = _columns(np.array(model.contacts, dtype=np.float64).reshape(-1, NC),
                                 self.n)
        self.drive = _columns(np.zeros(drive_size(self.ng)), self.n)
        self._blocks: np.ndarray | None = None

    # -- cars ----------------------------------------------------------------------------------
    def reset(self, idx: np.ndarray, state: np.ndarray | None = None) -> None:
        """The listed cars back to the template's spawn (or to ``state``, (S,) or (S, len))."""
        new = self.initial if state is None else np.asarray(state, dtype=np.float64)
        self.state[:, idx] = new[:, None] if new.ndim == 1 else new
        self.drive[:, idx] = 0.0

    def set_model(self, idx: Sequence[int] | np.ndarray, model: PlanarCar,
                  height: float | None = None) -> None:
        """Give the listed cars another car's parameters, contacts and centre of mass (same
        layout), and its base_link ``height`` where given (a body of other wheels)."""
        if len(model.contacts) != self.contacts.shape[0] or \
                len(model.groups.members) != self.ng:
            raise ValueError("a car of the batch must have the template's contacts and groups")
        self.car[:, idx] = np.array(model.car)[:, None]
        self.contacts[:, :, idx] = np.array(model.contacts).reshape(-1, NC)[:, :, None]
        self.com_x[idx], self.com_y[idx] = float(model.com[0]), float(model.com[1])
        if height is not None:
            self.height[idx] = float(height)
        self._blocks = None

    def blocks(self) -> np.ndarray:
        """``car`` and ``contacts`` laid out by block of cars for numba's loop
        (``lanes.blocked``); made again after ``set_model`` (the only writer of ``car`` and
        ``contacts``)."""
        if self._blocks is None:
            self._blocks = lanes.blocked(self.car, self.contacts)
        return self._blocks

    def step(self, cars: np.ndarray, nstep: np.ndarray, dt: np.ndarray) -> None:
        """Car ``cars[k]``: ``nstep[k]`` substeps of ``dt[k]`` s."""
        if len(cars) == 0:
            return
        if dynamics.COMPILED:
            n_all = np.zeros(self.n, dtype=np.int64)
            dt_all = np.zeros(self.n)
            n_all[cars], dt_all[cars] = nstep, dt
            blocks = self.blocks()
            state, drive, groups = self.state, self.drive, self.contact_groups

            def work(a: int, b: int) -> None:  # a range of blocks (the loop frees the GIL)
                lanes.run_blocks(state, blocks, groups, drive, dt_all, n_all, a, b)

            run_chunks(work, len(blocks), self.threads, MIN_CHUNK_CARS // lanes.LANES)
            return
        cars, nstep = np.asarray(cars), np.asarray(nstep)
        dt = np.asarray(dt, dtype=np.float64)
        groups = tuple(int(g) for g in self.contact_groups)
        scratch = new_scratch(self.ng)
        for k in range(int(nstep.max())):
            going = nstep > k  # the cars with substeps left: each slot steps exactly those
            idx = cars[going]
            if len(idx) == self.n and np.array_equal(idx, np.arange(self.n)):
                substep_arrays(self.state, self.car, self.contacts, groups, self.drive,
                               dt[going], scratch)
                continue
            state = self.state[:, idx]
            substep_arrays(state, self.car[:, idx], self.contacts[:, :, idx], groups,
                           self.drive[:, idx], dt[going], scratch)
            self.state[:, idx] = state

    # -- what the robot reads and writes -------------------------------------------------------
    def joint_angles(self, joints: Sequence[tuple[int, float]],
                     scale: Sequence[float] | None = None) -> np.ndarray:
        """(N, J): each joint's angle (``sign * angle`` of its group), as ``PlanarBody``;
        times ``scale[j]`` after that, where given (the encoders' signs)."""
        return self._joint_rows(joints, ANGLE, scale)

    def joint_speeds(self, joints: Sequence[tuple[int, float]]) -> np.ndarray:
        """(N, J): each joint's speed."""
        return self._joint_rows(joints, speed_row(self.ng))

    def _joint_rows(self, joints: Sequence[tuple[int, float]], first: int,
                    scale: Sequence[float] | None = None) -> np.ndarray:
        """(N, J): ``sign * state[first + g]`` of each joint's group ``g``, times ``scale``
        where given (numba's loop where installed: the same multiplies)."""
        if dynamics.COMPILED:
            out = np.empty((self.n, len(joints)))
            _gather(self.state, *self.joint_table(joints, first, scale), out)
            return out
        values = np.stack([sign * self.state[first + g] for g, sign in joints], axis=1)
        return values if scale is None else values * np.asarray(scale, dtype=float)

    def joint_table(self, joints: Sequence[tuple[int, float]], first: int = ANGLE,
                    scale: Sequence[float] | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The arrays numba's loops read joints' values by (``_joint_rows``): each joint's
        row of ``state`` (``first`` plus its group), its sign and its scale (1.0 where not
        given: a multiply that changes no bit); made once per joints."""
        key = (tuple(joints), first, None if scale is None else tuple(scale))
        table = self._tables.get(key)
        if table is None:
            table = self._tables[key] = (
                np.array([first + g for g, _ in joints], dtype=np.int64),
                np.array([sign for _, sign in joints], dtype=np.float64),
                np.ones(len(joints)) if scale is None else np.array(scale, dtype=float))
        return table

    @property
    def torque(self) -> np.ndarray:
        """(G, N): each wheel group's motor drive torque (N m), a view of ``drive``."""
        return self.drive[TORQUE:damping_row(self.ng)]

    @property
    def damping(self) -> np.ndarray:
        """(G, N): each wheel group's back-EMF damping (N m s/rad), a view of ``drive``."""
        return self.drive[damping_row(self.ng):]

    def heading(self) -> tuple[np.ndarray, np.ndarray]:
        """Every car's cos and sin of its yaw, (N,) views of ``state``."""
        return self.state[COS], self.state[SIN]

    def pose(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every car's base link x, y and yaw, with ``PlanarBody.link_pose`` and
        ``pose_from``'s arithmetic (the yaw through the quaternion, by ``math.atan2``; numba's
        loop over the cars where installed, ``_poses``)."""
        x, y, c, s = self.state[X], self.state[Y], self.state[COS], self.state[SIN]
        cx, cy = self.com_x, self.com_y
        if dynamics.COMPILED and _poses is not None:  # read at each call: a test switches it
            px, py, yaw = np.empty(self.n), np.empty(self.n), np.empty(self.n)
            _poses(x, y, c, s, cx, cy, px, py, yaw)
            return px, py, yaw
        px = x - (c * cx - s * cy)
        py = y - (s * cx + c * cy)
        qz, qw = yaw_quaternion_arrays(c, s)
        yaw = list(map(math.atan2, (2.0 * (qw * qz + 0.0 * 0.0)).tolist(),
                       (1.0 - 2.0 * (0.0 * 0.0 + qz * qz)).tolist()))
        return px, py, np.array(yaw)

    def speed(self) -> np.ndarray:
        """Every car's planar speed of the centre of mass (m/s)."""
        return np.hypot(self.state[VX], self.state[VY])


def _columns(values: np.ndarray, n: int) -> np.ndarray:
    """``values`` repeated for ``n`` cars along a new last axis. Its rows are laid out a little
    longer than ``n`` (this is a view of the first ``n`` columns): rows a power of two bytes
    apart fall into the same sets of the CPU's cache, and the compiled loop that gathers a
    car's numbers from 60 rows would evict its own lines (measured: its physics 20 % slower at
    4,096 cars; ``controller.columns.block``)."""
    out = np.empty((*values.shape, n + 8))[..., :n]
    out[...] = values[..., None]
    return out


def yaw_quaternion_arrays(c: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``simulator.yaw_quaternion``'s z and w for arrays of cos and sin (same arithmetic)."""
    # each branch's root is only taken where it is real; the other side is clipped at 0 so
    # that np.where's unused branch cannot warn about a NaN (|c| may exceed 1 by a rounding)
    half_c = np.sqrt(np.maximum((1.0 + c) / 2.0, 0.0))
    qz_a, qw_a = s / (2.0 * np.where(half_c > 0, half_c, 1.0)), half_c
    half_s = np.copysign(np.sqrt(np.maximum((1.0 - c) / 2.0, 0.0)), np.where(s != 0.0, s, 1.0))
    qz_b = half_s
    qw_b = s / (2.0 * np.where(half_s != 0, half_s, 1.0))
    front = c > -0.5
    return np.where(front, qz_a, qz_b), np.where(front, qw_a, qw_b)


_gather = _poses = None
if dynamics.COMPILED:
    import numba

    @numba.njit(cache=True, nogil=True)
    def _gather(state: np.ndarray, rows: np.ndarray, signs: np.ndarray, scale: np.ndarray,
                out: np.ndarray) -> None:
        """``out[i, j] = (signs[j] * state[rows[j], i]) * scale[j]``: joints' values, (N, J)."""
        for i in range(out.shape[0]):
            for j in range(rows.shape[0]):
                out[i, j] = (signs[j] * state[rows[j], i]) * scale[j]

    # ``PlanarBatch.pose`` as numba's loop over the cars: ``PlanarBody.link_pose``'s x and y,
    # ``yaw_quaternion`` itself compiled, and ``pose_from``'s yaw with the C library's
    # ``atan2``, which ``math.atan2`` calls too. Not where numba uses Intel's SVML: its vector
    # ``atan2`` may round otherwise (then numpy and ``math.atan2``, as without numba)
    if not numba.config.USING_SVML:
        _yaw_quaternion = numba.njit(cache=True, nogil=True)(yaw_quaternion)

        @numba.njit(cache=True, nogil=True)
        def _poses(x: np.ndarray, y: np.ndarray, c: np.ndarray, s: np.ndarray,
                   cx: np.ndarray, cy: np.ndarray, px: np.ndarray, py: np.ndarray,
                   yaw: np.ndarray) -> None:
            """Each car's base link x, y and yaw into ``px``, ``py``, ``yaw``."""
            for i in range(x.shape[0]):
                ci, si = c[i], s[i]
                px[i] = x[i] - (ci * cx[i] - si * cy[i])
                py[i] = y[i] - (si * cx[i] + ci * cy[i])
                qx, qy, qz, qw = _yaw_quaternion(ci, si)
                yaw[i] = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
