"""The tasks of the batched vector env, as parts it is given (not subclasses per engine).

``SmartCarBatchVectorEnv`` steps the cars (clocks, events, boards, physics through the
``CarBatch`` protocol); what an id adds on top is a tuple of parts, ``TASKS[env_id]``, each a
``TaskPart`` with hooks the env calls in order at the same points the single env's code runs:

- ``Reach``: reaching a goal, SmartCar-v0's ``GoalReachingTask`` on arrays (every id's
  first part): goals, reward, success and failure, the observation's columns and ``info``;
- ``Navigation``: SmartCarNav-v0's obstacles (each car's episode built by the kept single
  env, the builder), its laser (an event source on each car's clock), clearance, collision
  and proximity terms, scan sectors in the observation;
- ``GoalConditioned``: SmartCarGoal-v0's ``Dict`` observation, goal-conditioned reward and
  ends, and ``compute_reward`` for HER.

Every hook is the single env's arithmetic on arrays, in its order, so every car is its single
env bit for bit. A part's ``exports`` are read through the env (``envs.unwrapped.latest_ranges``,
``envs.unwrapped.compute_reward``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from smartcar_gym.envs.goal_env import GoalRewards, SmartCarGoalEnv
from smartcar_gym.envs.nav_env import SmartCarNavEnv
from smartcar_gym.envs.sensors.laser import SimulatedLaser
from smartcar_gym.envs.sensors.scan import SCAN_KEY, scan_sectors
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.tasks.obstacles import Obstacle, read_layout
from smartcar_gym.envs.tasks.reach import FLIP_UP_Z
from smartcar_gym.envs.vector.exact import planar_norms, wrap_angles

if TYPE_CHECKING:
    from smartcar_gym.envs.vector.base import CarsVectorEnv

TWO_PI = 2 * math.pi
Score = tuple[np.ndarray, np.ndarray, np.ndarray]  # reward, success, failure per car


class TaskPart:
    """One task's share of a batched env; every hook does nothing unless the part needs it.

    ``env`` is the ``SmartCarBatchVectorEnv`` the part was given to; ``single`` the settled
    single env it was made from (its task, observation and sensors' settings).
    """

    #: attributes of the part read through the env
    exports: tuple[str, ...] = ()
    #: the ``reset`` options the part takes (the env checks ``goal`` itself)
    option_keys: tuple[str, ...] = ()
    #: whether the part is an event source on each car's clock (``next_due``, ``fire``)
    senses = False
    #: whether the single env stays open after the batch is made (it builds episodes)
    keeps_single = False
    #: memory the part holds per car (bytes), beyond the engine's cars
    bytes_per_car = 0

    @staticmethod
    def limits(kwargs: dict[str, Any]) -> str | None:
        """What of the single env's kwargs the part cannot run batched (None: nothing)."""
        return None

    def attach(self, env: Any, single: SmartCarEnv) -> None:
        """The part's per-car arrays, once the env has its cars."""

    def check_options(self, env: Any, taken: dict[str, Any]) -> None:
        """Check the part's ``reset`` options (``taken``: those of ``option_keys`` given)."""

    def take_options(self, taken: dict[str, Any]) -> None:
        """Keep the checked options for this reset (after the env checked ``goal``)."""

    def new_worlds(self, env: Any, idx: np.ndarray, goals: np.ndarray | None) -> None:
        """Each listed car's goal (``goals``, or drawn) and its world at t = 0 (the last part
        that has this hook starts the cars)."""
        raise NotImplementedError

    def build_options(self, i: int, options: dict[str, Any]) -> None:
        """Add the part's options to car ``i``'s reset of the builder (``Navigation``)."""

    def from_builder(self, env: Any, i: int, builder: SmartCarEnv) -> None:
        """Take car ``i``'s share of the episode the builder has just started."""

    def after_reset(self, env: Any, mask: np.ndarray, idx: np.ndarray) -> None:
        """After the masked cars (``idx``) were reset, their controllers started and poses
        read."""

    def score(self, env: Any, a: np.ndarray, previous: Score | None) -> Score:
        """Reward, success and failure of every car after a step, from the previous part's."""
        assert previous is not None
        return previous

    def cut_short(self, env: Any, truncated: np.ndarray) -> np.ndarray:
        """Which cars the task truncates this step (before the time limit)."""
        return truncated

    def columns(self, env: Any, columns: dict[str, Any]) -> None:
        """Add the part's observation entries' columns over cars (by the entry's key)."""

    def observe(self, env: Any, columns: dict[str, Any]) -> Any:
        """Every car's observation from ``columns`` (the last part that has this hook)."""
        raise NotImplementedError

    def car_obs(self, obs: Any, i: int) -> Any:
        """Car ``i``'s observation copied out of ``observe``'s (``final_obs``)."""
        raise NotImplementedError

    def info_values(self, env: Any, values: dict[str, np.ndarray],
                    success: np.ndarray) -> None:
        """Add (or change) the part's ``info`` values over cars."""

    def next_due(self, env: Any) -> np.ndarray:
        """Each car's next event of the part (ns on its clock; ``senses``)."""
        raise NotImplementedError

    def fire(self, env: Any, mask: np.ndarray) -> None:
        """The masked cars' events of the part due at their clocks (``senses``)."""

    def close(self) -> None:
        """Release what the part holds (the builder)."""


# -- reaching a goal -----------------------------------------------------------------------------
def reach_score(env: CarsVectorEnv, px: np.ndarray, py: np.ndarray, a: np.ndarray,
                flipped: np.ndarray | bool = False) -> Score:
    """Reward, success and failure of every car from its true position: the arithmetic of
    ``GoalReachingTask.evaluate``, in its order, on arrays (it keeps each car's distance and
    action for the next step)."""
    task = env.task
    dx, dy = px - env.goal[:, 0], py - env.goal[:, 1]
    distance = np.sqrt(dx * dx + dy * dy)
    success = distance < task.goal_tolerance_m
    half = task.arena_half_size_m
    failure = flipped | (np.abs(px) > half) | (np.abs(py) > half)
    reward = (task.progress_weight * (env._distance - distance) - task.time_cost
              - task.action_cost * (a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1])
              + task.success_bonus * success.astype(np.float64)
              - task.failure_penalty * failure.astype(np.float64))
    env._distance = distance
    env._prev_action = a.astype(np.float32)
    return reward, success, failure


