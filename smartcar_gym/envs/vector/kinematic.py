"""SmartCarSim-v0 for N cars in numpy arrays: the kinematic mode has no physics to step."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from smartcar_gym.controller import KINEMATIC
from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.envs.exact import wrap_angles
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.vector.base import CarsVectorEnv
from smartcar_gym.envs.vector.common import (
    check_autoreset_mode,
    check_max_episode_steps,
    check_num_envs,
)
from smartcar_gym.sim.clock import NS_PER_S, seconds_to_ns

#: measured: 4096 cars hold about 9 MiB of arrays; the margin covers the per-car generators
BYTES_PER_CAR = 16 * 1024


class _Settings(SmartCarEnv):
    """SmartCarEnv's argument checks, model, config, task and observation, without a world."""

    def _open(self) -> None:
        self._needs_reset = True


def supports(kwargs: dict[str, Any]) -> str | None:
    """Why ``SmartCarSimVectorEnv`` cannot run these SmartCarEnv kwargs (None: it can)."""
    if kwargs.get("randomize") is not None:
        return "randomize (domain randomisation) needs the per-episode pybullet world"
    if kwargs.get("render_mode") == "human":
        return "render_mode='human' is the pybullet GUI"
    if kwargs.get("stop_speed") is not None:
        return "stop_speed's arrival terms (SmartCarArrive-v0) need the true speed"
    return None


class SmartCarSimVectorEnv(CarsVectorEnv):
    """## Description

    ``SmartCarSim-v0`` (the driver's ``sim: true``: the car follows the commanded twist) for
    ``num_envs`` cars at once, stepped in numpy arrays with no physics engine. Per car it is
    ``gym.make("SmartCarSim-v0")`` bit for bit: observations, rewards, terminations,
    truncations and infos equal N single envs seeded ``s, s+1, ...`` (tested), but for
    ``info["pose"]``'s yaw: here the body's exact heading, in the single env pybullet's float32
    quaternion's, within 1e-6 rad of it (docs/vector.md). The controller is
    ``controller.batched.BatchedArbotix``; the ground-truth position is rounded to float32 as the
    single env's pybullet body stores it. The task is the single env's, one ``ReachTask``
    over all the cars.

    Made by ``gym.make_vec("SmartCarSim-v0", num_envs=N, vectorization_mode="vector_entry_point",
    **kwargs)`` with SmartCarEnv's kwargs (``max_substep_s``, ``physics_hz`` and
    ``wheel_contact`` have no effect: nothing is simulated), plus ``autoreset_mode``.

    It is not ``SmartCarBatchVectorEnv`` with a kinematic car batch, because it is not the same
    thing: there are no events and no clock to step between them (the car follows the
    commanded twist over the whole period, then the controller fires once, as
    ``SmartCarRobot`` moves in sim mode), no engine (no world to copy, reset or step), the
    controller is the kinematic mode's (no boards, no motors), and the pose is pybullet's
    float32 body's, not an engine's. What both share, the vector conventions below and the
    task, is their common base ``CarsVectorEnv``.

    ## Conventions (Gymnasium 1.x)

    - **Autoreset**: ``"NextStep"`` (Gymnasium's default, ``AutoresetMode.NEXT_STEP``): the step
      after a car's episode ends resets that car, ignores its action and returns its first
      observation with reward 0. ``autoreset_mode="SameStep"`` resets it in the step that ends
      the episode and puts its last observation and info in ``info["final_obs"]`` and
      ``info["final_info"]`` (what SB3 expects; ``agents.sb3_vec_env`` uses it).
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
      (as SmartCar-v0, with its arithmetic: ``envs.exact``), each with its ``_key`` mask.
    - **Actions**: ``(N, 2)`` real numbers in [-1, 1] (clipped); another shape, complex
      numbers or NaN is one error line.
    - **render()**: with ``render_mode="rgb_array"``, a top-down view of the first cars (up to
      16) tiled in one ``render_width x render_height`` image: arena, goal, car.
    - **close()**: ``reset()`` reopens a closed env, as it does a single env; ``step()`` before
      it says so in one line.
    - **Copies** (``copy.deepcopy``, pickle): the whole state, every car's generator included.
    """

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 env_id: str = "SmartCarSim-v0", **kwargs: Any) -> None:
        why = supports(kwargs)
        if why is not None:
            raise ValueError(f"SmartCarSimVectorEnv cannot run {why}; use "
                             "vectorization_mode='sync' (or the vector_entry_point falls back)")
        self.num_envs = check_num_envs(num_envs, env_id, BYTES_PER_CAR)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        #: steps before a car's episode is truncated (None: no limit)
        self.max_episode_steps = check_max_episode_steps(max_episode_steps, env_id)
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
        self.label = type(self).__name__
        self._allocate_episodes(n, len(wheels), {})
        self._body = np.zeros((n, 3))  # the body's x, y, yaw in doubles
        self._wheels = np.zeros((n, len(groups)))
        self._wheel_speed = np.zeros((n, len(groups)))

    def clearances(self, cars: np.ndarray, max_distance_m: float) -> np.ndarray:
        """No obstacles: every car is ``max_distance_m`` from any."""
        return np.full(len(cars), max_distance_m)

    # -- the model -----------------------------------------------------------------------------
    def _reset_cars(self, mask: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """Spawn the masked cars afresh at the origin, each with a goal from its generator."""
        idx = np.flatnonzero(mask)
        state = self.state
        self.task.start(self, idx, options)
        state.steps[idx] = 0
        self._body[idx] = 0.0
        self._wheels[idx] = 0.0
        self._wheel_speed[idx] = 0.0
        state.previous_action[idx] = 0.0
        self.base.reset(0.0, None, mask)
        self._read(state.steps)
        self.task.begin(self, idx)

    def _run(self, linear_x: np.ndarray, angular_z: np.ndarray) -> None:
        """One controller period for every car: the twist commanded now, the body moved with
        it (as ``SmartCarRobot`` in sim mode), then the controller fires."""
        steps = self.state.steps
        self.base.cmd_vel(linear_x, angular_z,
                          (steps * self.period_ns).astype(np.float64) / NS_PER_S)
        v, w = self.base.commanded_twist()
        duration = self._duration
        x, y, th = self._body[:, 0], self._body[:, 1], self._body[:, 2]
        x += v * np.cos(th) * duration
        y += v * np.sin(th) * duration
        th += w * duration
        side = np.where(self._wheel_left, (v - w * self._half_track)[:, None],
                        (v + w * self._half_track)[:, None])
        self._wheel_speed = side / self._wheel_radius * self._wheel_sign
        self._wheels += self._wheel_speed * duration
        after = steps + 1
        self.base.update((after * self.period_ns).astype(np.float64) / NS_PER_S)
        self._read(after)

    def _read(self, steps: np.ndarray) -> None:
        """The state: the position as pybullet stores it (float32), the exact heading, the
        odometry, the wheels; each car's clock at ``steps`` periods."""
        state, body = self.state, self._body
        state.pose[:, 0] = body[:, 0].astype(np.float32)
        state.pose[:, 1] = body[:, 1].astype(np.float32)
        state.pose[:, 2] = wrap_angles(body[:, 2])
        self._read_odometry()
        state.wheel_position[:] = self._wheels[:, self._wheel_group]
        state.wheel_velocity[:] = self._wheel_speed[:, self._wheel_group]
        state.now_ns[:] = steps * self.period_ns
