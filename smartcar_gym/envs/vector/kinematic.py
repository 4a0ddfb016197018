"""SmartCarSim-v0 for N cars in numpy arrays: the kinematic mode has no physics to step."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from smartcar_gym.controller import KINEMATIC
from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.envs.observation import Observation
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.vector.common import (
    check_actions,
    check_autoreset_mode,
    check_max_episode_steps,
    check_num_envs,
    check_seeds,
    vector_info,
)
from smartcar_gym.envs.vector.exact import planar_norms, wrap_angles
from smartcar_gym.envs.vector.render import top_down_tiles
from smartcar_gym.sim.simulator import NS_PER_S, seconds_to_ns

#: measured: 4096 cars hold about 9 MiB of arrays; the margin covers the per-car generators
BYTES_PER_CAR = 16 * 1024
TWO_PI = 2 * math.pi


class _Settings(SmartCarEnv):
    """SmartCarEnv's argument checks, model, config, task and observation, without a world."""

    def _open(self) -> None:
        self.sim = None
        self._needs_reset = True


def supports(kwargs: dict[str, Any]) -> str | None:
    """Why ``SmartCarSimVectorEnv`` cannot run these SmartCarEnv kwargs (None: it can)."""
    if kwargs.get("randomize") is not None:
        return "randomize (domain randomisation) needs the per-episode pybullet world"
    if kwargs.get("render_mode") == "human":
        return "render_mode='human' is the pybullet GUI"
    if kwargs.get("stop_speed") is not None:
        return "stop_speed's arrival terms (SmartCarArrive-v0) are the single env's"
    return None