def reach_columns(env: Any) -> dict[str, Any]:
    """SmartCar-v0's observation entries as columns over cars: odometry, wheels, goal, last
    action (``env._wheels``/``_wheel_speed`` read, ``_wheel_group`` mapping wheels to them)."""
    b = env.base
    c, s = np.cos(b.theta), np.sin(b.theta)
    gx, gy = env.goal[:, 0] - b.x, env.goal[:, 1] - b.y
    wrapped = (env._wheels + math.pi) % TWO_PI - math.pi
    group = env._wheel_group
    return {
        "odom_position": (b.x, b.y),
        "odom_heading": (c, s),
        "odom_linear": (b.odom_v,),
        "odom_angular": (b.odom_w,),
        "wheel_positions": [wrapped[:, k] for k in group],
        "wheel_velocities": [env._wheel_speed[:, k] for k in group],
        "goal_base": (c * gx + s * gy, -s * gx + c * gy),
        "goal_distance": (np.hypot(gx, gy),),
        "previous_action": (env._prev_action[:, 0], env._prev_action[:, 1]),
        "goal_odom": (env.goal[:, 0], env.goal[:, 1]),
    }


class Reach(TaskPart):
    """Reaching a goal: SmartCar-v0's task (``GoalReachingTask``), the first part of every id."""

    def new_worlds(self, env: Any, idx: np.ndarray, goals: np.ndarray | None) -> None:
        """A goal per car (given or drawn from its generator), its world the settled one."""
        env._draw_goals(idx, goals)
        env.cars.reset(idx)

    def after_reset(self, env: Any, mask: np.ndarray, idx: np.ndarray) -> None:
        d = env._pose[idx, :2] - env.goal[idx]
        env._distance[idx] = np.sqrt(np.add.reduce(d * d, axis=-1))

    def score(self, env: Any, a: np.ndarray, previous: Score | None) -> Score:
        return reach_score(env, env._pose[:, 0], env._pose[:, 1], a, env._up_z < FLIP_UP_Z)

    def columns(self, env: Any, columns: dict[str, Any]) -> None:
        columns.update(reach_columns(env))

    def observe(self, env: Any, columns: dict[str, Any]) -> np.ndarray:
        return env._build(env.observation, columns)

    def car_obs(self, obs: np.ndarray, i: int) -> np.ndarray:
        return obs[i].copy()

    def info_values(self, env: Any, values: dict[str, np.ndarray],
                    success: np.ndarray) -> None:
        """SmartCarEnv's ``_info``: success, distance, true and odometry poses, their gap."""
        b, pose = env.base, env._pose
        values.update({
            "is_success": success.copy(),
            "distance": env._distance.copy(),
            "pose": pose.copy(),
            "odom_pose": np.stack([b.x, b.y, wrap_angles(b.theta)], axis=1),
            "odom_error": planar_norms(b.x - pose[:, 0], b.y - pose[:, 1]),
        })


