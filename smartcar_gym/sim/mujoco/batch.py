"""N copies of one car's MuJoCo world, each stepped by its own ``mj_step`` calls in C.

``CarBatch`` copies the compiled ``MjModel`` and the settled ``MjData`` of one
``MujocoSimulator`` N times: car i is exactly the single env's world (same model, same data,
same solver warm start), so its physics is bit for bit what ``N`` single envs compute. One
``step`` advances any subset of cars, each by its own number of substeps of its own length
(``mj_step(model, data, nstep)``: the substeps run in C), the cars split between worker threads
(MuJoCo releases Python's GIL inside ``mj_step``). What the emulated board changes between
events (the wheels' motor torque in ``qfrc_applied``, their back-EMF damping in
``dof_damping``) is written into each car's own model and data before it steps. A car whose
world MuJoCo finds unstable (and resets) is listed in ``unstable`` with its state then
(``mjlog``), for the vector env to report.

A car whose world changes per episode (SmartCarNav-v0's obstacles) gets a copy of the world its
single env builds (``load``). Its sensors query its own world in C the same way: ``scan`` (the
laser: one ``mj_multiRay`` per car) and ``distances`` (``mj_geomDistance`` over geom pairs).

Why not ``mujoco.rollout``: it restarts every rollout from a state vector, and MuJoCo's state
(``mjSTATE_INTEGRATION``) does not give the solver's warm start back, so chained rollouts drift
from the single env after the first interval. Why not one model holding N cars: the constraint
solver then solves all cars' contacts as one system (its iterations and tolerance are the
whole world's), so a car's bits depend on the others.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import mujoco
import numpy as np

from smartcar_gym.sim.mujoco import mjlog
from smartcar_gym.sim.mujoco.rays import hit_fraction, multi_ray, unit_rays
from smartcar_gym.sim.mujoco.simulator import MujocoSimulator

#: below this many cars to step, the threads cost more than they save
MIN_CARS_PER_THREAD = 4
#: rounding allowance (m) when bounding spheres rule a pair of geoms out of ``distances``
SPHERE_SLACK_M = 1e-6


class CarBatch:
    """``num_cars`` independent copies of ``sim``'s world as it is now (compiled, settled).

    Args:
        sim: a ``MujocoSimulator`` holding one car (spawned and settled): the template.
        num_cars: N.
        wheel_dofs: the wheels' dof addresses (``qfrc_applied``/``dof_damping`` columns).
        threads: worker threads for ``step`` (1: the calling thread only).

    ``qpos`` (N, nq) and ``qvel`` (N, nv) hold every car's state after its last step or reset;
    ``torque`` and ``damping`` (N, wheels) are what ``step`` writes before stepping a car.
    """

    def __init__(self, sim: MujocoSimulator, num_cars: int, wheel_dofs: list[int],
                 threads: int = 1) -> None:
        m, d = sim.model_compiled(), sim.data
        self.template_model, self.template_data = copy.copy(m), copy.copy(d)
        self.n = int(num_cars)
        self.dofs = np.asarray(wheel_dofs, dtype=np.intp)
        self.qpos = np.tile(d.qpos, (self.n, 1))
        self.qvel = np.tile(d.qvel, (self.n, 1))
        self.torque = np.tile(d.qfrc_applied[self.dofs], (self.n, 1))
        self.damping = np.tile(m.dof_damping[self.dofs], (self.n, 1))
        self.threads = max(1, int(threads))
        self._pool: ThreadPoolExecutor | None = None
        self.reopen()

    def reopen(self) -> None:
        """Every car a copy of the template's world (after ``close``: the worlds again)."""
        tm, td = self.template_model, self.template_data
        self.models = [copy.copy(tm) for _ in range(self.n)]
        self.datas = [copy.copy(td) for _ in range(self.n)]
        #: cars whose geom poses are older than their positions (stepped since ``_current``)
        self._stale = np.ones(self.n, dtype=bool)
        #: (car, what MuJoCo said) for each instability met while stepping, until taken
        self.unstable: list[tuple[int, mjlog.Instability]] = []

    def reset(self, cars: np.ndarray) -> None:
        """Put the listed cars back into the template's state (model values and data)."""
        tm, td = self.template_model, self.template_data
        for i in cars:
            m = self.models[i]
            mujoco.mj_copyData(self.datas[i], tm, td)
            self._stale[i] = True
            m.dof_damping[:] = tm.dof_damping
            m.opt.timestep = tm.opt.timestep
        self.qpos[cars] = td.qpos
        self.qvel[cars] = td.qvel
        self.torque[cars] = td.qfrc_applied[self.dofs]
        self.damping[cars] = tm.dof_damping[self.dofs]

    def load(self, car: int, sim: MujocoSimulator) -> None:
        """Make car ``car`` a copy of ``sim``'s world as it is now (a world built for this car's
        episode: the Nav obstacles); it must have the template's joints."""
        m, d = sim.model_compiled(), sim.data
        if (m.nq, m.nv) != (self.template_model.nq, self.template_model.nv):
            raise ValueError(f"car {car}'s world has {m.nq} positions and {m.nv} dofs, the "
                             f"batch {self.template_model.nq} and {self.template_model.nv}")
        self.models[car], self.datas[car] = copy.copy(m), copy.copy(d)
        self._stale[car] = True
        self.qpos[car], self.qvel[car] = d.qpos, d.qvel
        self.torque[car] = d.qfrc_applied[self.dofs]
        self.damping[car] = m.dof_damping[self.dofs]

    def step(self, cars: np.ndarray, nstep: np.ndarray, timestep: np.ndarray) -> None:
        """Step car ``cars[k]`` by ``nstep[k]`` substeps of ``timestep[k]`` s (in C)."""
        self._map(self._run, cars, (nstep.tolist(), timestep.tolist()))

    def scan(self, cars: np.ndarray, starts: np.ndarray,
             ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Car ``cars[k]``'s rays from ``starts[k]`` (one point, repeated: (B, 3)) to
        ``ends[k]`` ((B, 3)) in its own world, one ``mj_multiRay`` per car in C, as
        ``MujocoSimulator.ray_batch`` casts them (``rays``' arithmetic, on all cars at once):
        which rays hit (K, B) and how far along (1 where none)."""
        _, length, unit = unit_rays(starts, ends)
        geom = np.full(length.shape, -1, dtype=np.int32)
        dist = np.full(length.shape, -1.0)
        self._map(self._multi_ray, cars, (list(starts[:, 0]), list(unit),
                                          length.max(axis=1).tolist(), list(geom), list(dist)))
        return hit_fraction(geom, dist, length)

    def distances(self, cars: np.ndarray, pairs: list[np.ndarray],
                  max_distance_m: float) -> np.ndarray:
        """Per listed car, the smallest ``mj_geomDistance`` between the geom pairs
        ``pairs[i]`` ((P, 2) ids) of car i's world, at most ``max_distance_m`` (<= 0:
        touching): ``MujocoBody.distance_to`` over a car's pairs."""
        out = np.full(len(cars), float(max_distance_m))
        self._map(self._nearest, cars, (list(range(len(cars))), [pairs[i] for i in cars.tolist()]),
                  (out, max_distance_m))
        return out

    def _map(self, run: Callable[..., None], cars: np.ndarray, per_car: tuple[list, ...],
             shared: tuple = ()) -> None:
        """``run(cars, *per_car, *shared)`` with the cars (and each ``per_car`` list, one entry
        per car) split between the worker threads."""
        count = len(cars)
        if count == 0:
            return
        chunks = min(self.threads, count // MIN_CARS_PER_THREAD) or 1
        if chunks == 1:
            run(cars.tolist(), *per_car, *shared)
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="smartcar-mj")
        jobs = [self._pool.submit(run, cars[k::chunks].tolist(),
                                  *(a[k::chunks] for a in per_car), *shared)
                for k in range(chunks)]
        for job in jobs:
            job.result()

    def _run(self, cars: list[int], nstep: list[int], timestep: list[float]) -> None:
        models, datas, dofs = self.models, self.datas, self.dofs
        torque, damping, qpos, qvel = self.torque, self.damping, self.qpos, self.qvel
        for i, n, dt in zip(cars, nstep, timestep, strict=True):
            m, d = models[i], datas[i]
            m.opt.timestep = dt
            d.qfrc_applied[dofs] = torque[i]
            m.dof_damping[dofs] = damping[i]
            unstable = mjlog.step(m, d, n)
            if unstable:
                self.unstable += [(i, event) for event in unstable]
            qpos[i] = d.qpos
            qvel[i] = d.qvel
            self._stale[i] = True

    def _current(self, car: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
        """Car ``car``'s model and data with every geom's pose computed from its positions
        (after ``mj_step`` they are those before the step), as ``MujocoSimulator.kinematics``:
        once per step, however many sensors ask (the laser and the clearance at one instant)."""
        m, d = self.models[car], self.datas[car]
        if self._stale[car]:
            mujoco.mj_kinematics(m, d)
            self._stale[car] = False
        return m, d

    def _multi_ray(self, cars: list[int], starts: list, units: list, cutoffs: list[float],
                   geoms: list, dists: list) -> None:
        for i, start, unit, cutoff, geom, dist in zip(cars, starts, units, cutoffs, geoms, dists,
                                                      strict=True):
            multi_ray(*self._current(i), start, unit, cutoff, geom, dist)

    def _nearest(self, cars: list[int], slots: list[int], pairs: list[np.ndarray],
                 out: np.ndarray, max_distance_m: float) -> None:
        for i, k, car_pairs in zip(cars, slots, pairs, strict=True):
            m, d = self._current(i)
            nearest = max_distance_m
            # a pair whose bounding spheres are further apart than max_distance_m gives
            # exactly max_distance_m: only the others are measured (the same minimum)
            g1, g2 = car_pairs[:, 0], car_pairs[:, 1]
            apart = d.geom_xpos[g1] - d.geom_xpos[g2]
            gap = (np.sqrt(np.add.reduce(apart * apart, axis=1)) - m.geom_rbound[g1]
                   - m.geom_rbound[g2])
            for g1, g2 in car_pairs[gap <= max_distance_m + SPHERE_SLACK_M].tolist():
                nearest = min(nearest, mujoco.mj_geomDistance(m, d, g1, g2, max_distance_m,
                                                              None))
            out[k] = nearest

    def bytes_per_car(self) -> int:
        """The memory one car's model and data hold (bytes)."""
        m, d = self.template_model, self.template_data
        return int(m.nbuffer + d.nbuffer) if hasattr(d, "nbuffer") else int(
            m.nbuffer + d.narena * 8)

    def __getstate__(self) -> dict:
        """The template and the arrays, without the cars' worlds or the worker threads (a
        copy is closed until ``reopen``)."""
        state = self.__dict__.copy()
        state.update(models=[], datas=[], _pool=None, unstable=[])
        return state

    def close(self) -> None:
        """Stop the worker threads and drop the cars' copies (the template stays, for
        ``reopen``)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
        self.models, self.datas = [], []
