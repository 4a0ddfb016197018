"""SmartCar-v0 on MuJoCo for N cars: the physics in C per car, everything else in numpy arrays."""

from __future__ import annotations

import math
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from smartcar_gym.controller import HARDWARE
from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.tasks.reach import FLIP_UP_Z
from smartcar_gym.envs.vector.common import (
    CannotBatch,
    batch_limits,
    check_autoreset_mode,
    check_max_episode_steps,
    check_num_envs,
    check_num_threads,
    vector_info,
)
from smartcar_gym.envs.vector.exact import planar_norms, wrap_angles
from smartcar_gym.envs.vector.kinematic import SmartCarSimVectorEnv
from smartcar_gym.envs.vector.render import top_down_tiles
from smartcar_gym.sim.clock import MAX_FIRINGS_PER_INSTANT, NS_PER_S

#: measured with 4.0.0 (256 cars): 0.74 MiB resident per car, mostly its MjData arena
BYTES_PER_CAR = 800 * 1024
_NEVER = np.iinfo(np.int64).max


def supports(kwargs: dict[str, Any]) -> str | None:
    """Why ``SmartCarMujocoVectorEnv`` cannot run these SmartCar-v0 kwargs (None: it can)."""
    if kwargs.get("engine") != "mujoco":
        return "only engine='mujoco' is batched in C"
    return batch_limits(kwargs)