# -- SmartCarNav-v0 ------------------------------------------------------------------------------
class Navigation(TaskPart):
    """SmartCarNav-v0's obstacles, laser and clearance.

    Each episode's obstacles differ, so a car's reset builds its world as its single env
    does: the kept single env (``builder``) is reset with the car's own generator (goal,
    obstacles, the laser's noise seed, the first scan at t = 0; with ``randomize`` the
    robot's draw) and the car's slot becomes that world (``CarBatch.load``) with that robot
    (``take_robot``). From there on nothing goes through a single env: the
    laser is an event source on each car's clock whose beams the engine casts
    (``CarBatch.cast``), the ranges (REP 117, noise from each car's generator) and scan
    sectors are ``SimulatedLaser.ranges`` and ``scan_sectors`` on arrays, and the clearance
    (``CarBatch.clearances``) gives ``NavigationTask``'s collision and proximity terms.
    ``reset(options={"obstacles": layout})`` gives every reset car that layout.
    """

    exports = ("builder", "laser", "scan_sectors", "latest_ranges", "next_scan", "clearance",
               "collision", "obstacles")
    option_keys = ("obstacles",)
    senses = True
    keeps_single = True
    bytes_per_car = 48 * 1024  # its obstacles and latest scan
    #: the single env that builds every car's episode at its resets (once attached)
    builder: SmartCarNavEnv | None = None

    @staticmethod
    def limits(kwargs: dict[str, Any]) -> str | None:
        if kwargs.get("render_mode") is not None:
            return ("render_mode: the batch's top-down tiles draw no obstacles or scans (the "
                    "single env's picture does)")
        return None

    def attach(self, env: Any, single: SmartCarNavEnv) -> None:
        n = env.num_envs
        self.builder = single
        self.laser = SimulatedLaser(single.laser_config, single.mount)  # its arithmetic only
        self.scan_sectors = single.scan_sectors
        #: every car's latest scan, (N, beams) float32
        self.latest_ranges = np.zeros((n, single.laser_config.beams), dtype=np.float32)
        #: the observation's scan sectors of ``latest_ranges``, remade for the cars scanned
        #: since (``_stale``): a car that has not scanned (parked) keeps its row
        self._sectors = np.zeros((n, single.scan_sectors))
        self._stale = np.ones(n, dtype=bool)
        self._laser_rngs: list[np.random.Generator | None] = [None] * n
        self._next_scan = np.zeros(n, dtype=np.int64)
        self.clearance = np.zeros(n)
        self.collision = np.zeros(n, dtype=bool)
        #: every car's obstacle layout
        self.obstacles: list[tuple[Obstacle, ...]] = [()] * n
        self._layout: Any = None

    @property
    def next_scan(self) -> np.ndarray:
        """Each car's next scan (ns on its clock): it changes with every scan (a stamp)."""
        return self._next_scan

    def check_options(self, env: Any, taken: dict[str, Any]) -> None:
        if "obstacles" in taken and self.builder is not None:
            self.builder._check_layout(read_layout(taken["obstacles"], "options['obstacles']"),
                                       "options['obstacles']")

    def take_options(self, taken: dict[str, Any]) -> None:
        self._layout = taken.get("obstacles")

    def new_worlds(self, env: Any, idx: np.ndarray, goals: np.ndarray | None) -> None:
        """Each listed car's episode as its single env starts it (goal, obstacles, first
        scan), built by the builder with the car's generator and loaded into its slot."""
        b = self.builder
        assert b is not None
        layout, self._layout = self._layout, None
        for i in idx.tolist():
            options: dict[str, Any] = {}
            if goals is not None:
                options["goal"] = goals[i]
            if layout is not None:
                options["obstacles"] = layout
            for part in env.parts:
                part.build_options(i, options)
            b.np_random = env._rng(i)
            _, info = b.reset(options=options or None)
            env.goal[i] = b.goal
            self.latest_ranges[i] = b.laser.latest.ranges
            self._stale[i] = True
            self._laser_rngs[i] = b.laser.rng
            self._next_scan[i] = self.laser.period_ns
            self.clearance[i], self.collision[i] = info["clearance"], False
            self.obstacles[i] = b.obstacles
            env.cars.load(i, b)
            env.take_robot(i, b)
            for part in env.parts:
                part.from_builder(env, i, b)

    def score(self, env: Any, a: np.ndarray, previous: Score | None) -> Score:
        """``SmartCarNavEnv.step``'s collision and proximity terms from each car's
        clearance, on top of reaching the goal."""
        assert previous is not None
        reward, success, failure = previous
        task = env.task
        running = np.flatnonzero(~env._parked)  # a parked car stands: its clearance stays
        self.clearance[running] = env.cars.clearances(env._pose, task.proximity_m, running)
        self.collision = self.clearance <= 0.0
        reward = (reward + task.collision_reward(self.collision)
                  + task.proximity_reward(self.clearance))
        return reward, success, failure | self.collision

    def columns(self, env: Any, columns: dict[str, Any]) -> None:
        stale = np.flatnonzero(self._stale)
        if len(stale):
            self._sectors[stale] = scan_sectors(self.latest_ranges[stale],
                                                self.laser.config.range_max, self.scan_sectors)
            self._stale[:] = False
        columns[SCAN_KEY] = tuple(self._sectors.T.copy())

    def info_values(self, env: Any, values: dict[str, np.ndarray],
                    success: np.ndarray) -> None:
        values["collision"] = self.collision.copy()
        values["clearance"] = self.clearance.copy()

    def next_due(self, env: Any) -> np.ndarray:
        return self._next_scan

    def fire(self, env: Any, mask: np.ndarray) -> None:
        """The masked cars' scans due at their clocks (the laser's ``on_event``)."""
        due = mask & (self._next_scan <= env._now)
        if due.any():
            self._scan(env, np.flatnonzero(due))
            self._next_scan[due] += self.laser.period_ns

    def _scan(self, env: Any, idx: np.ndarray) -> None:
        """``SimulatedLaser.scan`` for the listed cars: the engine casts, the ranges here."""
        laser = self.laser
        hit, fraction = env.cars.cast(idx, laser)
        self._stale[idx] = True
        if laser.config.noise_std_m > 0:
            for k, i in enumerate(idx.tolist()):
                self.latest_ranges[i] = laser.ranges(fraction[k], hit[k], self._laser_rngs[i])
        else:
            self.latest_ranges[idx] = laser.ranges(fraction, hit, None)

    def close(self) -> None:
        if self.builder is not None:
            self.builder.close()


