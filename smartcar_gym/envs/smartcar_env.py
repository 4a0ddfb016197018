"""SmartCarEnv: the ROS tutorial smartcar, driven through an emulated ArbotiX base, on a task."""

from __future__ import annotations

import os
from collections.abc import Mapping
from contextlib import nullcontext
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from smartcar_gym import checks
from smartcar_gym.controller import (
    HARDWARE,
    KINEMATIC,
    MODES,
    ArbotixConfig,
)
from smartcar_gym.envs.actions import check_action
from smartcar_gym.envs.camera import draw
from smartcar_gym.envs.observation import space_and_names
from smartcar_gym.envs.randomization import Draw, Randomization
from smartcar_gym.envs.settings import (
    RenderModes,
    check_image,
    check_tick_targets,
    load_config,
    load_robot,
    max_substep,
    own_keywords,
    render_modes,
    split_keywords,
)
from smartcar_gym.envs.state import CarState, car_values
from smartcar_gym.envs.tasks.base import CarSettings, Task, runs_on_values
from smartcar_gym.envs.tasks.registry import get_task
from smartcar_gym.envs.world import World
from smartcar_gym.model import RobotModel
from smartcar_gym.model.contact import check_wheel_contact
from smartcar_gym.sim.contracts import window_of
from smartcar_gym.sim.engines import (
    DEFAULT_ENGINE,
    check_engine_keywords,
    engine_kwargs,
    engine_options,
    get_engine,
    reserve_keywords,
)

_ONE = np.zeros(1, dtype=np.int64)  # the single env's car, as a task's list of cars
#: what the env shows of its world (``envs.world.World``), by the name it shows it under
_FROM_WORLD = {"sim": "sim", "robot": "robot", "laser": "laser", "markers": "markers",
               "obstacle_bodies": "bodies"}


