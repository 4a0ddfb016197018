"""BARN runs on one batched env (``SmartCarBatchVectorEnv``): its cars take the jobs in turn.

``run_barn_vector`` is ``runner.run_barn`` for a batch: the same jobs to the same cars in the
same order (a car whose run ends takes the next job by a partial reset with its seed and
world), ``driver.act`` for the cars with a run (``driver.act_chunk`` at a time, None: all at
once), a car left without a run parked where it stands (not reset: no world is built for it).
``BatchCar`` shows the driver car i as it sees a single env (odometry, scan, global path, the
car's settings). Per car the batch is its single env bit for bit, so the records are the
single envs' row's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.bench.runner import Job, RunRecord, record_of

#: the ``info`` keys a run's record reads
RECORD_KEYS = ("outcome", "run_time_s", "score", "score_025", "optimal_time_s", "distance")


class BatchCar:
    """Car ``i`` of a batched BARN env, as a driver reads a single env (``env.unwrapped``)."""

    def __init__(self, env: Any, i: int) -> None:
        self._env, self._i = env, i
        s = env.settings
        self.robot_model, self.wheel_contact = s.robot_model, s.wheel_contact
        self.max_linear, self.max_angular = s.max_linear, s.max_angular
        self.protocol = env.protocol

    @property
    def robot(self) -> SimpleNamespace:
        """The odometry (x, y, theta, v, omega) and the controller's period."""
        b, i = self._env.base, self._i
        odometry = SimpleNamespace(x=float(b.x[i]), y=float(b.y[i]), theta=float(b.theta[i]),
                                   v=float(b.odom_v[i]), omega=float(b.odom_w[i]))
        return SimpleNamespace(odometry=odometry, update_period_ns=self._env.period_ns)

    @property
    def laser(self) -> SimpleNamespace:
        """The laser's settings and the car's latest scan (``laser.latest.ranges``)."""
        laser = self._env.laser
        return SimpleNamespace(config=laser.config, mount=laser.mount,
                               latest=SimpleNamespace(ranges=self._env.latest_ranges[self._i]))

    @property
    def global_path(self) -> np.ndarray:
        return self._env.global_paths[self._i]

    @property
    def localize(self) -> bool:
        """Whether the car follows its path from its pose on the map (``localize=True``)."""
        return self._env.localize

    @property
    def map_pose(self) -> tuple[float, float, float]:
        """Base_link on the map (x, y, yaw), as the car's last observation saw it."""
        return tuple(float(v) for v in self._env.map_poses[self._i])


def run_barn_vector(envs: gym.vector.VectorEnv, driver: Any, jobs: Sequence[Job],
                    keep: Callable[[Job], bool] = lambda job: False,
                    report: Callable[[RunRecord], None] | None = None) -> list[RunRecord]:
    """Every job's record, in the order of ``jobs`` (as ``run_barn``'s)."""
    u = envs.unwrapped
    n = u.num_envs
    cars = [BatchCar(u, i) for i in range(n)]
    queue = list(enumerate(jobs))
    records: list[RunRecord | None] = [None] * len(jobs)
    slots: list[tuple[int, Job, list] | None] = [None] * n
    worlds = [jobs[0].world if jobs else 0] * n

    def start(idx: list[int], first: bool) -> None:
        seeds: list[int | None] = [None] * n
        started = []
        for i in idx:
            slots[i] = queue.pop(0) + ([],) if queue else None
            if slots[i] is not None:
                seeds[i], worlds[i] = slots[i][1].seed, slots[i][1].world
                started.append(i)
        fresh, idle = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        fresh[started] = True
        idle[idx] = True
        idle &= ~fresh
        if first or started:  # the first reset resets every car; later, only the new runs'
            options: dict[str, Any] = {"world": list(worlds)}
            if not first:
                options["reset_mask"] = fresh
            obs[:], info = envs.reset(seed=seeds, options=options)
            for i in started:
                slots[i][2].append(info["pose"][i, :2].copy())
        if idle.any():
            u.park(idle)  # a car left without a run stands where it is: no new world
        if started:
            driver.reset(cars, started)

    obs = np.zeros(envs.observation_space.shape, dtype=envs.observation_space.dtype)
    start(list(range(n)), True)
    while any(slot is not None for slot in slots):
        active = [i for i, slot in enumerate(slots) if slot is not None]
        actions = np.zeros((n, 2), dtype=np.float32)
        size = getattr(driver, "act_chunk", None) or max(len(active), 1)
        for j in range(0, len(active), size):
            chunk = active[j:j + size]
            actions[chunk] = driver.act([cars[i] for i in chunk], obs[chunk], chunk)
        obs[:], _, terminated, truncated, info = envs.step(actions)
        ended = []
        for i in active:
            index, job, way = slots[i]
            way.append(info["pose"][i, :2].copy())
            if terminated[i] or truncated[i]:
                records[index] = record_of(job, {k: info[k][i] for k in RECORD_KEYS}, way,
                                           keep(job))
                if report is not None:
                    report(records[index])
                ended.append(i)
        if ended:
            start(ended, False)
    return records
