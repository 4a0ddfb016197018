"""SmartCarBARN-v0's part of the batched env: the BARN protocol on top of ``Navigation``.

``TASKS["SmartCarBARN-v0"]`` is ``(Reach, Navigation, Barn)``: ``Navigation`` builds each car's
episode through the kept single env (here a ``SmartCarBARNEnv``: the world's cylinders, the
goal the protocol sets, the global path) and runs its laser and clearance; ``Barn`` picks the
world (``reset(options={"world": i})``, one index or one per car), follows each car's global
path (``PathTrackers``, the waypoint row of the observation), times its run (``RunClock``),
ends it (collision, success, failure, the scaled timeout) and reports the outcome and the
challenge's scores in ``info``: the single env's arithmetic, per car, in its order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smartcar_gym.envs.barn_env import SmartCarBARNEnv
from smartcar_gym.envs.tasks.barn import (
    COLLISION,
    FAILURE,
    SUCCESS,
    TIMEOUT,
    RunClock,
    barn_score,
)
from smartcar_gym.envs.tasks.path_trackers import PathTrackers
from smartcar_gym.envs.vector.parts import TASKS, Navigation, Reach, Score, TaskPart
from smartcar_gym.navigation.localization import IDENTITY, Localizer, Pose, beam_geometry
from smartcar_gym.parallel import run_chunks
from smartcar_gym.sim.clock import NS_PER_S

ENV_ID = "SmartCarBARN-v0"


class Barn(TaskPart):
    """The BARN worlds and protocol for every car (after ``Reach`` and ``Navigation``)."""

    exports = ("worlds", "protocol", "timeout_steps", "global_paths", "planned_paths",
               "waypoints", "localize", "corrections", "map_poses")
    #: ``goal`` is taken only to be refused: the protocol sets the goal
    option_keys = ("world", "goal")
    bytes_per_car = 16 * 1024  # its global path and tracker

    def attach(self, env: Any, single: SmartCarBARNEnv) -> None:
        n = env.num_envs
        self.builder = single
        self.worlds, self.protocol = single.worlds, single.protocol
        self.timeout_steps = single.timeout_steps
        self.lookahead_m = single.lookahead_m
        self.path_progress_weight = single.path_progress_weight
        #: each car's ground-truth distance to go along its path (``progress="path"``)
        self._to_go = np.zeros(n)
        self._reward_trackers = PathTrackers(n, 0.0)
        #: each car's world index, its OT and its global path (odom frame)
        self.world = np.zeros(n, dtype=np.int64)
        self.optimal = np.zeros(n)
        self.global_paths: list[np.ndarray] = [np.zeros((0, 2))] * n
        #: each car's next waypoint in its odometry base_link frame, (N, 2)
        self.waypoints = np.zeros((n, 2))
        self._trackers = PathTrackers(n, self.lookahead_m)
        self._clocks = [RunClock(np.zeros(2), self.protocol.moved_m) for _ in range(n)]
        self.outcome = np.full(n, None, dtype=object)
        #: each car's AT and scores (``info_values``): (3, N)
        self._timing = np.zeros((3, n))
        self._timeout = np.zeros(n, dtype=bool)
        self._chosen: list[int] | None = None
        #: ``localize``: each car's localization (on its builder's scan matcher), and its
        #: base_link on the map as the last observation saw it, (N, 3)
        self.localize = single.localize
        self._localizers: list[Localizer | None] = [None] * n
        self.map_poses = np.zeros((n, 3))
        if self.localize:
            self._beams = beam_geometry(single.laser_config.angles, single.laser.mount)

    @property
    def corrections(self) -> list[Pose]:
        """Each car's map -> odom correction (the identity without ``localize``)."""
        return [IDENTITY if loc is None else loc.correction for loc in self._localizers]

    @property
    def planned_paths(self) -> dict[int, np.ndarray]:
        """The global paths planned so far, by world (the builder's)."""
        return self.builder.planned_paths

    def check_options(self, env: Any, taken: dict[str, Any]) -> None:
        """``world``: one index for every reset car, or one per car; ``goal`` refused."""
        if "goal" in taken:
            raise ValueError(f"unknown reset option(s) ['goal']; {ENV_ID} takes 'world' (the "
                             "BARN protocol sets the goal)")
        if "world" in taken:
            self._chosen = self._read_worlds(env, taken["world"])

    def _read_worlds(self, env: Any, given: Any) -> list[int]:
        n = env.num_envs
        if isinstance(given, list | tuple | np.ndarray):
            chosen = list(given)
            if len(chosen) != n:
                raise ValueError(f"options['world'] must be a world index or {n} of them (one "
                                 f"per car), got {len(chosen)}")
        else:
            chosen = [given] * n
        for index in chosen:
            self.worlds.world(index)  # one line naming a world out of range
        return [int(index) for index in chosen]

    def take_options(self, taken: dict[str, Any]) -> None:
        if "world" not in taken:
            self._chosen = None

    def build_options(self, i: int, options: dict[str, Any]) -> None:
        if self._chosen is not None:
            options["world"] = self._chosen[i]

    def from_builder(self, env: Any, i: int, builder: SmartCarBARNEnv) -> None:
        """Car ``i``'s world, OT and global path, as its single env has them."""
        world = builder.world
        assert world is not None
        self.world[i] = world.index
        self.optimal[i] = self.protocol.optimal_time_s(world.path_length_m * self.protocol.scale)
        self.global_paths[i] = builder.global_path
        if builder.localizer is not None:  # the car's own, on the builder's map
            self._localizers[i] = Localizer(builder.localizer.matcher, *self._beams)

    def after_reset(self, env: Any, mask: np.ndarray, idx: np.ndarray) -> None:
        """A fresh run: its clock, no outcome, the path followed from its start."""
        self._chosen = None  # an autoreset draws its world
        for i in idx.tolist():
            self._clocks[i] = RunClock(np.zeros(2), self.protocol.moved_m)
            self._trackers.start(i, self.global_paths[i])
            self._reward_trackers.start(i, self.global_paths[i])
            self._to_go[i] = self._reward_trackers.to_go([i], np.zeros((1, 2)))[0]
        if len(idx):
            self._follow(env, idx)
        self.outcome[idx] = None
        self._timeout[idx] = False

    def _follow(self, env: Any, idx: np.ndarray) -> None:
        """Cars ``idx``' next waypoints from their odometry, or their pose on the map after
        matching a new scan (``SmartCarBARNEnv.readings``)."""
        b = env.base
        poses = np.column_stack([b.x[idx], b.y[idx], b.theta[idx]]).astype(float)
        if self.localize:
            odoms = [tuple(row) for row in poses.tolist()]
            scans = env.next_scan[idx].tolist()  # each car's scan's key (its next one's time)
            ranges = env.latest_ranges[idx]
            localizers = [self._localizers[i] for i in idx.tolist()]

            def match(a: int, z: int) -> None:  # the cars split over threads (the compiled
                for k in range(a, z):           # matcher frees the GIL)
                    localizers[k].match(odoms[k], scans[k], ranges[k])

            run_chunks(match, len(idx), env.threads)
            for k, localizer in enumerate(localizers):
                poses[k] = localizer.locate(odoms[k], scans[k], ranges[k])
        self.map_poses[idx] = poses
        self.waypoints[idx] = self._trackers.waypoints_in_base(idx, poses)

    def score(self, env: Any, a: np.ndarray, previous: Score | None) -> Score:
        """``SmartCarBARNEnv.step``: the run's clock and outcome, the timeout, the waypoint."""
        assert previous is not None
        reward, success, failure = previous
        collision = env.collision
        pose, now = env._pose, env._now
        if self.path_progress_weight:
            to_go = self._reward_trackers.to_go(np.arange(env.num_envs), pose[:, :2])
            reward = reward + self.path_progress_weight * (self._to_go - to_go)
            self._to_go = to_go
        running = np.flatnonzero(~env._parked)  # a parked car stands: as timed and followed
        for i in running.tolist():
            self._clocks[i].update(pose[i, :2], int(now[i]) / NS_PER_S)
        self._follow(env, running)
        ended = collision | success | failure
        self._timeout = ~ended & (env._steps >= self.timeout_steps)
        for outcome, mask in ((TIMEOUT, self._timeout), (FAILURE, failure),
                              (SUCCESS, success), (COLLISION, collision)):
            self.outcome[mask] = outcome  # the last one written wins, as the single env's elif
        return reward, success, failure

    def cut_short(self, env: Any, truncated: np.ndarray) -> np.ndarray:
        return truncated | self._timeout

    def columns(self, env: Any, columns: dict[str, Any]) -> None:
        columns["waypoint_base"] = (self.waypoints[:, 0], self.waypoints[:, 1])

    def info_values(self, env: Any, values: dict[str, np.ndarray],
                    success: np.ndarray) -> None:
        """``SmartCarBARNEnv._barn_info``: world, outcome, AT, OT and both scores (a parked
        car's as they were: its clock stands)."""
        now = env._now
        run_time, score, score_025 = self._timing
        for i in np.flatnonzero(~env._parked).tolist():
            run_time[i] = at = self._clocks[i].elapsed_s(int(now[i]) / NS_PER_S)
            won = self.outcome[i] == SUCCESS
            score[i] = barn_score(won, at, self.optimal[i])
            score_025[i] = barn_score(won, at, self.optimal[i], floor=4.0)
        values.update(world=self.world.copy(), outcome=self.outcome.copy(),
                      run_time_s=run_time.copy(), optimal_time_s=self.optimal.copy(),
                      score=score.copy(), score_025=score_025.copy())


TASKS[ENV_ID] = (SmartCarBARNEnv, (Reach, Navigation, Barn))