class SmartCarEnv(gym.Env):
    """## Description

    The smartcar of the classic ROS indigo tutorial (a 0.25 x 0.16 m box on four 25 mm wheels)
    driven like the real robot: every action is a ``cmd_vel`` Twist sent to an emulation of
    the ArbotiX ROS ``diff_controller`` (configured by ``smartcar_arbotix.yaml``), which turns
    it into wheel speeds in encoder ticks per frame, slews them by ``accel_limit``, and hands
    them to the board's integer PID, whose PWM drives one DC gearmotor per side. The robot
    sees only what the real one would: the controller's odometry (from the wheel encoders),
    the wheel joint states and its sensors. What the car is asked to do is the env's task
    (``task``: a registered task's name): its observation, reward, episode ends and ``info``
    are the task's card (docs/env.md); every id is this env on one task.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``, scaled and published as a ``geometry_msgs/Twist`` on cmd_vel:

    | Num | Action                          | Min | Max | Unit                  |
    |-----|---------------------------------|-----|-----|-----------------------|
    | 0   | linear.x  = a[0] * max_linear   | -1  | 1   | m/s after scaling     |
    | 1   | angular.z = a[1] * max_angular  | -1  | 1   | rad/s after scaling   |

    Out-of-range values are clipped to [-1, 1]. A wrong shape or a NaN/inf raises ``ValueError``.
    One step is one controller update period (``1 / rate``: 0.1 s with the shipped config): the
    command arrives, the world runs for one period, then the controller fires (odometry, 1 s
    timeout, ramp, write to the board). As on the robot, a command therefore reaches the wheels
    at the next controller update. Within the period the simulator steps the engine from event
    to event (the board's 34 ms PID frames, the controller update, the task's sensors), each
    interval in the fewest equal substeps no longer than ``max_substep_s``. A
    differential-drive ``model`` (one drive wheel per side, e.g. two wheels and a caster:
    ``robot_model.drive_kind``) has its contacts solved to convergence and its encoders start
    mid-tick, so that it drives straight; a skid base such as the smartcar is stepped as in
    0.2.0 (docs/stepping.md, "Driving straight").

    ## Starting State

    The world is rebuilt, the car is placed at the origin facing +x, left to settle for 0.1 s,
    and the controller starts: the start pose is the odometry origin. The task then draws its
    episode (the goal, obstacles) with ``self.np_random``; with ``randomize`` the robot, the
    ground and the true start pose are drawn from it too (after the task's goal).
    ``close()`` frees the simulator; a later ``reset()`` makes a new one, and so does the first
    ``reset()`` of a copy (``copy.deepcopy`` or pickle): a copy has the same settings and
    random state but a world of its own.

    ## Arguments

    | kwarg             | default        | meaning                                              |
    |-------------------|----------------|------------------------------------------------------|
    | task              | "reach"        | the registered task (``envs.tasks.registry``); its   |
    |                   |                | own keywords are the env's too (its card)            |
    | model             | shipped xacro  | .urdf / .xacro robot description                     |
    | model_args        | None           | xacro arguments for ``model`` (a dict); the shipped  |
    |                   |                | xacro takes the task's (Nav's ``laser:=true``) first |
    | package_path      | None           | folders searched for ``$(find pkg)``                 |
    | wheels            | None (auto)    | ``{"left": [joints], "right": [joints]}``            |
    | controller_config | shipped YAML   | arbotix YAML (``controllers: {..: diff_controller}``)|
    | controller_mode   | None           | "hardware" (PID, encoders, motors) or "sim"          |
    |                   |                | (kinematic, the driver's ``sim: true``); None: the   |
    |                   |                | YAML's ``sim`` key (hardware unless sim: true)       |
    | render_mode       | None           | None, "human" (a window: pybullet's GUI, MuJoCo's    |
    |                   |                | viewer; needs a display) or "rgb_array"; a MuJoCo    |
    |                   |                | env lists only "rgb_array" in ``metadata`` where its |
    |                   |                | viewer cannot open (macOS outside mjpython)          |
    | max_linear        | 0.5            | m/s for a[0] = 1                                     |
    | max_angular       | 2.0            | rad/s for a[1] = 1                                   |
    | max_substep_s     | 0.01           | longest physics substep between events (s), in       |
    |                   |                | [1e-4, 0.02]; 0.002 gives fixed 500 Hz stepping      |
    |                   |                | (planar: 0.02 by default, up to 0.05)                |
    | physics_hz        | None           | deprecated: ``max_substep_s = 1 / physics_hz``       |
    | wheel_contact     | "sphere"       | drive wheels touch the ground as spheres of their    |
    |                   |                | radius (one contact each, faster) or "urdf": the     |
    |                   |                | model's own collision shapes (cylinders)             |
    | render_width/height | 480, 360     | rgb_array image size (px, at most 4096)              |
    | randomize         | None           | domain randomisation: None (the nominal robot),      |
    |                   |                | "default" (the shipped preset), "odometry" (only     |
    |                   |                | what makes odometry drift), a dict                   |
    |                   |                | ``{factor: [low, high]}`` or a YAML file of one;     |
    |                   |                | drawn per episode (docs/sim2real.md)                 |
    | engine            | "pybullet"     | physics engine: "pybullet", "mujoco" (the ``mujoco`` |
    |                   |                | extra; docs/engines.md), "planar" (a rigid car on    |
    |                   |                | identified tyres, in arrays; docs/planar.md) or a    |
    |                   |                | registered plug-in. SmartCarSim-v0 steps no physics: |
    |                   |                | its engine only holds the body                       |
    | (an engine's own) |                | the keywords the engine declares (``Engine.kwargs``):|
    |                   |                | planar's ``planar_params`` (its fit: None, "mujoco", |
    |                   |                | a file of ``smartcar-calibrate --fit planar``, a     |
    |                   |                | dict or a ``PlanarParams``)                          |

    ## Vector envs

    ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)`` makes N
    cars in one process (docs/vector.md): SmartCarSim-v0 in numpy arrays
    (``SmartCarSimVectorEnv``), the other ids on an engine with a car batch (MuJoCo, planar:
    ``SmartCarBatchVectorEnv``, the same task object over all the cars), each bit for bit N
    single envs; elsewhere, or with what a batch lacks, N single envs in a loop
    (``SmartCarLoopVectorEnv``). Gymnasium 1.x autoreset, car i seeded ``s + i``.

    ## Version History

    * v0 (0.5.0): one env class for every id, each id a registered task (its card); the
      engine's own keywords are the engine's to declare; ``model_args`` on every id.
    * v0 (0.4.0): ``engine="planar"`` and ``planar_params``: the same car, controller and
      tasks on a planar skid-steer engine identified from pybullet, MuJoCo or a bag
      (docs/planar.md); its ``max_substep_s`` defaults to 0.02; ``render_mode="human"`` is
      pybullet's and MuJoCo's only. pybullet stays the default, its rollouts unchanged.
    * v0 (0.3.0): ``engine="mujoco"``: the same car, controller and tasks on MuJoCo
      (docs/engines.md); pybullet stays the default, its rollouts unchanged bit for bit.
      ``render_mode="human"`` opens MuJoCo's viewer. A world MuJoCo finds unstable (and resets)
      is one ``MujocoWarning`` with the car's state; nothing goes to ``MUJOCO_LOG.TXT``.
    * v0 (0.2.0): event-driven stepping (``max_substep_s``, default 0.01 s); ``physics_hz``
      deprecated. ``max_substep_s=0.002`` reproduces 0.1.0's fixed 500 Hz stepping bit for bit.
    * v0 (0.1.0): initial version.
    """

    metadata = {"render_modes": RenderModes(["human", "rgb_array"]), "render_fps": 10}
    #: the worker threads a task may split per-car work over (one car: none)
    threads = 1

    def __init__(
        self,
        model: str | os.PathLike | RobotModel | None = None,
        *,
        task: str = "reach",
        model_args: Mapping[str, Any] | None = None,
        package_path: list[str | os.PathLike] | None = None,
        wheels: dict[str, list[str]] | None = None,
        controller_config: str | os.PathLike | ArbotixConfig | None = None,
        controller_mode: str | None = None,
        render_mode: str | None = None,
        render_width: int = 480,
        render_height: int = 360,
        max_linear: float = 0.5,
        max_angular: float = 2.0,
        max_substep_s: float | None = None,
        physics_hz: float | None = None,
        wheel_contact: str = "sphere",
        randomize: str | os.PathLike | dict | Randomization | None = None,
        engine: str | None = None,
        **kwargs: Any,
    ) -> None:
        entry = get_task(task)
        task_class: type[Task] = entry.load()
        #: the id the env runs as (its task's first), in messages
        self.env_name = next(iter(entry.ids))
        refused = [k for k in kwargs if k in task_class.refused_keywords]
        if refused:
            raise TypeError(f"{self.env_name} takes no {', '.join(refused)}: "
                            f"{task_class.refused_keywords[refused[0]]}")
        given, task_kwargs = split_keywords(self.env_name, kwargs, own_keywords(
            task_class.__init__), own_keywords(SmartCarEnv.__init__))
        #: the engine's description (``sim.engines.Engine``), resolved once and passed on
        self.engine_spec = get_engine(DEFAULT_ENGINE if engine is None else engine)
        #: the engine's registered name
        self.engine = self.engine_spec.name
        spec = self.engine_spec
        self.metadata = {**self.metadata, "render_modes": render_modes(spec, render_mode)}
        checks.one_of("render_mode", render_mode, list(self.metadata["render_modes"]),
                      none_ok=True)
        check_engine_keywords(spec, given)  # another engine's keyword fails before any loading
        checks.one_of("controller_mode", controller_mode, MODES, none_ok=True)
        self.render_mode = render_mode
        self.wheel_contact = check_wheel_contact(wheel_contact)
        self.randomization = Randomization.from_spec(randomize)
        #: this episode's draw of ``randomize`` (None: the nominal robot)
        self.draw: Draw | None = None
        self.max_linear = checks.positive_number("max_linear", max_linear)
        self.max_angular = checks.positive_number("max_angular", max_angular)
        self.max_substep_s = max_substep(max_substep_s, physics_hz, spec)
        self.render_width, self.render_height = check_image(render_width, render_height)
        self.task: Task = task_class(**task_kwargs)
        self.task.label = self.env_name
        self.robot_model = load_robot(model, model_args, package_path, wheels,
                                      task_class.model_args)
        self.controller_config = load_config(
            controller_config, task_class.env_defaults.get("controller_config"))
        check_tick_targets(self.controller_config, self.max_linear, self.max_angular)
        #: the env keywords only this env's engine takes, resolved for the robot
        self.engine_options = engine_options(spec, given, self.robot_model)
        if controller_mode is None:  # as the driver: its `sim` parameter picks the mode
            controller_mode = KINEMATIC if self.controller_config.kinematic else HARDWARE
        self.controller_mode = controller_mode
        if engine is not None and controller_mode == KINEMATIC:
            gym.logger.warn(f"controller_mode='sim' (SmartCarSim-v0) steps no physics: "
                            f"engine={engine!r} only holds the kinematically moved body")
        self.metadata = {**self.metadata, "render_fps": self.controller_config.rate_hz}
        self.task.bind(CarSettings(self.robot_model, self.controller_config, controller_mode,
                                   self.max_linear, self.max_angular, self.wheel_contact,
                                   self.engine))
        self.task.attach(1)
        self._declare()
        self.world = World(spec, self.max_substep_s, self.engine_options,
                           self.robot_model, self.controller_config, controller_mode,
                           self.wheel_contact, render_mode,
                           getattr(self.task, "goal_tolerance_m", 0.1))
        self._open()
        try:
            if spec.spawn_check:
                self.world.check()
        except BaseException:  # a refused robot leaves no world behind
            self.close()
            raise
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)

    def _declare(self) -> None:
        """The car's state, the observation, its space and names."""
        #: the car's public state (one row): what the task reads and writes
        self.state = CarState.zeros(1, len(self.task.car.wheel_joints), self.task.readings())
        #: the step hooks run on the car's values (numbers), not one-row arrays
        self._on_values = runs_on_values(self.task)
        #: ``Cars.values``, chosen once (a step calls it about fifteen times)
        self.values = car_values if self._on_values else _as_is
        self.observation = self.task.observation()
        #: the observation's space, and what each value is (per key of a Dict space)
        self.observation_space, self.observation_names = space_and_names(self.observation)

    def _open(self) -> None:
        self.world.open()
        self._needs_reset = True

    # -- what the task sees (``tasks.base.Cars``) ------------------------------------------------
    def rng(self, car: int) -> np.random.Generator:
        return self.np_random

    def clearances(self, cars: np.ndarray, max_distance_m: float) -> np.ndarray:
        return np.array([self.world.clearance(max_distance_m)])

    def place_obstacles(self, car: int, obstacles: Any, pillars: bool) -> None:
        self.world.place(obstacles, pillars)

    def __getattr__(self, name: str) -> Any:
        """The world's ``sim``, ``robot``, ``laser`` (``SimulatedLaser``: ``latest`` is its last
        ``LaserScan``), ``markers`` and ``obstacle_bodies`` (what ``CarBatch.load`` reads; each
        None while closed), what the task exports (``obstacles``, ``compute_reward``, ...; a
        per-car one as this car's value) and the engines' keywords (``planar_params``: None on
        another engine), read here."""
        world = self.__dict__.get("world")
        if world is not None and name in _FROM_WORLD:
            return getattr(world, _FROM_WORLD[name])
        task = self.__dict__.get("task")
        if task is not None and name in task.exports:
            value = getattr(task, name)
            return _scalar(value[0]) if name in task.car_exports else value
        if name in engine_kwargs():  # another engine's keyword: None here
            return self.__dict__.get("engine_options", {}).get(name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def goal(self) -> np.ndarray:
        """The episode's goal (x, y) in the ``odom`` frame."""
        return self.state.goal[0]

    # -- gymnasium API -----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        with self.world.exclusive("reset"):
            super().reset(seed=seed)
            checked = self.task.check_options(options, vector=False)
            if self.world.sim is None:  # closed (or a copy): open a world of its own
                self._open()
            state, task, world = self.state, self.task, self.world
            state.steps[0] = 0
            state.previous_action[0] = 0.0
            task.start(self, _ONE, checked)
            window = window_of(world.sim)
            # a window must not draw a half-built world
            with window.building() if window is not None else nullcontext():
                self.draw = world.spawn(self.randomization, self.np_random)
                task.build(self, _ONE, checked)
                laser = task.laser
                if laser is not None:  # the laser's noise: its own generator
                    world.attach_laser(*laser, np.random.default_rng(
                        self.np_random.integers(2**63)), scan=not task.builds_only)
                world.read(state, task.needs_speed)
                if not task.builds_only:  # a batch's builder: the batch's task begins the car
                    task.begin(self, _ONE)
                if world.markers is not None:
                    world.markers.create(self.goal)
                    world.mark_odometry()
            self._needs_reset = False
            if self.render_mode == "human":
                self.render()
            return self._observe(), self._info(self.values(np.zeros(1, dtype=bool)))

    def step(self, action: np.ndarray) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        with self.world.exclusive("step"):
            self._check_ready("step")
            action = check_action(action)
            world, state, task = self.world, self.state, self.task
            robot, sim = world.robot, world.sim
            robot.cmd_vel(float(action[0]) * self.max_linear, float(action[1]) * self.max_angular)
            sim.run_until(sim.now_ns + robot.update_period_ns, physics=not robot.kinematic)
            state.steps[0] += 1
            world.read(state, task.needs_speed)
            car = self._car
            reward, success, failure = task.score(
                self, action if self._on_values else action.reshape(1, 2))
            state.previous_action[0] = action
            truncated = task.truncated(self)
            if world.markers is not None:
                world.mark_odometry()
            if self.render_mode == "human":
                self.render()
            return (self._observe(), float(car(reward)), bool(car(success) or car(failure)),
                    bool(car(truncated)), self._info(success))

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode="
                            f"'rgb_array' or 'human' to gym.make('{self.env_name}', ...)")
            return None
        self._check_ready("render")
        return draw(self.world, self.goal, self.render_mode, self.render_width,
                    self.render_height)

    def close(self) -> None:
        world = self.__dict__.get("world")
        if world is not None:
            world.close()

    # -- copies --------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """A copy keeps settings and random state, never this env's world."""
        state = self.__dict__.copy()
        state["world"], state["_needs_reset"] = self.world.detached(), True
        return state

    # -- helpers -------------------------------------------------------------------------------
    def _check_ready(self, call: str) -> None:
        if self.world.sim is None:
            raise RuntimeError(f"SmartCarEnv is closed: call reset() to reopen it before {call}()")
        if self._needs_reset:
            raise ResetNeeded(f"SmartCarEnv: call reset() before {call}()")

    def _car(self, value: Any) -> Any:
        """The car's value of what a step hook gave (its row 0, unless on values)."""
        return value if self._on_values else value[0]

    def _observe(self) -> Any:
        obs = self.task.observe(self)
        if isinstance(obs, dict):
            return {key: self._car(value) for key, value in obs.items()}
        return self._car(obs)

    def _info(self, success: np.ndarray) -> dict[str, Any]:
        info = {key: _scalar(self._car(value))
                for key, value in self.task.info(self, success).items()}
        if self.draw is not None:
            info["randomization"] = self.draw.info
        return info


# no engine may declare one of the env's own keywords as its own (it would never reach it)
reserve_keywords("SmartCarEnv", own_keywords(SmartCarEnv.__init__))


def _scalar(value: Any) -> Any:
    """A car's value as the single env gives it: numbers as Python's, arrays as they are."""
    return value.item() if isinstance(value, np.generic) else value


def _as_is(array: np.ndarray) -> np.ndarray:
    """A per-car array as a task written over arrays sees it in a single env: itself."""
    return array
