"""SmartCar-v0: drive the ROS tutorial smartcar to a goal through an emulated ArbotiX base."""

from __future__ import annotations

import math
import os
import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext
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
    load_controller_config,
)
from smartcar_gym.envs.observation import Entry, Observation, Readings
from smartcar_gym.envs.randomization import Draw, Randomization
from smartcar_gym.envs.robots.entries import robot_entries
from smartcar_gym.envs.robots.smartcar import Pose2D, SmartCarRobot
from smartcar_gym.envs.tasks.reach import GoalReachingTask
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.model.contact import check_wheel_contact
from smartcar_gym.sim.clock import check_max_substep
from smartcar_gym.sim.contracts import Simulator, window_of
from smartcar_gym.sim.engines import (
    DEFAULT_ENGINE,
    check_engine,
    default_max_substep,
    engine_options,
    get_engine,
    make_simulator,
    substep_range,
    window_unavailable,
)
from smartcar_gym.sim.markers import SceneMarkers

MAX_RENDER_PX = 4096  # 8000 x 8000 took 2.4 GB and minutes per frame
#: the rows of SmartCar-v0's observation, in order (entries come from robot, task and env)
OBSERVATION_ORDER = (
    "odom_position", "odom_heading", "odom_linear", "odom_angular", "wheel_positions",
    "wheel_velocities", "goal_base", "goal_distance", "previous_action", "goal_odom",
)


class RenderModes(list):
    """The render modes, as ``metadata["render_modes"]`` lists them.

    ``gymnasium.make`` calls string methods on a ``render_mode`` it does not find in this list
    (``render_mode=1`` died with an AttributeError inside gymnasium); a value that is not a
    string is let through so that the env refuses it with a message naming it.
    """

    def __contains__(self, item: object) -> bool:
        return not isinstance(item, str) or super().__contains__(item)


def previous_action_entry() -> Entry:
    """The action of the previous step (zeros after reset), as the agent sent it."""
    return Entry("previous_action", ("prev_linear", "prev_angular"), -1.0, 1.0, "",
                 "previous action", lambda r: r.previous_action)


def observed_wheels(model: RobotModel) -> list[str]:
    """The wheel joints in observation order: left then right, each as the model lists them."""
    return [w.joint for w in model.left_wheels + model.right_wheels]


def declare_observation(wheel_joints: Sequence[str], task: GoalReachingTask) -> Observation:
    """SmartCar-v0's observation: robot, task and action entries in ``OBSERVATION_ORDER``.

    It needs no simulator, so the ROS policy node declares the env's very observation.
    """
    return Observation.compose(
        OBSERVATION_ORDER,
        robot_entries(wheel_joints, 2 * task.arena_half_size_m),
        task.observation_entries(),
        [previous_action_entry()],
    )


