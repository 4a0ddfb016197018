"""Any id's task for N cars on an engine with a car batch: one task object over all the cars.

One class, engine-neutral and task-neutral: the clocks and events (``events.Clocks``), the
batched ArbotiX boards, the laser (``laser.BatchLaser``), autoreset and ``park`` are here; the
physics is the engine's ``CarBatch`` (``sim.batch``), made by the registered engine's
``car_batch`` (``sim.engines``); the task is the id's (``envs.tasks``), the very class its
single env runs.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from smartcar_gym.controller import HARDWARE
from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.tasks.registry import get_task, task_names, task_of
from smartcar_gym.envs.vector.base import CarsVectorEnv
from smartcar_gym.envs.vector.common import (
    CannotBatch,
    batch_limits,
    check_autoreset_mode,
    check_max_episode_steps,
    check_num_envs,
    check_num_threads,
    check_park_mask,
)
from smartcar_gym.envs.vector.events import Clocks
from smartcar_gym.envs.vector.laser import BatchLaser
from smartcar_gym.sim.batch import CarBatch
from smartcar_gym.sim.engines import DEFAULT_ENGINE, engine_names, get_engine


def id_kwargs(env_id: str, kwargs: dict[str, Any]) -> dict[str, Any]:
    """``kwargs`` over the id's registered ones (its task among them), as ``gym.make`` gives
    them (``gym.make_vec`` passes them already)."""
    if "task" in kwargs:
        return dict(kwargs)
    return {**gym.spec(env_id).kwargs, **kwargs}


class SmartCarBatchVectorEnv(CarsVectorEnv):
    """## Description

    ``env_id`` (any registered task's id: Reach, Nav, Goal, BARN, a plug-in's) for
    ``num_envs`` cars at once on ``engine``, any registered engine with a car batch
    (``Engine.car_batch``: MuJoCo's worlds stepped in C, the planar engine's arrays). Per car
    it is ``gym.make(env_id, engine=...)`` bit for bit (tested): the single env is made, reset
    (spawn and settle) and copied into every car (``CarBatch``); each car keeps its own clock
    from its own reset and the single env's event stepping (``events.Clocks``). The task is
    the single env's task class, one object over all the cars (``Task.for_cars``); a task
    whose episodes build worlds of their own (``Task.builds_worlds``: Nav's obstacles, BARN's
    worlds) has each car's episode built by the single env (the ``builder``, reset with the
    car's generator) and loaded into the car (``CarBatch.load``).

    Made by ``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point",
    engine=..., **kwargs)`` with the single env's kwargs, plus ``max_episode_steps``,
    ``autoreset_mode`` and ``num_threads`` (worker threads stepping the physics where the
    engine uses them, an integer >= 1; default ``os.cpu_count()``). What no batch runs
    (``render_mode="human"``, ``controller_mode="sim"``; what the task's ``limits`` name:
    ``stop_speed``, any ``render_mode`` with a laser; ``randomize`` on a task that builds no
    world per episode) and differential-drive models on an engine whose batch does not take
    them (``batches_differential``) fall back to ``SmartCarLoopVectorEnv``. With
    ``randomize`` each car's robot is the builder's draw for its episode (``take_robot``: the
    body through ``CarBatch.load``, the board's track, motor and faulty encoders, the command
    latency), and ``info["randomization"]`` is every car's draw.

    ## Conventions

    As ``SmartCarSimVectorEnv`` (autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
    ``s + i``, ``info`` per car with ``_key`` masks, ``(N, 2)`` actions, ``render()`` tiles the
    first 16 cars top-down, ``reset()`` reopens a closed batch), plus ``park``. A copy
    (``copy.deepcopy``, pickle) is as a copy of the single env: the same settings and
    generators, no worlds of the original's; it is closed and its first ``reset()`` makes
    its own. The cars' public state is ``state`` (``envs.state.CarState``); what the task
    exports is read through the env (``obstacles``, ``compute_reward``, ...).
    """

    def __init__(self, env_id: str, num_envs: int = 1, max_episode_steps: int | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 num_threads: int | None = None, *, label: str | None = None,
                 **kwargs: Any) -> None:
        kwargs = id_kwargs(env_id, kwargs)
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
        make_cars = engine.car_batch
        assert make_cars is not None  # why_not said so
        task_class = get_task(kwargs["task"]).load()
        per_car = getattr(make_cars, "bytes_per_car", 0) + task_class.bytes_per_car
        self.num_envs = check_num_envs(num_envs, f"{env_id} ({name})", per_car)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        #: steps before a car's episode is truncated (None: no limit)
        self.max_episode_steps = check_max_episode_steps(max_episode_steps, env_id)
        #: the worker threads the cars' compiled loops split over (physics, laser, boards, task)
        self.threads = check_num_threads(num_threads)
        template = SmartCarEnv(**kwargs)
        try:
            if template.controller_mode != HARDWARE:
                raise ValueError(f"{self.label} is the hardware mode (PID, motors)")
            if template.robot_model.drive_kind == "differential" \
                    and not engine.batches_differential:
                raise CannotBatch(f"{self.label} runs skid-steer bases; a differential-drive "
                                  "model starts its encoders mid-tick (the vector_entry_point "
                                  "falls back to the loop)")
            template.reset(seed=0)
            self._init_from(template, make_cars(template, self.num_envs, self.threads))
        except BaseException:
            template.close()
            raise
        #: the single env that builds each car's episode (a task that builds worlds), else None
        self.builder = template if self.task.builds_worlds else None
        if self.builder is None:
            template.close()  # every car is a copy of its world
        else:
            template.task.only_build()

    @staticmethod
    def why_not(env_id: str, kwargs: dict[str, Any]) -> str | None:
        """Why this class cannot run ``env_id`` with these single-env kwargs (None: it can)."""
        entry = task_of(env_id)
        if entry is None:
            return f"{env_id} (not an id of a registered task)"
        kwargs = id_kwargs(env_id, kwargs)
        name = kwargs.get("engine", DEFAULT_ENGINE)
        if name not in engine_names():
            return f"engine={name!r}, not a registered engine"
        if get_engine(name).car_batch is None:
            return f"engine={name!r}: it has no car batch (Engine.car_batch)"
        task = get_task(kwargs.get("task", entry.name)).load()
        why = batch_limits(kwargs) or task.limits(kwargs)
        if why is None and kwargs.get("randomize") is not None and not task.builds_worlds:
            building = ", ".join(i for t in task_names() for i in get_task(t).ids
                                 if get_task(t).load().builds_worlds)
            why = (f"randomize (domain randomisation) on {env_id}: the batch varies a car as "
                   f"the single env that builds its episode draws it ({building})")
        return why

    def _init_from(self, s: SmartCarEnv, cars: CarBatch) -> None:
        """Everything per car, from the settled single env ``s`` and its copies ``cars``."""
        self._take_settings(s)
        n, robot = self.num_envs, s.robot
        #: the engine's cars (the ``CarBatch`` protocol)
        self.cars = cars
        self.period_ns = robot.update_period_ns
        self.base = BatchedArbotix(s.controller_config, HARDWARE, s.robot_model.wheel_radius_m,
                                   num_cars=n, encoder_phase_ticks=robot.encoder_phase_ticks,
                                   threads=self.threads)
        laser = self.task.laser
        self._allocate_episodes(n, len(robot.wheel_joint_indices), self.task.readings())
        #: the task's laser on every car (None: the task's cars carry none)
        self.laser = None if laser is None else BatchLaser(*laser, n)
        self.clocks = Clocks(self.state, self.base, cars, self.period_ns,
                             s.sim.max_substep_ns, self.laser, self._report_unstable)
        #: per car, its robot's draw (``info["randomization"]``; None: not varied)
        self._draws: list[dict[str, float | int] | None] = [None] * n

    def close_extras(self, **kwargs: Any) -> None:
        """Free the cars' worlds and threads, and the builder (``reset`` reopens)."""
        if self.__dict__.get("cars") is not None:
            self.cars.close()
        if self.__dict__.get("builder") is not None:
            self.builder.close()
        self._needs_reset = True

    def _reopen(self) -> None:
        """Every car a copy of the settled world again."""
        self.cars.reopen()

    def __getstate__(self) -> dict[str, Any]:
        """A copy keeps the settings, every car's generator and the settled world it was
        made from, never the cars' worlds or threads: it is closed, and its first ``reset``
        reopens it (as a copy of a single env gets a world of its own at its first reset)."""
        state = self.__dict__.copy()
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
        self.state.parked |= check_park_mask(mask, self.num_envs)

    # -- what the task sees (``tasks.base.Cars``) ------------------------------------------------
    def clearances(self, cars: np.ndarray, max_distance_m: float) -> np.ndarray:
        return self.cars.clearances(self.state.pose, max_distance_m, cars)

    # -- resets --------------------------------------------------------------------------------
    def _reset_cars(self, mask: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """The masked cars afresh: their episodes and worlds, the controller at t = 0."""
        idx = np.flatnonzero(mask)
        state, task = self.state, self.task
        state.parked[idx] = False
        if task.builds_worlds:
            self._build(idx, options)
        else:
            task.start(self, idx, options)
            self.cars.reset(idx)
        state.steps[idx] = 0
        state.previous_action[idx] = 0.0
        self.clocks.reset(idx)
        self.base.reset(0.0, self.cars.encoder_angles(), mask)
        self.cars.set_drive(mask, self.base.drive_torque, self.base.damping)
        self._read()
        task.begin(self, idx)

    def _build(self, idx: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """Each listed car's episode as its single env starts it, built by the builder with
        the car's generator and loaded into its slot."""
        b = self.builder
        for i in idx.tolist():
            b.np_random = self.rng(i)
            b.reset(options=options[i] or None)
            self.state.take(i, b.state)
            self.task.take(i, b.task)
            self.cars.load(i, b)
            self.take_robot(i, b)
            if self.laser is not None:
                self.laser.start(i, b.laser.rng)
        if self.laser is not None:  # their first scans, the builder's (it scans none)
            self.laser.scan(self.cars, self.state, idx)

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
            self.clocks.delays.pop(i, None)
        else:
            self.clocks.delays[i] = robot.command_delay

    # -- steps ---------------------------------------------------------------------------------
    def _run(self, linear_x: np.ndarray, angular_z: np.ndarray) -> None:
        self.clocks.command(linear_x, angular_z)
        self.clocks.run_period()
        self._read()

    def _read(self) -> None:
        """Every car's state from the engine and the boards: pose, odometry, wheels."""
        state = self.state
        state.up_z[:] = self.cars.read_pose(state.pose)
        self._read_odometry()
        state.wheel_position[:], state.wheel_velocity[:] = self.cars.read_wheels()

    def _report_unstable(self, found: Sequence[Warning]) -> None:
        """The engine's warnings of unstable cars, each naming the id and engine."""
        for warning in found:
            warnings.warn(f"{self.env_id} ({self.engine}): {warning}", type(warning),
                          stacklevel=5)

    def _info_values(self, success: np.ndarray) -> dict[str, Any]:
        values = self.task.info(self, success)
        draws = self._draws
        if draws[0] is not None:  # randomize: every car's, by factor
            values["randomization"] = {key: np.array([d[key] for d in draws])
                                       for key in draws[0]}
        return values