class SmartCarSimVectorEnv(gym.vector.VectorEnv):
    """## Description

    ``SmartCarSim-v0`` (the driver's ``sim: true``: the car follows the commanded twist) for
    ``num_envs`` cars at once, stepped in numpy arrays with no physics engine. Per car it is
    ``gym.make("SmartCarSim-v0")`` bit for bit: observations, rewards, terminations,
    truncations and infos equal N single envs seeded ``s, s+1, ...`` (tested), but for
    ``info["pose"]``'s yaw: here the body's exact heading, in the single env pybullet's float32
    quaternion's, within 1e-6 rad of it (docs/vector.md). The controller is
    ``controller.batched.BatchedArbotix``; the ground-truth position is rounded to float32 as the
    single env's pybullet body stores it.

    Made by ``gym.make_vec("SmartCarSim-v0", num_envs=N, vectorization_mode="vector_entry_point",
    **kwargs)`` with SmartCarEnv's kwargs (``max_substep_s``, ``physics_hz`` and
    ``wheel_contact`` have no effect: nothing is simulated), plus ``autoreset_mode``.

    ## Conventions (Gymnasium 1.x)

    - **Autoreset**: ``"NextStep"`` (Gymnasium's default, ``AutoresetMode.NEXT_STEP``): the step
      after a car's episode ends resets that car, ignores its action and returns its first
      observation with reward 0. ``autoreset_mode="SameStep"`` resets it in the step that ends
      the episode and puts its last observation and info in ``info["final_obs"]`` and
      ``info["final_info"]`` (what SB3 expects; ``agents.vec_env`` uses it).
      ``metadata["autoreset_mode"]`` says which.
    - **Episode limit**: ``max_episode_steps`` as ``gym.make`` reads it: None the id's
      registered limit (200 steps), -1 none, a positive integer that limit; others refused.
    - **Seeding**: ``reset(seed=s)`` seeds car i with ``s + i`` (a list seeds each car), as
      ``SyncVectorEnv``; ``reset()`` keeps each car's generator. A seed that is not an integer
      >= 0 (or None) is one error line. ``reset(options={"goal":
      (x, y)})`` gives every car that goal, an ``(N, 2)`` array one each.
    - **Partial resets**: ``reset(seed=[...], options={"reset_mask": mask})`` resets only the
      cars of the ``(N,)`` bool ``mask`` (as Gymnasium's own vector envs): the observation
      holds every car's, ``info`` the reset cars' (its ``_key`` masks are ``mask``), and a
      reset car is not autoreset at the next step.
    - **info**: per car ``is_success``, ``distance``, ``pose``, ``odom_pose``, ``odom_error``
      (as SmartCar-v0, with its arithmetic: ``vector.exact``), each with its ``_key`` mask.
    - **Actions**: ``(N, 2)`` real numbers in [-1, 1] (clipped); another shape, complex
      numbers or NaN is one error line.
    - **render()**: with ``render_mode="rgb_array"``, a top-down view of the first cars (up to
      16) tiled in one ``render_width x render_height`` image: arena, goal, car.
    - **close()**: ``reset()`` reopens a closed env, as it does a single env; ``step()`` before
      it says so in one line.
    - **Copies** (``copy.deepcopy``, pickle): the whole state, every car's generator included.
    """

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}
    #: attributes taken from ``settings`` (lambdas inside): a copy takes them again
    from_settings: tuple[str, ...] = ("observation",)

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 **kwargs: Any) -> None:
        why = supports(kwargs)
        if why is not None:
            raise ValueError(f"SmartCarSimVectorEnv cannot run {why}; use "
                             "vectorization_mode='sync' (or the vector_entry_point falls back)")
        self.num_envs = check_num_envs(num_envs, "SmartCarSim-v0", BYTES_PER_CAR)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        #: steps before a car's episode is truncated (None: no limit)
        self.max_episode_steps = check_max_episode_steps(max_episode_steps, "SmartCarSim-v0")
        kwargs.setdefault("controller_mode", KINEMATIC)
        s = _Settings(**kwargs)
        if s.controller_mode != KINEMATIC:
            raise ValueError(f"SmartCarSimVectorEnv is the kinematic mode ('sim'), got "
                             f"controller_mode={s.controller_mode!r}")
        self._take_settings(s)
        n = self.num_envs
        model, config = s.robot_model, s.controller_config
        wheels = list(model.left_wheels) + list(model.right_wheels)
        # wheels of one side and sign turn alike: each such group is computed once
        kinds = [(w.side, w.forward_sign) for w in wheels]
        groups = sorted(set(kinds))
        self._wheel_group = np.array([groups.index(k) for k in kinds])
        self._wheel_left = np.array([side == "left" for side, _ in groups])
        self._wheel_sign = np.array([float(sign) for _, sign in groups])
        self._half_track = config.base_width_m / 2.0
        self._wheel_radius = model.wheel_radius_m
        self.period_ns = seconds_to_ns(1.0 / config.rate_hz)
        self._duration = self.period_ns / NS_PER_S
        self.base = BatchedArbotix(config, KINEMATIC, model.wheel_radius_m, num_cars=n)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._steps = np.zeros(n, dtype=np.int64)
        self._pose = np.zeros((n, 3))  # the body's x, y, yaw in doubles
        self._wheels = np.zeros((n, len(groups)))
        self._wheel_speed = np.zeros((n, len(groups)))
        self.goal = np.zeros((n, 2))
        self._distance = np.zeros(n)
        self._prev_action = np.zeros((n, 2), dtype=np.float32)
        self._autoreset = np.zeros(n, dtype=bool)
        self._needs_reset = True

    def _take_settings(self, s: Any) -> None:
        """The task, observation, spaces and metadata of the single env (or its settings)
        ``s`` that every car shares."""
        self.settings = s
        self.task, self.observation = s.task, s.observation
        self.observation_names = s.observation_names
        self.render_mode = s.render_mode
        self.metadata = {**self.metadata, "render_fps": s.controller_config.rate_hz,
                         "autoreset_mode": self.autoreset_mode}
        self.single_observation_space = s.observation_space
        self.single_action_space = s.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    # -- copies --------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """Everything but what is taken from ``settings`` (the single env's own copy keeps
        its settings and declares its observation again)."""
        state = self.__dict__.copy()
        for key in self.from_settings:
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        for key in self.from_settings:
            setattr(self, key, getattr(self.settings, key))

    # -- gymnasium API -------------------------------------------------------------------------
    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """Each car's generator (created from entropy if it had none)."""
        return tuple(self._rng(i) for i in range(self.num_envs))

    def _rng(self, i: int) -> np.random.Generator:
        if self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random(None)
        return self._rngs[i]

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        n = self.num_envs
        seeds = check_seeds(seed, n)
        if self.closed:  # as the single envs: reset() reopens
            self._reopen()
            self.closed = False
        options, mask = self._reset_mask(options)
        for i, s in enumerate(seeds):
            if mask[i] and (s is not None or self._rngs[i] is None):
                self._rngs[i], _ = seeding.np_random(s)
        goals = self._check_options(options)
        self._reset_cars(mask, goals)
        self._autoreset[mask] = False
        self._needs_reset = False
        return self._observe(), self._info(mask, np.zeros(n, dtype=bool))

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                          dict[str, Any]]:
        if self.closed:
            raise RuntimeError(f"{type(self).__name__} is closed: call reset() to reopen it "
                               "before step()")
        if self._needs_reset:
            raise gym.error.ResetNeeded(f"{type(self).__name__}: call reset() before step()")
        a = check_actions(actions, self.num_envs)
        restart = self._autoreset.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP \
            else np.zeros(self.num_envs, dtype=bool)
        reward, success, failure = self._advance(a)
        terminated = success | failure
        truncated = self._cut_short() | (
            self._steps >= self.max_episode_steps if self.max_episode_steps is not None
            else np.zeros(self.num_envs, dtype=bool))
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            if restart.any():
                self._reset_cars(restart, None)
                reward[restart] = 0.0
                terminated[restart] = truncated[restart] = success[restart] = False
            obs = self._observe()
            info = self._info(np.ones(self.num_envs, dtype=bool), success)
        else:
            done = terminated | truncated
            obs = self._observe()
            info = self._info(np.ones(self.num_envs, dtype=bool), success)
            if done.any():
                final_obs = np.full(self.num_envs, None, dtype=object)
                for i in np.flatnonzero(done):
                    final_obs[i] = self._car_obs(obs, i)
                final_info = self._info(done, success)
                self._reset_cars(done, None)
                obs = self._observe()
                info = self._info(np.ones(self.num_envs, dtype=bool), success & ~done)
                info["final_obs"], info["_final_obs"] = final_obs, done.copy()
                info["final_info"], info["_final_info"] = final_info, done.copy()
        self._autoreset = terminated | truncated
        return obs, reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode='rgb_array'")
            return None
        s = self.settings
        return top_down_tiles(self._pose[:16, :2], self._pose[:16, 2], self.goal[:16],
                              s.task.goal_tolerance_m, s.task.arena_half_size_m,
                              s.render_width, s.render_height)

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release: no engine, no files."""

    def _reopen(self) -> None:
        """What ``close_extras`` released, back before ``reset`` starts the cars again (nothing
        here)."""

    # -- the model -----------------------------------------------------------------------------
    def _reset_mask(self, options: Any) -> tuple[Any, np.ndarray]:
        """``options`` without ``"reset_mask"``, and the cars to reset (all without one)."""
        everyone = np.ones(self.num_envs, dtype=bool)
        if not isinstance(options, dict) or "reset_mask" not in options:
            return options, everyone
        options = dict(options)
        mask = options.pop("reset_mask")
        if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_
                and mask.shape == (self.num_envs,) and mask.any()):
            raise ValueError(f"options['reset_mask'] must be a bool array of shape "
                             f"({self.num_envs},) with a car to reset, got {mask!r}")
        if self._needs_reset and not mask.all():
            raise gym.error.ResetNeeded(f"{type(self).__name__}: the first reset() resets every "
                                        "car (no reset_mask)")
        return options or None, mask.copy()

    def _check_options(self, options: Any) -> np.ndarray | None:
        if options is None:
            return None
        if not isinstance(options, dict) or set(options) - {"goal"}:
            raise ValueError(f"reset options must be {{'goal': (x, y) or an ({self.num_envs}, 2) "
                             f"array}}, got {options!r}")
        if "goal" not in options:
            return None
        goal = np.asarray(options["goal"], dtype=float)
        rows = goal.reshape(-1, 2) if goal.shape in ((2,), (self.num_envs, 2)) else None
        if rows is None:
            raise ValueError(f"options['goal'] must be (x, y) or an ({self.num_envs}, 2) array, "
                             f"got shape {goal.shape}")
        checked = np.array([self.task.check_goal(g) for g in rows])
        return np.broadcast_to(checked, (self.num_envs, 2))

    def _reset_cars(self, mask: np.ndarray, goals: np.ndarray | None) -> None:
        """Spawn the masked cars afresh at the origin, each with a goal from its generator."""
        idx = np.flatnonzero(mask)
        origin = np.zeros(2)
        for i in idx:
            self.goal[i] = (goals[i] if goals is not None
                            else self.task.sample_goal(self._rng(i), origin))
        self._steps[idx] = 0
        self._pose[idx] = 0.0
        self._wheels[idx] = 0.0
        self._wheel_speed[idx] = 0.0
        self._prev_action[idx] = 0.0
        self.base.reset(0.0, None, mask)
        # the position is float32 in pybullet: (0, 0) exactly
        g = self.goal[idx]
        dx, dy = 0.0 - g[:, 0], 0.0 - g[:, 1]
        self._distance[idx] = np.sqrt(dx * dx + dy * dy)

    def _advance(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One controller period for every car: SmartCarEnv.step's arithmetic, in arrays."""
        s = self.settings
        now_s = (self._steps * self.period_ns).astype(np.float64) / NS_PER_S
        self.base.cmd_vel(a[:, 0] * s.max_linear, a[:, 1] * s.max_angular, now_s)
        self._steps += 1
        # the body moves with the commanded twist (SmartCarRobot._move_kinematically) ...
        v, w = self.base.commanded_twist()
        duration = self._duration
        x, y, th = self._pose[:, 0], self._pose[:, 1], self._pose[:, 2]
        x += v * np.cos(th) * duration
        y += v * np.sin(th) * duration
        th += w * duration
        side = np.where(self._wheel_left, (v - w * self._half_track)[:, None],
                        (v + w * self._half_track)[:, None])
        self._wheel_speed = side / self._wheel_radius * self._wheel_sign
        self._wheels += self._wheel_speed * duration
        # ... then the controller fires
        self.base.update((self._steps * self.period_ns).astype(np.float64) / NS_PER_S)
        # the task, on the position as pybullet stores it (float32)
        px = x.astype(np.float32).astype(np.float64)
        py = y.astype(np.float32).astype(np.float64)
        return self._score(px, py, a)

    def _score(self, px: np.ndarray, py: np.ndarray, a: np.ndarray,
               flipped: np.ndarray | bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reward, success and failure of every car from its true position: the arithmetic
        of ``GoalReachingTask.evaluate``, in its order, on arrays."""
        task = self.task
        dx, dy = px - self.goal[:, 0], py - self.goal[:, 1]
        distance = np.sqrt(dx * dx + dy * dy)
        success = distance < task.goal_tolerance_m
        half = task.arena_half_size_m
        failure = flipped | (np.abs(px) > half) | (np.abs(py) > half)
        reward = (task.progress_weight * (self._distance - distance) - task.time_cost
                  - task.action_cost * (a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1])
                  + task.success_bonus * success.astype(np.float64)
                  - task.failure_penalty * failure.astype(np.float64))
        self._distance = distance
        self._prev_action = a.astype(np.float32)
        return reward, success, failure

    def _cut_short(self) -> np.ndarray:
        """Which cars the env itself truncates this step (none here: only the time limit)."""
        return np.zeros(self.num_envs, dtype=bool)

    @staticmethod
    def _car_obs(obs: np.ndarray, i: int) -> np.ndarray:
        """Car ``i``'s observation, copied out of the batch (``final_obs``)."""
        return obs[i].copy()

    def _observe(self) -> np.ndarray:
        """Every car's observation: ``Observation.build``'s values, in its order and rounding."""
        return self._build(self.observation, self._columns())

    def _build(self, observation: Observation, columns: dict[str, Any]) -> np.ndarray:
        """``observation.build`` for every car from the entries' ``columns``."""
        obs = np.empty((self.num_envs, len(observation.names)), dtype=np.float32)
        k = 0
        for entry in observation.entries:
            for col in columns[entry.key]:
                obs[:, k] = col  # each float64 value rounded once to float32
                k += 1
        return np.minimum(np.maximum(obs, observation.low, out=obs), observation.high, out=obs)

    def _columns(self) -> dict[str, Any]:
        """Each observation entry's values as columns over cars (by the entry's key)."""
        b = self.base
        c, s = np.cos(b.theta), np.sin(b.theta)
        gx, gy = self.goal[:, 0] - b.x, self.goal[:, 1] - b.y
        wrapped = (self._wheels + math.pi) % TWO_PI - math.pi
        group = self._wheel_group
        columns = {
            "odom_position": (b.x, b.y),
            "odom_heading": (c, s),
            "odom_linear": (b.odom_v,),
            "odom_angular": (b.odom_w,),
            "wheel_positions": [wrapped[:, k] for k in group],
            "wheel_velocities": [self._wheel_speed[:, k] for k in group],
            "goal_base": (c * gx + s * gy, -s * gx + c * gy),
            "goal_distance": (np.hypot(gx, gy),),
            "previous_action": (self._prev_action[:, 0], self._prev_action[:, 1]),
            "goal_odom": (self.goal[:, 0], self.goal[:, 1]),
        }
        return columns

    def _info(self, mask: np.ndarray, success: np.ndarray) -> dict[str, Any]:
        b, pose = self.base, self._pose
        px = pose[:, 0].astype(np.float32).astype(np.float64)
        py = pose[:, 1].astype(np.float32).astype(np.float64)
        values = {
            "is_success": success.copy(),
            "distance": self._distance.copy(),
            # the body's exact heading, wrapped; the single env's is pybullet's float32
            # quaternion's, within 1e-6 rad of it (docs/vector.md): the one inexact value
            "pose": np.stack([px, py, wrap_angles(pose[:, 2])], axis=1),
            "odom_pose": np.stack([b.x, b.y, wrap_angles(b.theta)], axis=1),
            "odom_error": planar_norms(b.x - px, b.y - py),
        }
        if not mask.all():
            values = {k: np.where(mask.reshape(-1, *([1] * (v.ndim - 1))), v,
                                  np.zeros_like(v)) for k, v in values.items()}
        return vector_info(values, mask)