class SmartCarEnv(gym.Env):
    """## Description

    The smartcar of the classic ROS indigo tutorial (a 0.25 x 0.16 m box on four 25 mm wheels)
    in pybullet, driven like the real robot: every action is a ``cmd_vel`` Twist sent to an
    emulation of the ArbotiX ROS ``diff_controller`` (configured by ``smartcar_arbotix.yaml``),
    which turns it into wheel speeds in encoder ticks per frame, slews them by ``accel_limit``,
    and hands them to the board's integer PID, whose PWM drives one DC gearmotor per side.
    The robot sees only what the real one would: the controller's odometry (from the wheel
    encoders) and the wheel joint states. The task is to reach a goal on the ground.

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
    at the next controller update. Within the period the simulator steps pybullet from event to
    event (the board's 34 ms PID frames, the controller update), each interval in the fewest
    equal substeps no longer than ``max_substep_s``. A differential-drive ``model`` (one drive
    wheel per side, e.g. two wheels and a caster: ``robot_model.drive_kind``) has its contacts
    solved to convergence and its encoders start mid-tick, so that it drives straight; a skid
    base such as the smartcar is stepped as in 0.2.0 (docs/stepping.md, "Driving straight").

    ## Observation Space

    ``Box(low, high, (21,), float32)`` with finite bounds (values are clipped into them):

    {observation_table}

    where A = ``arena_size / 2``. Wheels are listed left then right, front then back, as the
    model's wheels are found (``env.unwrapped.observation_names`` names every entry, e.g.
    ``left_back_wheel_joint.velocity``); ``info`` has nothing the observation needs.

    ## Rewards

    ``10 * (d_prev - d) - 0.01 - 0.01 * |a|^2``, plus ``+10`` on reaching the goal and ``-10``
    on flipping over or leaving the arena, where d is the ground-truth distance (m) from
    base_link to the goal. With ``stop_speed`` the +10 needs the car at rest (below), each
    step within ``goal_tolerance`` also costs ``1.0 * |v|`` (the true speed, m/s) and each
    step ``20 * (e - e_prev)``, e the odometry's distance (m) from the truth.

    ## Starting State

    The world is rebuilt (``resetSimulation``), the car is placed at the origin facing +x, left
    to settle for 0.1 s, and the controller starts: the start pose is the odometry origin. The
    goal is drawn with ``self.np_random`` at a uniform distance in ``goal_range`` and a uniform
    bearing. ``reset(options={"goal": (x, y)})`` sets it instead (the only option). With
    ``randomize``, the robot, the ground and the true start pose are then drawn from
    ``self.np_random`` (after the goal: the goals are the nominal env's for the same seed).
    ``close()`` disconnects the pybullet client; a later ``reset()`` connects a new one, and so
    does the first ``reset()`` of a copy (``copy.deepcopy`` or pickle): a copy has the same
    settings and random state but a world of its own.

    ## Episode End

    Terminated when the ground-truth distance is under ``goal_tolerance`` (success; with
    ``stop_speed`` the odometry's distance too, and the true speed of base_link under
    ``stop_speed``: at rest), when the
    car flips over (base_link z axis tilted more than 60 degrees) or when it leaves the square
    arena. Truncated by the ``TimeLimit`` (200 steps = 20 s for SmartCar-v0).

    ``info``: ``is_success`` (bool), ``distance`` (ground truth, m), ``pose`` (ground-truth
    x, y, yaw), ``odom_pose`` (odometry x, y, yaw), ``odom_error`` (m between the two), and
    with ``randomize`` ``randomization``: this episode's draw (factor -> value, ``noise_seed``).

    ## Arguments

    | kwarg             | default        | meaning                                              |
    |-------------------|----------------|------------------------------------------------------|
    | model             | shipped xacro  | .urdf / .xacro robot description                     |
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
    | goal_range        | (0.5, 1.5)     | min, max goal distance from the start (m)            |
    | goal_tolerance    | 0.1            | success radius (m)                                   |
    | arena_size        | 5.0            | side of the square arena centred on the start (m)    |
    | stop_speed        | None           | m/s: success only at rest (speed under this) inside  |
    |                   |                | the tolerance; None: on entering it (docs/ros.md)    |
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
    |                   |                | extra; docs/engines.md) or "planar" (a rigid car on  |
    |                   |                | identified tyres, in arrays; docs/planar.md).        |
    |                   |                | SmartCarSim-v0 steps no physics: its engine only     |
    |                   |                | holds the body                                       |
    | planar_params     | None           | engine="planar"'s parameters: None (the shipped fit  |
    |                   |                | to pybullet for the shipped smartcar: the shipped    |
    |                   |                | xacro, any xacro args, or a copy of it; neutral      |
    |                   |                | built-in values for any other ``model``), "mujoco"   |
    |                   |                | (the fit to MuJoCo), a file of ``smartcar-calibrate  |
    |                   |                | --fit planar``, a dict or a ``PlanarParams``         |

    ## Vector envs

    ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)`` makes N
    cars in one process (docs/vector.md): SmartCarSim-v0 in numpy arrays
    (``SmartCarSimVectorEnv``, bit for bit N single envs but for ``info["pose"]``'s yaw,
    within 1e-6 rad), SmartCar-v0, SmartCarNav-v0 and SmartCarGoal-v0 on an engine with a car
    batch (``SmartCarBatchVectorEnv``, bit for bit N single envs, infos included: MuJoCo's
    worlds in C, the planar engine's cars in arrays, differential-drive robots too on
    planar; ``randomize`` on the Nav and BARN ids), on pybullet or with what the batches lack
    (``randomize`` here, ``stop_speed``, the GUI, a differential-drive ``model`` on MuJoCo) as N
    single envs in a loop (``SmartCarLoopVectorEnv``). Gymnasium 1.x autoreset
    (``"NextStep"``, or ``autoreset_mode="SameStep"``), car i seeded ``s + i``,
    ``info["is_success"]`` per car.

    ## Version History

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
    #: the keys ``reset(options=...)`` accepts, and the env's name in messages (subclasses add)
    reset_options: tuple[str, ...] = ("goal",)
    env_name = "SmartCar-v0"

    @checks.keyword_checked  # max_linar=: "... (did you mean 'max_linear'?)", via gym.make too
    def __init__(
        self,
        model: str | os.PathLike | RobotModel | None = None,
        controller_config: str | os.PathLike | ArbotixConfig | None = None,
        controller_mode: str | None = None,
        render_mode: str | None = None,
        max_linear: float = 0.5,
        max_angular: float = 2.0,
        goal_range: tuple[float, float] = (0.5, 1.5),
        goal_tolerance: float = 0.1,
        arena_size: float = 5.0,
        max_substep_s: float | None = None,
        physics_hz: float | None = None,
        package_path: list[str | os.PathLike] | None = None,
        wheels: dict[str, list[str]] | None = None,
        render_width: int = 480,
        render_height: int = 360,
        wheel_contact: str = "sphere",
        randomize: str | os.PathLike | dict | Randomization | None = None,
        engine: str | None = None,
        stop_speed: float | None = None,
        planar_params: str | os.PathLike | dict | Any | None = None,
    ) -> None:
        self.engine = DEFAULT_ENGINE if engine is None else check_engine(engine)
        self.metadata = {**self.metadata, "render_modes": self._render_modes(render_mode)}
        checks.one_of("render_mode", render_mode, list(self.metadata["render_modes"]),
                      none_ok=True)
        #: the env keywords only this env's engine takes, checked (resolved for the robot
        #: once it is loaded, below: ``Engine.kwargs``); a keyword of another engine's is refused
        given = {"planar_params": planar_params}
        self.engine_options = engine_options(self.engine, given)
        checks.one_of("controller_mode", controller_mode, MODES, none_ok=True)
        self.render_mode = render_mode
        self.wheel_contact = check_wheel_contact(wheel_contact)
        self.randomization = Randomization.from_spec(randomize)
        #: this episode's draw of ``randomize`` (None: the nominal robot)
        self.draw: Draw | None = None
        self.max_linear = checks.positive_number("max_linear", max_linear)
        self.max_angular = checks.positive_number("max_angular", max_angular)
        half = checks.positive_number("arena_size", arena_size) / 2.0
        self.max_substep_s = self._substep(max_substep_s, physics_hz, self.engine)
        size = f"rgb_array images are at most {MAX_RENDER_PX} px a side"
        self.render_width = checks.positive_int("render_width", render_width, MAX_RENDER_PX, size)
        self.render_height = checks.positive_int("render_height", render_height, MAX_RENDER_PX,
                                                 size)
        self.task = GoalReachingTask(
            goal_range_m=checks.number_pair("goal_range", goal_range),
            goal_tolerance_m=checks.positive_number("goal_tolerance", goal_tolerance),
            arena_half_size_m=half,
            stop_speed_m_s=(None if stop_speed is None
                            else checks.positive_number("stop_speed", stop_speed)),
        )
        model = checks.source("model", model, RobotModel)
        controller_config = checks.source("controller_config", controller_config, ArbotixConfig)
        self.robot_model = (
            model if isinstance(model, RobotModel)
            else load_model(model, package_path=package_path, wheels=wheels)
        )
        self.controller_config = (
            controller_config if isinstance(controller_config, ArbotixConfig)
            else load_controller_config(controller_config)
        )
        self._check_tick_targets()
        self.engine_options = engine_options(self.engine, given, self.robot_model)
        if controller_mode is None:  # as the driver: its `sim` parameter picks the mode
            controller_mode = KINEMATIC if self.controller_config.kinematic else HARDWARE
        self.controller_mode = controller_mode
        if engine is not None and controller_mode == KINEMATIC:
            gym.logger.warn(f"controller_mode='sim' (SmartCarSim-v0) steps no physics: "
                            f"engine={engine!r} only holds the kinematically moved body")
        self.metadata = {**self.metadata, "render_fps": self.controller_config.rate_hz}

        self.sim: Simulator | None = None
        self._open()
        try:
            if get_engine(self.engine).spawn_check:
                self._check_car()
            self.observation = self._declare_observation()
        except BaseException:  # a refused robot leaves no world behind
            self.close()
            raise
        #: what each observation entry is, in order (wheels as found: left then right)
        self.observation_names: tuple[str, ...] = self.observation.names
        self.observation_space = self.observation.space
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.goal = np.zeros(2)
        self._distance = 0.0
        self._odometry_error = 0.0
        self._prev_action = np.zeros(2, dtype=np.float32)

    @property
    def planar_params(self) -> Any:
        """The planar engine's free parameters (``sim.planar.params.PlanarParams``; None on an
        engine that does not take ``planar_params``)."""
        return self.engine_options.get("planar_params")

    def _render_modes(self, render_mode: Any) -> RenderModes:
        """The modes this env's engine supports here: without a window (MuJoCo's viewer on
        macOS outside mjpython), only "rgb_array"; asking for "human" then says why."""
        why = window_unavailable(self.engine)
        if why is None:
            return RenderModes(["human", "rgb_array"])
        if render_mode == "human":
            raise ValueError(f"render_mode='human' is not available with engine="
                             f"{self.engine!r} here: {why}; use render_mode='rgb_array'")
        return RenderModes(["rgb_array"])

    def _declare_observation(self) -> Observation:
        """Robot, task and action entries in ``OBSERVATION_ORDER``."""
        return declare_observation(observed_wheels(self.robot_model), self.task)

    @staticmethod
    def _substep(max_substep_s: float | None, physics_hz: float | None,
                 engine: str = DEFAULT_ENGINE) -> float:
        if physics_hz is None:
            if max_substep_s is None:
                return default_max_substep(engine)
            return check_max_substep(max_substep_s, allowed=substep_range(engine))
        if max_substep_s is not None:
            raise ValueError(
                f"pass max_substep_s or physics_hz, not both (got max_substep_s={max_substep_s!r}, "
                f"physics_hz={physics_hz!r}); physics_hz is deprecated"
            )
        hz = checks.positive_number("physics_hz", physics_hz)
        substep = check_max_substep(1.0 / hz, f"1 / physics_hz (physics_hz={physics_hz!r})")
        warnings.warn(
            f"physics_hz is deprecated: the simulator steps from event to event; pass "
            f"max_substep_s={substep:g} instead", DeprecationWarning, stacklevel=3,
        )
        return substep

    def _check_tick_targets(self) -> None:
        """Refuse speeds whose wheel targets overflow the board's 16-bit ticks per frame."""
        config = self.controller_config
        wheel_speed = self.max_linear + self.max_angular * config.base_width_m / 2.0
        limit = config.max_target_speed_m_s
        if wheel_speed > limit:
            raise ValueError(
                f"max_linear={self.max_linear} and max_angular={self.max_angular} ask a wheel for "
                f"{wheel_speed:g} m/s, but with ticks_meter {config.ticks_meter:g} "
                f"({config.source}) the board's 16-bit target holds at most {limit:g} m/s"
            )

    def _open(self) -> None:
        """Connect a fresh simulator (its own world) with the robot and the markers."""
        self.sim = make_simulator(self.engine, max_substep_s=self.max_substep_s,
                                  gui=self.render_mode == "human",
                                  draws=self.render_mode is not None, **self.engine_options)
        self.robot = SmartCarRobot(
            self.sim, self.robot_model, self.controller_config, mode=self.controller_mode,
            wheel_contact=self.wheel_contact,
        )
        self.markers = (
            SceneMarkers(self.sim, self.task.goal_tolerance_m) if self.render_mode is not None
            else None
        )
        self._needs_reset = True

    def _check_car(self) -> None:
        """Spawn the robot once in a scratch world (an engine with ``spawn_check``) and step
        it once, so that a car the engine cannot run (the planar engine: it would tip over,
        too few ground contacts) is refused by ``gym.make`` in one line (ModelError), not at
        the first reset."""
        sim = make_simulator(self.engine, max_substep_s=self.max_substep_s,
                             **self.engine_options)
        try:
            robot = SmartCarRobot(sim, self.robot_model, self.controller_config,
                                  mode=self.controller_mode, wheel_contact=self.wheel_contact)
            robot.spawn(settle_s=0.0)
            sim.run_until(sim.now_ns + sim.max_substep_ns)
        finally:
            sim.close()

    # -- gymnasium API -----------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        with self._exclusive("reset"):
            super().reset(seed=seed)
            goal = self._check_options(options)
            if self.sim is None:  # closed (or a copy): open a world of its own
                self._open()
            if goal is None:
                goal = self.task.sample_goal(self.np_random, np.zeros(2))
            window = window_of(self.sim)
            # a window must not draw a half-built world
            with window.building() if window is not None else nullcontext():
                self.sim.reset()
                start = (0.0, 0.0, 0.0)
                if self.randomization is not None:
                    self.draw = self.randomization.apply(self.np_random, self.sim, self.robot)
                    start = self.draw.start_pose
                self.robot.spawn(*start)
                self.goal = goal
                self._build_world()
                self._prev_action = np.zeros(2, dtype=np.float32)
                pose = self.robot.pose()
                self._distance = float(self.task.distance(np.array([pose.x, pose.y]), self.goal))
                odom = self.robot.odometry
                self._odometry_error = math.hypot(odom.x - pose.x, odom.y - pose.y)
                if self.markers is not None:
                    self.markers.create(self.goal)
                    self._mark_odometry()
            self._needs_reset = False
            if self.render_mode == "human":
                self.render()
            return self._observe(), self._info(pose, False)

    def _check_options(self, options: Any) -> np.ndarray | None:
        """``reset``'s options, checked before the world is rebuilt; the goal if one is given."""
        if options is None:
            return None
        if not isinstance(options, dict):
            raise TypeError(
                f"reset options must be a dict such as {{'goal': (x, y)}}, got "
                f"{type(options).__name__}: {options!r}"
            )
        unknown = set(options) - set(self.reset_options)
        if unknown:
            raise ValueError(f"unknown reset option(s) {sorted(unknown, key=str)}; "
                             f"{self.env_name} takes {', '.join(map(repr, self.reset_options))}")
        return self.task.check_goal(options["goal"]) if "goal" in options else None

    def _build_world(self) -> None:
        """Extension hook: ``reset`` calls it once the robot is spawned and ``self.goal`` chosen,
        before the first observation; subclasses add bodies and sensors here (and may move
        the goal). SmartCar-v0 adds nothing."""

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        with self._exclusive("step"):
            self._check_ready("step")
            action = self._validate_action(action)
            self.robot.cmd_vel(float(action[0]) * self.max_linear,
                               float(action[1]) * self.max_angular)
            self.sim.run_until(self.sim.now_ns + self.robot.update_period_ns,
                               physics=not self.robot.kinematic)
            pose = self.robot.pose()
            arrival = ()
            if self.task.stop_speed_m_s is not None:  # true planar speed, odometry
                (vx, vy, _), _ = self.robot.body.velocity()
                odom = self.robot.odometry
                arrival = (math.hypot(vx, vy), (odom.x, odom.y), self._odometry_error)
            outcome = self.task.evaluate(self._distance, np.array([pose.x, pose.y]), pose.up_z,
                                         self.goal, action, *arrival)
            self._distance = outcome.distance
            self._odometry_error = outcome.odometry_error
            self._prev_action = action.astype(np.float32)
            if self.markers is not None:
                self._mark_odometry()
            if self.render_mode == "human":
                self.render()
            terminated = outcome.success or outcome.failure
            return (self._observe(), outcome.reward, terminated, False,
                    self._info(pose, outcome.success))

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array' or 'human' "
                "to gym.make('SmartCar-v0', ...)"
            )
            return None
        self._check_ready("render")
        self.markers.draw()
        pose = self.robot.pose()
        target = (np.array([pose.x, pose.y]) + self.goal) / 2.0
        span = float(np.linalg.norm(self.goal - np.array([pose.x, pose.y])))
        distance = max(0.9, 1.1 * span + 0.5)
        target3 = (float(target[0]), float(target[1]), 0.0)
        if self.render_mode == "human":
            self._show(target3, distance, -60.0)
            return None
        return self.sim.render(
            self.render_width, self.render_height, target3, distance, yaw_deg=0.0, pitch_deg=-60.0
        )

    def _show(self, target: Sequence[float], distance: float, pitch_deg: float) -> None:
        """Point the window's camera (``render_mode="human"``), looking north."""
        window = window_of(self.sim)
        if window is not None:
            window.point_gui_camera(target, distance, yaw_deg=0.0, pitch_deg=pitch_deg)

    def close(self) -> None:
        if getattr(self, "sim", None) is not None:
            self.sim.close()
            self.sim = None

    # -- copies --------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """A copy keeps settings and random state, never this env's pybullet world."""
        state = self.__dict__.copy()
        for key in ("sim", "robot", "markers", "_lock", "observation"):  # world; lambdas
            state.pop(key, None)
        state["sim"] = None
        state["_needs_reset"] = True
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.observation = self._declare_observation()

    # -- helpers -------------------------------------------------------------------------------
    @contextmanager
    def _exclusive(self, call: str) -> Iterator[None]:
        """One thread at a time: a second one gets a clear error, not a corrupted world."""
        lock = self.__dict__.setdefault("_lock", threading.Lock())
        if not lock.acquire(blocking=False):
            raise RuntimeError(
                f"SmartCarEnv.{call}() called while another thread is inside this env: an env "
                "is one simulated world and is not thread-safe; give each thread its own env "
                "(gym.make_vec with vectorization_mode='async' runs envs in parallel)"
            )
        try:
            yield
        finally:
            lock.release()

    def _check_ready(self, call: str) -> None:
        if self.sim is None:
            raise RuntimeError(f"SmartCarEnv is closed: call reset() to reopen it before {call}()")
        if self._needs_reset:
            raise ResetNeeded(f"SmartCarEnv: call reset() before {call}()")

    def _validate_action(self, action: Any) -> np.ndarray:
        if type(action) is np.ndarray and action.shape == (2,) and action.dtype.kind == "f":
            a0, a1 = float(action[0]), float(action[1])  # the usual case, in a few microseconds
            if math.isfinite(a0) and math.isfinite(a1):
                return np.array([min(max(a0, -1.0), 1.0), min(max(a1, -1.0), 1.0)])
        if np.iscomplexobj(action):
            raise ValueError(f"action must be real numbers, got {np.asarray(action).tolist()}")
        try:
            arr = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise ValueError(f"action must be 2 numbers (linear, angular), got {action!r}") from err
        if arr.shape != (2,):
            raise ValueError(
                f"action must have shape (2,) (linear, angular), got shape {arr.shape}: {action!r}"
            )
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"action must be finite, got {arr.tolist()}")
        return np.clip(arr, -1.0, 1.0)

    def _mark_odometry(self) -> None:
        odom = self.robot.odometry
        self.markers.add_pose(odom.x, odom.y, odom.theta)

    def readings(self) -> Readings:
        """What the robot knows now (odometry, wheel joint states), the goal and last action."""
        position, velocity = self.robot.body.joint_lists(self.robot.wheel_joint_indices)
        return Readings(self.robot.odometry, position, velocity, self.goal.tolist(),
                        self._prev_action.tolist())

    def _observe(self) -> np.ndarray:
        return self.observation.build(self.readings())

    def _info(self, pose: Pose2D, success: bool) -> dict[str, Any]:
        odom = self.robot.odometry
        dx, dy = odom.x - pose.x, odom.y - pose.y
        info = {
            "is_success": success,
            "distance": self._distance,
            "pose": np.array([pose.x, pose.y, pose.yaw]),
            # odometry's theta is never wrapped (as upstream); here it is, like pose's yaw
            "odom_pose": np.array([odom.x, odom.y, math.remainder(odom.theta, 2 * math.pi)]),
            # sqrt(dx * dx + dy * dy), not math.hypot: a batch of cars gets the same bits from
            # numpy (np.hypot and math.hypot differ in the last bit; vector/exact.py)
            "odom_error": math.sqrt(dx * dx + dy * dy),
        }
        if self.draw is not None:
            info["randomization"] = self.draw.info
        return info


def _doc_table() -> str:
    """SmartCar-v0's observation table as its docstring shows it (the shipped four wheels)."""
    observation = declare_observation(["lf", "lb", "rf", "rb"], GoalReachingTask())
    return observation.table().replace("\n", "\n    ")


SmartCarEnv.__doc__ = SmartCarEnv.__doc__.replace("{observation_table}", _doc_table())
