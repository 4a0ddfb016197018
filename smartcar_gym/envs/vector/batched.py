"""SmartCar-, SmartCarNav-, SmartCarGoal- and SmartCarBARN-v0, N cars on an engine with a car batch.

One class, engine-neutral: the clocks, events, batched ArbotiX boards, autoreset and ``park``
are here; the physics is the engine's ``CarBatch`` (``sim.batch``), made by the registered
engine's ``car_batch`` (``sim.engines``); each id's task is a tuple of parts
(``envs.vector.parts``).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from smartcar_gym.controller import HARDWARE
from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.controller.latency import CommandDelay
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.vector import barn_part  # noqa: F401  (adds SmartCarBARN-v0's parts)
from smartcar_gym.envs.vector.base import CarsVectorEnv
from smartcar_gym.envs.vector.common import (
    CannotBatch,
    batch_limits,
    check_autoreset_mode,
    check_max_episode_steps,
    check_num_envs,
    check_num_threads,
)
from smartcar_gym.envs.vector.parts import TASKS, TaskPart
from smartcar_gym.sim.batch import CarBatch
from smartcar_gym.sim.clock import MAX_FIRINGS_PER_INSTANT, NS_PER_S
from smartcar_gym.sim.engines import DEFAULT_ENGINE, engine_names, get_engine

_NEVER = np.iinfo(np.int64).max


def _last_with(parts: tuple[TaskPart, ...], hook: str) -> TaskPart:
    """The last of ``parts`` whose class has its own ``hook`` (the one that does it)."""
    return [p for p in parts if getattr(type(p), hook) is not getattr(TaskPart, hook)][-1]


class SmartCarBatchVectorEnv(CarsVectorEnv):
    """## Description

    ``env_id`` (an id of ``parts.TASKS``: Nav, Goal, BARN, ...) for ``num_envs`` cars at once
    on ``engine``, any registered engine with a car batch (``Engine.car_batch``: MuJoCo's
    worlds stepped in C, the planar engine's arrays). Per car it is ``gym.make(env_id,
    engine=...)`` bit for bit (tested): the single env is made, reset (spawn and settle) and
    copied into every car (``CarBatch``); each car keeps its own clock from its own reset and
    the single env's event stepping: at each of its events (the controller every 0.1 s, the
    board's PID frame every 35 ms while it drives, a task's sensors) the batched ArbotiX
    (``controller.batched.BatchedArbotix``) fires for the cars that are due, their motor
    outputs go to the engine, and every car steps to its own next event in the fewest equal
    substeps no longer than ``max_substep_s``. After autoresets cars are at different points
    of the 35 ms frame cycle, so no common schedule is assumed. The task is the id's parts
    (``parts.TASKS``): reaching a goal; Nav's obstacles and laser; Goal's ``Dict``
    observation and ``compute_reward``; BARN's worlds, waypoint, outcome and scores.

    Made by ``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point",
    engine=..., **kwargs)`` with the single env's kwargs, plus ``max_episode_steps``,
    ``autoreset_mode`` and ``num_threads`` (worker threads stepping the physics where the
    engine uses them, an integer >= 1; default ``os.cpu_count()``). What no batch runs
    (``render_mode="human"``, ``controller_mode="sim"``, ``stop_speed``; any ``render_mode``
    on Nav; ``randomize`` on the ids without a part that keeps a single env to build each
    car's episode) and differential-drive models on an engine whose batch does not take them
    (``batches_differential``) fall back to ``SmartCarLoopVectorEnv``. With ``randomize``
    (Nav, BARN) each car's robot is the builder's draw for its episode (``take_robot``: the
    body through ``CarBatch.load``, the board's track, motor and faulty encoders, the
    command latency), and ``info["randomization"]`` is every car's draw.

    ## Conventions

    As ``SmartCarSimVectorEnv`` (autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
    ``s + i``, ``info`` per car with ``_key`` masks, ``(N, 2)`` actions, ``render()`` tiles the
    first 16 cars top-down, ``reset()`` reopens a closed batch), plus ``park``. A copy
    (``copy.deepcopy``, pickle) is as a copy of the single env: the same settings and
    generators, no worlds of the original's; it is closed and its first ``reset()`` makes
    its own. What a part exports is read through the env (``latest_ranges``, ``obstacles``,
    ``compute_reward``, ...).
    """

    def __init__(self, env_id: str, num_envs: int = 1, max_episode_steps: int | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 num_threads: int | None = None, *, label: str | None = None,
                 **kwargs: Any) -> None:
        name = kwargs.setdefault("engine", DEFAULT_ENGINE)
        self.env_id = env_id
        #: what the env calls itself in its error lines
        self.label = label or f"{type(self).__name__} ({env_id} on {name})"
        why = self.why_not(env_id, kwargs)
        if why is not None:
            raise ValueError(f"{self.label} cannot run {why}; use vectorization_mode='sync' "
                             "(or the vector_entry_point falls back)")
        engine = get_engine(name)
        #: the engine each car runs on (its registered name)
        self.engine = engine.name
        single_env, part_types = TASKS[env_id]
        self.parts: tuple[TaskPart, ...] = tuple(part() for part in part_types)
        make_cars = engine.car_batch
        assert make_cars is not None  # why_not said so
        per_car = (getattr(make_cars, "bytes_per_car", 0)
                   + sum(p.bytes_per_car for p in self.parts))
        self.num_envs = check_num_envs(num_envs, f"{env_id} ({name})", per_car)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        #: steps before a car's episode is truncated (None: no limit)
        self.max_episode_steps = check_max_episode_steps(max_episode_steps, env_id)
        threads = check_num_threads(num_threads)
        #: the worker threads the cars' compiled loops split over (physics, laser, parts)
        self.threads = threads
        template = single_env(**kwargs)
        try:
            if template.controller_mode != HARDWARE:
                raise ValueError(f"{self.label} is the hardware mode (PID, motors)")
            if template.robot_model.drive_kind == "differential" \
                    and not engine.batches_differential:
                raise CannotBatch(f"{self.label} runs skid-steer bases; a differential-drive "
                                  "model starts its encoders mid-tick (the vector_entry_point "
                                  "falls back to the loop)")
            template.reset(seed=0)
            self._init_from(template, make_cars(template, self.num_envs, threads))
        except BaseException:
            template.close()
            raise
        if not any(p.keeps_single for p in self.parts):
            template.close()  # every car is a copy of its world

    @staticmethod
    def why_not(env_id: str, kwargs: dict[str, Any]) -> str | None:
        """Why this class cannot run ``env_id`` with these single-env kwargs (None: it can)."""
        if env_id not in TASKS:
            return f"{env_id} (the batched ids are {', '.join(TASKS)})"
        name = kwargs.get("engine", DEFAULT_ENGINE)
        if name not in engine_names():
            return f"engine={name!r}, not a registered engine"
        if get_engine(name).car_batch is None:
            return f"engine={name!r}: it has no car batch (Engine.car_batch)"
        why = batch_limits(kwargs)
        parts = TASKS[env_id][1]
        if why is None and kwargs.get("randomize") is not None \
                and not any(p.keeps_single for p in parts):
            batched = ", ".join(i for i, (_, ps) in TASKS.items()
                                if any(p.keeps_single for p in ps))
            why = (f"randomize (domain randomisation) on {env_id}: the batch varies a car as "
                   f"the single env that builds its episode draws it ({batched})")
        for part in parts:
            why = why or part.limits(kwargs)
        return why

    def _init_from(self, s: SmartCarEnv, cars: CarBatch) -> None:
        """Everything per car, from the settled single env ``s`` and its copies ``cars``."""
        self._take_settings(s)
        n, robot = self.num_envs, s.robot
        #: the engine's cars (the ``CarBatch`` protocol)
        self.cars = cars
        self.max_substep_ns = s.sim.max_substep_ns
        self.period_ns = robot.update_period_ns
        wheels = len(robot.wheel_joint_indices)
        self._wheel_group = np.arange(wheels)
        self.base = BatchedArbotix(s.controller_config, HARDWARE, s.robot_model.wheel_radius_m,
                                   num_cars=n, encoder_phase_ticks=robot.encoder_phase_ticks)
        self._allocate_episodes(n)
        self._now = np.zeros(n, dtype=np.int64)  # each car's clock (ns since its reset)
        self._next_update = np.zeros(n, dtype=np.int64)
        self._pose = np.zeros((n, 3))
        self._up_z = np.ones(n)
        self._wheels = np.zeros((n, wheels))
        self._wheel_speed = np.zeros((n, wheels))
        self._parked = np.zeros(n, dtype=bool)
        #: per car whose robot delays its commands (``randomize``'s latency): the delay
        self._delays: dict[int, CommandDelay] = {}
        #: per car, its robot's draw (``info["randomization"]``; None: not varied)
        self._draws: list[dict[str, float | int] | None] = [None] * n
        for part in self.parts:
            part.attach(self, s)
        self._sensors = tuple(p for p in self.parts if p.senses)
        self._starter = _last_with(self.parts, "new_worlds")
        self._observer = _last_with(self.parts, "observe")
        self._option_keys = {key for p in self.parts for key in p.option_keys}

    def __getattr__(self, name: str) -> Any:
        """What a part exports (``latest_ranges``, ``compute_reward``, ...), read here."""
        for part in self.__dict__.get("parts", ()):
            if name in part.exports:
                return getattr(part, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def close_extras(self, **kwargs: Any) -> None:
        """Free the cars' worlds and threads, and what the parts hold (``reset`` reopens)."""
        if self.__dict__.get("cars") is not None:
            self.cars.close()
        for part in self.__dict__.get("parts", ()):
            part.close()
        self._needs_reset = True

    def _reopen(self) -> None:
        """Every car a copy of the settled world again."""
        self.cars.reopen()

    def __getstate__(self) -> dict[str, Any]:
        """A copy keeps the settings, every car's generator and the settled world it was
        made from, never the cars' worlds or threads: it is closed, and its first ``reset``
        reopens it (as a copy of a single env gets a world of its own at its first reset)."""
        state = super().__getstate__()
        state["closed"], state["_needs_reset"] = True, True
        return state

    def park(self, mask: np.ndarray) -> None:
        """Stop simulating the masked cars until a ``reset`` names each one (``reset_mask``): no
        events, no physics, their clocks stand still, and no autoreset (a car parked once its
        episode ended is not started again). ``step`` still reports them, computed from where
        they stand (the same observation; a reward and infos that mean nothing) and never
        ending (``terminated`` and ``truncated`` False). For evaluations with fewer episodes
        left than cars: the idle cars cost no physics and no new world
        (``smartcar-eval --vectorization batched``, ``smartcar-bench barn``). The other cars step
        exactly as they would have. ``mask`` is a numpy bool array of shape (N,)."""
        if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_
                and mask.shape == (self.num_envs,)):
            got = (f"a {mask.dtype} array of shape {mask.shape}" if isinstance(mask, np.ndarray)
                   else f"a {type(mask).__name__}")
            raise ValueError(f"park: expected a bool mask of shape ({self.num_envs},) (a numpy "
                             f"array of dtype bool), got {got}")
        self._parked |= mask

    # -- resets --------------------------------------------------------------------------------
    def _check_options(self, options: Any) -> np.ndarray | None:
        """The parts' options (checked first, kept once ``goal`` is checked too), then the
        ``goal`` option."""
        taken: dict[str, Any] = {}
        if isinstance(options, dict) and self._option_keys & options.keys():
            options = dict(options)
            taken = {key: options.pop(key) for key in self._option_keys if key in options}
        for part in self.parts:
            part.check_options(self, taken)
        goals = super()._check_options(options)
        for part in self.parts:
            part.take_options(taken)
        return goals

    def _reset_cars(self, mask: np.ndarray, goals: np.ndarray | None) -> None:
        """The masked cars afresh: a new goal and world, the controller at t = 0."""
        idx = np.flatnonzero(mask)
        self._parked[idx] = False
        self._starter.new_worlds(self, idx, goals)
        self._steps[idx] = 0
        self._now[idx] = 0
        self._next_update[idx] = self.period_ns
        self._prev_action[idx] = 0.0
        self.base.reset(0.0, self.cars.encoder_angles(), mask)
        self._motors_to_wheels(mask)
        self._read_pose()
        for part in self.parts:
            part.after_reset(self, mask, idx)

    def take_robot(self, i: int, single: SmartCarEnv) -> None:
        """Car ``i``'s robot becomes ``single``'s, just reset for the car's episode (the
        builder's): where that robot varies (``randomize``), its controller's track, motor and
        encoders (``BatchedArbotix.vary``), its command latency and its draw; the engine's
        ``CarBatch.load`` takes its body."""
        robot = single.robot
        self._draws[i] = None if single.draw is None else single.draw.info
        encoders = robot.base.encoders
        self.base.vary(i, robot.config, None if all(e.exact for e in encoders) else encoders)
        if robot.command_delay is None:
            self._delays.pop(i, None)
        else:
            self._delays[i] = robot.command_delay

    def _command(self, lx: np.ndarray, az: np.ndarray) -> None:
        """Every car's ``cmd_vel`` now (``SmartCarRobot.cmd_vel``): a delayed car's into its
        line, the others' to the boards."""
        now_s = self._now / NS_PER_S
        if not self._delays:
            self.base.cmd_vel(lx, az, now_s)
            return
        direct = np.ones(self.num_envs, dtype=bool)
        for i, delay in self._delays.items():
            delay.publish(float(lx[i]), float(az[i]), int(self._now[i]))
            direct[i] = False
        self.base.cmd_vel(lx, az, now_s, direct)

    def _deliver(self, updated: np.ndarray, now_s: np.ndarray) -> None:
        """The delayed commands that arrive at the updates just run (``on_event``)."""
        for i in np.flatnonzero(updated).tolist():
            delay = self._delays.get(i)
            if delay is None:
                continue
            for linear_x, angular_z in delay.arrivals(int(self._now[i])):
                one = np.zeros(self.num_envs, dtype=bool)
                one[i] = True
                self.base.cmd_vel(linear_x, angular_z, now_s, one)

    # -- the model -----------------------------------------------------------------------------
    def _read_pose(self) -> None:
        """Every car's ground-truth x, y, yaw (``_pose``) and up axis' z (``_up_z``)."""
        self._up_z = self.cars.read_pose(self._pose)

    def _motors_to_wheels(self, mask: np.ndarray) -> None:
        """The masked cars' motor outputs (the boards') to their wheels."""
        self.cars.set_drive(mask, self.base.drive_torque, self.base.damping)

    def _fire(self, mask: np.ndarray) -> None:
        """Every masked car's events due at its clock: controller update, then PID frame (the
        robot's), then the parts' sensors, in the single env's order."""
        now, cars, base = self._now, self.cars, self.base
        for _ in range(MAX_FIRINGS_PER_INSTANT):
            firing = mask & (self._robot_due() <= now)
            if not firing.any():
                for part in self._sensors:
                    part.fire(self, mask)
                return
            now_s = now / NS_PER_S
            angles = cars.encoder_angles()
            update = firing & (now >= self._next_update)
            if update.any():
                base.update(now_s, angles, update)
                if self._delays:
                    self._deliver(update, now_s)
                self._next_update[update] += self.period_ns
            base.board_tick(now_s, angles, firing)
            cars.set_drive(firing, base.drive_torque, base.damping)
        raise RuntimeError("a car's board is still due after "
                           f"{MAX_FIRINGS_PER_INSTANT} firings at one instant")

    def _next_due(self) -> np.ndarray:
        """Each car's next event (ns on its clock), of any source."""
        due = self._robot_due()
        for part in self._sensors:
            due = np.minimum(due, part.next_due(self))
        return due

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
            unstable = self.cars.take_unstable()
            if unstable:
                self._report_unstable(unstable)
            self._now[cars] = target
            pending = active

    def _report_unstable(self, found: Any) -> None:
        """The engine's warnings of unstable cars, each naming the id and engine."""
        for warning in found:
            warnings.warn(f"{self.env_id} ({self.engine}): {warning}", type(warning),
                          stacklevel=5)

    def _advance(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One controller period for every car: SmartCarEnv.step's arithmetic, in arrays,
        then the task's score (each part's, in order)."""
        s = self.settings
        self._command(a[:, 0] * s.max_linear, a[:, 1] * s.max_angular)
        self._run_period()
        self._steps += 1
        self._read_pose()
        score = None
        for part in self.parts:
            score = part.score(self, a, score)
        assert score is not None
        return score

    def _cut_short(self) -> np.ndarray:
        truncated = np.zeros(self.num_envs, dtype=bool)
        for part in self.parts:
            truncated = part.cut_short(self, truncated)
        return truncated

    # -- observations and infos ----------------------------------------------------------------
    def _columns(self) -> dict[str, Any]:
        self._wheels, self._wheel_speed = self.cars.read_wheels()
        columns: dict[str, Any] = {}
        for part in self.parts:
            part.columns(self, columns)
        return columns

    def _observe(self) -> Any:
        return self._observer.observe(self, self._columns())

    def _car_obs(self, obs: Any, i: int) -> Any:
        return self._observer.car_obs(obs, i)

    def _info_values(self, success: np.ndarray) -> dict[str, Any]:
        values: dict[str, Any] = {}
        for part in self.parts:
            part.info_values(self, values, success)
        draws = self._draws
        if draws[0] is not None:  # randomize: every car's, by factor
            values["randomization"] = {key: np.array([d[key] for d in draws])
                                       for key in draws[0]}
        return values