class SmartCarMujocoVectorEnv(SmartCarSimVectorEnv):
    """## Description

    ``SmartCar-v0`` with ``engine="mujoco"`` for ``num_envs`` cars at once. Per car it is
    ``gym.make("SmartCar-v0", engine="mujoco")`` bit for bit (tested): each car is a copy of
    the single env's compiled, settled MuJoCo world (``sim.mujoco.batch.CarBatch``), stepped
    with the single env's event clock, each interval between its own events in the fewest equal
    substeps no longer than ``max_substep_s`` with one ``mj_step(model, data, n)`` call; the
    cars are split between ``num_threads`` worker threads (MuJoCo runs without Python's GIL).
    The ArbotiX boards and ``diff_controller`` s are ``controller.batched.BatchedArbotix``;
    observation, reward and resets are numpy over cars.

    Every car keeps its own clock from its own reset, so after autoresets cars are at different
    points of the board's 35 ms PID frame cycle: each car's events are found and its intervals
    stepped on its own (no common schedule is assumed).

    Made by ``gym.make_vec("SmartCar-v0", num_envs=N, vectorization_mode="vector_entry_point",
    engine="mujoco", **kwargs)`` with SmartCarEnv's kwargs, plus ``max_episode_steps``,
    ``autoreset_mode`` and ``num_threads`` (worker threads stepping the physics, an integer
    >= 1; default ``os.cpu_count()``).
    ``randomize``, ``render_mode="human"``, ``controller_mode="sim"`` and differential-drive
    models fall back to ``SmartCarLoopVectorEnv``.

    ## Conventions

    As ``SmartCarSimVectorEnv`` (autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
    ``s + i``, ``info`` per car with ``_key`` masks, ``(N, 2)`` actions, ``render()`` tiles the
    first 16 cars top-down, ``reset()`` reopens a closed batch). A copy (``copy.deepcopy``,
    pickle) is as a copy of the single env: the same settings and generators, no worlds of
    the original's; its first ``reset()`` makes its own.
    """

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}
    #: the single env each car is bit for bit, and its id (messages)
    single_env = SmartCarEnv
    env_id = "SmartCar-v0"
    bytes_per_car = BYTES_PER_CAR
    why_not = staticmethod(supports)
    #: the engine each car runs on, and whether a differential-drive model can be batched
    engine = "mujoco"
    differential = False

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 num_threads: int | None = None, **kwargs: Any) -> None:
        kwargs.setdefault("engine", self.engine)
        why = self.why_not(kwargs)
        if why is not None:
            raise ValueError(f"{type(self).__name__} cannot run {why}; use "
                             "vectorization_mode='sync' (or the vector_entry_point falls back)")
        self.num_envs = check_num_envs(num_envs, f"{self.env_id} (mujoco)", self.bytes_per_car)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        #: steps before a car's episode is truncated (None: no limit)
        self.max_episode_steps = check_max_episode_steps(max_episode_steps, self.env_id)
        num_threads = check_num_threads(num_threads)
        template = self.single_env(**kwargs)
        try:
            if template.controller_mode != HARDWARE:
                raise ValueError(f"{type(self).__name__} is the hardware mode (PID, motors)")
            if template.robot_model.drive_kind == "differential" and not self.differential:
                raise CannotBatch(f"{type(self).__name__} runs skid-steer bases; a "
                                  "differential-drive model starts its encoders mid-tick "
                                  "(the vector_entry_point falls back to the loop)")
            template.reset(seed=0)
            self._init_from(template, num_threads)
        except BaseException:
            template.close()
            raise
        self._keep(template)

    def _keep(self, template: SmartCarEnv) -> None:
        """The single env the batch was made from, once made: closed (every car is a copy of
        its world)."""
        template.close()

    def _init_from(self, s: SmartCarEnv, num_threads: int) -> None:
        from smartcar_gym.sim.mujoco.batch import CarBatch

        self._take_settings(s)
        n, robot, sim = self.num_envs, s.robot, s.sim
        ids = robot.body._ids
        qadr, dadr = ids.addresses(robot.wheel_joint_indices)
        self._wheel_q = np.asarray(qadr)
        self._wheel_v = np.asarray(dadr)
        self._encoder_q = np.asarray(ids.addresses(robot._encoder_idx)[0])
        self._encoder_sign = np.array(robot._encoder_signs, dtype=np.float64)
        self._free_q, self._free_v = ids.free_q, ids.free_v
        self._side = np.array([0 if left else 1 for left in robot._left])
        self._share = np.array(robot._share)
        self._sign = np.array(robot._signs)
        self.max_substep_ns = sim.max_substep_ns
        self.cars = CarBatch(sim, n, list(dadr), num_threads)
        wheels = len(self._wheel_q)
        self._wheel_group = np.arange(wheels)
        self.period_ns = robot.update_period_ns
        self._allocate(s, wheels)

    def _allocate(self, s: SmartCarEnv, wheels: int) -> None:
        """What every physics batch keeps per car, whatever its engine: the boards and
        controllers, clocks, poses, wheels, goals and episode state."""
        n = self.num_envs
        self.base = BatchedArbotix(s.controller_config, HARDWARE, s.robot_model.wheel_radius_m,
                                   num_cars=n, encoder_phase_ticks=s.robot.encoder_phase_ticks)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._steps = np.zeros(n, dtype=np.int64)
        self._now = np.zeros(n, dtype=np.int64)  # each car's clock (ns since its reset)
        self._next_update = np.zeros(n, dtype=np.int64)
        self._pose = np.zeros((n, 3))
        self._up_z = np.ones(n)
        self._wheels = np.zeros((n, wheels))
        self._wheel_speed = np.zeros((n, wheels))
        self.goal = np.zeros((n, 2))
        self._distance = np.zeros(n)
        self._prev_action = np.zeros((n, 2), dtype=np.float32)
        self._autoreset = np.zeros(n, dtype=bool)
        self._parked = np.zeros(n, dtype=bool)
        self._needs_reset = True

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the worker threads and free the cars' worlds (``reset`` makes them again)."""
        if getattr(self, "cars", None) is not None:
            self.cars.close()
        self._needs_reset = True

    def _reopen(self) -> None:
        """Every car a copy of the settled world again (the batch's template)."""
        self.cars.reopen()

    def __getstate__(self) -> dict[str, Any]:
        """A copy keeps the settings, every car's generator and the settled world it was
        made from, never the cars' worlds or threads: it is closed, and its first ``reset``
        reopens it (as a copy of a single env gets a world of its own at its first reset)."""
        state = super().__getstate__()
        state["closed"], state["_needs_reset"] = True, True
        return state

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode='rgb_array'")
            return None
        s = self.settings
        return top_down_tiles(self._pose[:16, :2], self._pose[:16, 2], self.goal[:16],
                              s.task.goal_tolerance_m, s.task.arena_half_size_m,
                              s.render_width, s.render_height)

    # -- the model -----------------------------------------------------------------------------
    def _angles(self) -> np.ndarray:
        """The encoder wheels' forward-positive angles (N, 2), as ``encoder_angles``."""
        return self.cars.qpos[:, self._encoder_q] * self._encoder_sign

    def _read_pose(self) -> None:
        """Ground-truth x, y, yaw and up_z from the free joint (``pose_from``'s arithmetic)."""
        q = self.cars.qpos[:, self._free_q:self._free_q + 7]
        qw, qx, qy, qz = q[:, 3], q[:, 4], q[:, 5], q[:, 6]
        self._pose[:, 0], self._pose[:, 1] = q[:, 0], q[:, 1]
        # math.atan2 (libm), as the single env: numpy's arctan2 differs in the last bit
        self._pose[:, 2] = list(map(math.atan2, (2.0 * (qw * qz + qx * qy)).tolist(),
                                    (1.0 - 2.0 * (qy * qy + qz * qz)).tolist()))
        self._up_z = 1.0 - 2.0 * (qx * qx + qy * qy)

    def park(self, mask: np.ndarray) -> None:
        """Stop simulating the masked cars until each one's next reset (``reset`` or an
        autoreset): no events, no physics, their clocks stand still. ``step`` still reports
        them, computed from where they stand (the same observation; a reward, ends and infos
        that mean nothing). For evaluations with fewer episodes left than cars: the idle cars
        cost no physics (``smartcar-eval --vectorization batched``). The other cars step
        exactly as they would have."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.num_envs,):
            raise ValueError(f"park: expected a bool mask of shape ({self.num_envs},), got "
                             f"shape {mask.shape}")
        self._parked |= mask

    def _reset_cars(self, mask: np.ndarray, goals: np.ndarray | None) -> None:
        """The masked cars afresh: the settled world, the controller at t = 0, a new goal."""
        idx = np.flatnonzero(mask)
        self._parked[idx] = False
        self._new_worlds(idx, goals)
        self._steps[idx] = 0
        self._now[idx] = 0
        self._next_update[idx] = self.period_ns
        self._prev_action[idx] = 0.0
        self.base.reset(0.0, self._angles(), mask)
        self._motors_to_wheels(mask)
        self._read_pose()
        d = self._pose[idx, :2] - self.goal[idx]
        self._distance[idx] = np.sqrt(np.add.reduce(d * d, axis=-1))

    def _new_worlds(self, idx: np.ndarray, goals: np.ndarray | None) -> None:
        """Each listed car's goal (given or drawn from its generator) and its world at t = 0."""
        origin = np.zeros(2)
        for i in idx:
            self.goal[i] = (goals[i] if goals is not None
                            else self.task.sample_goal(self._rng(i), origin))
        self.cars.reset(idx)

    def _motors_to_wheels(self, mask: np.ndarray) -> None:
        """Each side's motor output shared by its wheels (``set_motor_output``)."""
        side = self._side
        self.cars.torque[mask] = (self.base.drive_torque[mask][:, side] * self._share
                                  * self._sign)
        self.cars.damping[mask] = self.base.damping[mask][:, side] * self._share

    def _fire(self, mask: np.ndarray) -> None:
        """Every masked car's events due at its clock: controller update, then PID frame (the
        robot's), then the sensors' (``_fire_sensors``), in the single env's order."""
        now = self._now
        for _ in range(MAX_FIRINGS_PER_INSTANT):
            firing = mask & (self._robot_due() <= now)
            if not firing.any():
                self._fire_sensors(mask)
                return
            now_s = now / NS_PER_S
            angles = self._angles()
            update = firing & (now >= self._next_update)
            if update.any():
                self.base.update(now_s, angles, update)
                self._next_update[update] += self.period_ns
            self.base.board_tick(now_s, angles, firing)
            self._motors_to_wheels(firing)
        raise RuntimeError("a car's board is still due after "
                           f"{MAX_FIRINGS_PER_INSTANT} firings at one instant")

    def _fire_sensors(self, mask: np.ndarray) -> None:
        """The event sources after the robot (SmartCar-v0 has none)."""

    def _next_due(self) -> np.ndarray:
        """Each car's next event (ns on its clock), of any source."""
        return self._robot_due()

    def _robot_due(self) -> np.ndarray:
        """Each car's next robot event (ns on its clock): ``SmartCarRobot.next_event_ns``."""
        frame = self.base.next_frame_ms()
        frame_ns = np.where(frame >= 0, np.maximum(self._now, frame * 1_000_000), _NEVER)
        return np.minimum(self._next_update, frame_ns)

    def _run_period(self) -> None:
        """``run_until(now + period)`` for every car, from event to event."""
        end = self._now + self.period_ns
        pending = ~self._parked
        while True:
            self._fire(pending)
            active = pending & (self._now < end)
            if not active.any():
                return
            cars = np.flatnonzero(active)
            target = np.minimum(self._next_due()[cars], end[cars])
            interval = target - self._now[cars]
            nstep = -(-interval // self.max_substep_ns)
            timestep = interval.astype(np.float64) / (nstep * NS_PER_S).astype(np.float64)
            moving = interval > 0
            self.cars.step(cars[moving], nstep[moving], timestep[moving])
            if self.cars.unstable:
                self._report_unstable()
            self._now[cars] = target
            pending = active

    def _report_unstable(self) -> None:
        """A warning per car whose world MuJoCo found unstable (and reset), with its state."""
        from smartcar_gym.sim.mujoco.mjlog import MujocoWarning, describe

        events, self.cars.unstable = self.cars.unstable, []
        for car, event in sorted(events, key=lambda e: e[0]):
            line = describe(event, [(f"car {car}", self._free_q, self._free_v)])
            warnings.warn(f"{self.env_id} (mujoco): {line}", MujocoWarning, stacklevel=5)

    def _advance(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One controller period for every car: SmartCarEnv.step's arithmetic, in arrays."""
        s = self.settings
        self.base.cmd_vel(a[:, 0] * s.max_linear, a[:, 1] * s.max_angular,
                          self._now / NS_PER_S)
        self._run_period()
        self._steps += 1
        self._read_pose()
        return self._score(self._pose[:, 0], self._pose[:, 1], a, self._up_z < FLIP_UP_Z)

    def _read_wheels(self) -> None:
        """Every car's wheel joint angles and speeds, into ``_wheels`` and ``_wheel_speed``."""
        self._wheels = self.cars.qpos[:, self._wheel_q]
        self._wheel_speed = self.cars.qvel[:, self._wheel_v]

    def _columns(self) -> dict[str, Any]:
        self._read_wheels()
        return super()._columns()

    def _info(self, mask: np.ndarray, success: np.ndarray) -> dict[str, Any]:
        values = self._info_values(success)
        if not mask.all():
            values = {k: np.where(mask.reshape(-1, *([1] * (v.ndim - 1))), v,
                                  np.zeros_like(v)) for k, v in values.items()}
        return vector_info(values, mask)

    def _info_values(self, success: np.ndarray) -> dict[str, np.ndarray]:
        """Every car's ``info`` values (as SmartCarEnv's ``_info``) by key."""
        b, pose = self.base, self._pose
        return {
            "is_success": success.copy(),
            "distance": self._distance.copy(),
            "pose": pose.copy(),
            "odom_pose": np.stack([b.x, b.y, wrap_angles(b.theta)], axis=1),
            "odom_error": planar_norms(b.x - pose[:, 0], b.y - pose[:, 1]),
        }