# -- SmartCarGoal-v0 -----------------------------------------------------------------------------
class GoalConditioned(GoalRewards, TaskPart):
    """SmartCarGoal-v0: the ``Dict`` observation (``observation``, ``achieved_goal``,
    ``desired_goal``, each ``(N, ...)``), the reward ``compute_reward(achieved_goal,
    desired_goal)``, terminated on reaching the goal by odometry, truncated when the odometry
    leaves the arena or the car flips, ``info["flipped"]``; reaching the goal's reward and ends
    are computed (as the single env's) and not used. ``compute_reward``,
    ``compute_terminated`` and ``compute_truncated`` are the single env's (goals
    ``(..., 2)``)."""

    exports = ("goal_task", "compute_reward", "compute_terminated", "compute_truncated")

    def attach(self, env: Any, single: SmartCarGoalEnv) -> None:
        n = env.num_envs
        self.goal_task = single.goal_task
        self._flipped = np.zeros(n, dtype=bool)
        self._truncate = np.zeros(n, dtype=bool)
        self._just_reset = np.zeros(n, dtype=bool)
        self._reset_success = np.zeros(n, dtype=bool)

    def after_reset(self, env: Any, mask: np.ndarray, idx: np.ndarray) -> None:
        """SmartCarGoalEnv.reset's ``is_success`` and ``flipped``."""
        achieved, desired = self._goals(env)
        self._reset_success[mask] = self.goal_task.is_success(achieved, desired)[mask]
        self._flipped[mask] = env.task.is_flipped(env._up_z[mask])
        self._just_reset[mask] = True

    def score(self, env: Any, a: np.ndarray, previous: Score | None) -> Score:
        """The goal-conditioned reward and ends from the observed goals."""
        self._just_reset[:] = False
        achieved, desired = self._goals(env)
        self._flipped = env.task.is_flipped(env._up_z)
        success = self.goal_task.compute_terminated(achieved, desired, None)
        self._truncate = self.goal_task.compute_truncated(achieved, desired, None) | self._flipped
        reward = self.goal_task.compute_reward(achieved, desired, None)
        return reward, success, np.zeros(env.num_envs, dtype=bool)

    def cut_short(self, env: Any, truncated: np.ndarray) -> np.ndarray:
        return self._truncate.copy()

    def _goals(self, env: Any) -> tuple[np.ndarray, np.ndarray]:
        """Every car's observed achieved and desired goals ((N, 2) float32)."""
        columns, s = env._columns(), env.settings
        return env._build(s._achieved, columns), env._build(s._desired, columns)

    def columns(self, env: Any, columns: dict[str, Any]) -> None:
        columns["achieved_goal"] = (env.base.x, env.base.y)
        columns["desired_goal"] = (env.goal[:, 0], env.goal[:, 1])

    def observe(self, env: Any, columns: dict[str, Any]) -> dict[str, np.ndarray]:
        s = env.settings
        return {"observation": env._build(env.observation, columns),
                "achieved_goal": env._build(s._achieved, columns),
                "desired_goal": env._build(s._desired, columns)}

    def car_obs(self, obs: dict[str, np.ndarray], i: int) -> dict[str, np.ndarray]:
        return {key: value[i].copy() for key, value in obs.items()}

    def info_values(self, env: Any, values: dict[str, np.ndarray],
                    success: np.ndarray) -> None:
        # a car just reset reports its reset's is_success (the goal may start within reach)
        values["is_success"] = np.where(self._just_reset, self._reset_success, success)
        values["flipped"] = self._flipped.copy()


#: each batched id: the single env every car is, bit for bit, and the parts of its task
TASKS: dict[str, tuple[type[SmartCarEnv], tuple[type[TaskPart], ...]]] = {
    "SmartCar-v0": (SmartCarEnv, (Reach,)),
    "SmartCarNav-v0": (SmartCarNavEnv, (Reach, Navigation)),
    "SmartCarGoal-v0": (SmartCarGoalEnv, (Reach, GoalConditioned)),
}  # SmartCarBARN-v0's: envs.vector.barn_part adds them
