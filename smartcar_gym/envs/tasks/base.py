"""What a task is: one class, written once over the cars' state, for any number of cars.

A single env runs its task over one car, a batched env over N; both call the same methods at
the same points of ``reset`` and ``step``, so a car of the batch is its single env bit for bit
by construction. A task keeps its settings (its keywords) and its per-car numbers (arrays,
first axis the car); it reads and writes the cars' public state (``envs.state.CarState``)
through ``Cars``, the env it runs in.

The order of a reset, for the cars ``idx`` (``idx`` is an int array):

1. ``check_options``: the reset options, checked before anything is touched;
2. ``start``: the episode's draws before the car is spawned (the goal, BARN's world);
3. the env spawns each car (and draws its robot with ``randomize``);
4. ``build``: what the world holds this episode (obstacles), a single env's only: a batched
   env builds a ``builds_worlds`` task's episodes with a single env of the task (its builder)
   and copies each into a car with ``take``;
5. the env attaches the sensors the task declares (``laser``) and reads the state;
6. ``begin``: the task's numbers at the start (distances, clearances, waypoints).

A step: the env sends each car's action, runs the period and reads the state, then
``score`` (reward, success, failure), ``truncated``, ``observe`` and ``info``. Tasks are
registered by name (``envs.tasks.registry``), each with the ids made from it.

The step hooks read the cars' per-car arrays (the state's, and the task's own) through
``Cars.values``. A hook written so that it works on what that gives whether it is arrays over
the cars or one car's values (``envs.state.car_values``: Python numbers of an (N,) field, a
numpy row of an (N, k) one; unpack a row's columns with ``envs.state.split``, reduce it with
``axis=-1``, write the task's arrays with ``a[...] = value``, copy what ``info`` hands out with
``envs.state.copied``) says so with ``@one_or_many``; a single env whose task's step hooks all
say so runs them on its car's values, in about a third of the time they take on one-row arrays
(numpy's cost per call). Otherwise every hook sees one-row arrays in a single env: a task may
be written over arrays alone. Either way the numbers are the same bit for bit: Python's and
numpy's float arithmetic and square root are IEEE's (where numpy's function is not libm's,
``np.hypot``, a hook calls numpy's on numbers too).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from smartcar_gym.envs.observation import Observation
from smartcar_gym.envs.state import SCAN, SCAN_TIME, CarState
from smartcar_gym.sim.clock import seconds_to_ns

if TYPE_CHECKING:
    from smartcar_gym.controller import ArbotixConfig
    from smartcar_gym.envs.sensors.scan import LaserConfig
    from smartcar_gym.envs.tasks.obstacles import Obstacle
    from smartcar_gym.model import RobotModel

#: reward, success and failure of every car after a step
Score = tuple[np.ndarray, np.ndarray, np.ndarray]
#: the hooks a step calls, which ``Cars.values`` serves
STEP_HOOKS = ("score", "truncated", "columns", "observe", "info")


def one_or_many(hook: Any) -> Any:
    """Mark a step hook as written for one car's values as well as for arrays of cars (the
    module says how)."""
    hook.one_or_many = True
    return hook


def runs_on_values(task: Task) -> bool:
    """Whether every step hook of ``task`` is ``one_or_many``: a single env then hands them
    its car's values (``Cars.values``) instead of one-row arrays."""
    return all(getattr(getattr(type(task), name), "one_or_many", False) for name in STEP_HOOKS)


@dataclass(frozen=True)
class CarSettings:
    """What a task may know of the car it runs on: the robot, its controller and the scale
    of its actions (``bind``)."""

    robot_model: RobotModel
    controller_config: ArbotixConfig
    controller_mode: str
    max_linear: float
    max_angular: float
    wheel_contact: str
    engine: str

    @property
    def period_s(self) -> float:
        """One step: the controller's update period (s, from its whole ns)."""
        return seconds_to_ns(1.0 / self.controller_config.rate_hz) * 1e-9

    @property
    def wheel_joints(self) -> list[str]:
        """The wheel joints in observation order: left then right, each as the model lists
        them."""
        model = self.robot_model
        return [w.joint for w in model.left_wheels + model.right_wheels]


class Cars(Protocol):
    """The env a task runs in, as the task sees it: the cars' state and what only the engine
    can answer."""

    #: every car's state (one row a car)
    state: CarState
    #: the worker threads a task may split per-car work over (``parallel.run_chunks``)
    threads: int

    def rng(self, car: int) -> np.random.Generator:
        """Car ``car``'s generator (the single env's ``np_random``)."""

    def values(self, array: np.ndarray) -> Any:
        """A per-car array (the state's or the task's) as the step hooks see it: the array,
        or in a single env whose task ``runs_on_values`` its one car's value (row 0: a Python
        number of an (N,) array, a numpy row of an (N, k) one)."""

    def clearances(self, cars: np.ndarray, max_distance_m: float) -> np.ndarray:
        """(K,): each listed car's ground-truth distance (m) to its nearest obstacle, at most
        ``max_distance_m``; <= 0 where they touch."""

    def place_obstacles(self, car: int, obstacles: tuple[Obstacle, ...],
                        pillars: bool) -> None:
        """Put ``obstacles`` into car ``car``'s world (a single env's ``build``)."""


#: one car's reset options when none were given: empty and read-only, so that every car of a
#: batch can share it (an autoreset of many cars then makes no dict a car)
NO_OPTIONS: Mapping[str, Any] = MappingProxyType({})


def no_options(n: int) -> tuple[Mapping[str, Any], ...]:
    """The options of ``n`` cars reset with none (``Task.start``'s ``options``)."""
    return (NO_OPTIONS,) * n


class Task:
    """One task over N cars (see the module). Subclasses set the class attributes below and
    override the hooks they need; every hook's default does nothing."""

    #: the keys ``reset(options=...)`` accepts
    option_keys: ClassVar[tuple[str, ...]] = ()
    #: each episode builds a world of its own (obstacles): a batched env builds each car's
    #: episode with a single env of the task and copies it (``take``)
    builds_worlds: ClassVar[bool] = False
    #: the per-car attributes (first axis: the car) ``take`` copies from a builder's car
    per_car: ClassVar[tuple[str, ...]] = ()
    #: attributes an env shows as its own (``env.unwrapped.obstacles``, ``compute_reward``)
    exports: ClassVar[tuple[str, ...]] = ()
    #: the per-car ones among them, which a single env shows as its car's value
    car_exports: ClassVar[tuple[str, ...]] = ()
    #: whether the task reads the state's ``speed`` (the env reads it only then)
    needs_speed: ClassVar[bool] = False
    #: env keywords whose defaults the task changes (``controller_config``, ...)
    env_defaults: ClassVar[Mapping[str, Any]] = {}
    #: xacro arguments of the task's default robot (the shipped xacro's ``laser:=true``)
    model_args: ClassVar[Mapping[str, str]] = {}
    #: env keywords the task refuses, each with the reason (BARN's protocol sets the goal)
    refused_keywords: ClassVar[Mapping[str, str]] = {}
    #: memory the task holds per car (bytes), for a batched env's check of ``num_envs``
    bytes_per_car: ClassVar[int] = 0

    #: the id the task runs as, in its messages (set by the env)
    label = "the task"
    #: a batch's builder's task (``only_build``): its env's reset builds and begins nothing
    builds_only = False
    #: the car it runs on (``bind``)
    car: CarSettings
    #: how many cars it runs on (``attach``)
    num = 0

    # -- settings ------------------------------------------------------------------------------
    @property
    def laser(self) -> tuple[LaserConfig, np.ndarray] | None:
        """The laser the task's cars carry: its config and its base_link -> laser mount (4x4);
        None: none."""
        return None

    def readings(self) -> dict[str, tuple[tuple[int, ...], Any]]:
        """The sensors' readings in the cars' state, each a car's shape and dtype: the laser's
        ranges and their time (``envs.state``), none without a laser."""
        laser = self.laser
        if laser is None:
            return {}
        return {SCAN: ((laser[0].beams,), np.float32), SCAN_TIME: ((), np.int64)}

    def bind(self, car: CarSettings) -> None:
        """Learn the car the task runs on (called once, before ``observation``)."""
        self.car = car

    def observation(self) -> Observation | dict[str, Observation]:
        """The observation's entries (a dict of them for a ``Dict`` space), declared once."""
        declared = self.__dict__.get("_declared")
        if declared is None:
            declared = self._declared = self.declare()
        return declared

    def declare(self) -> Observation | dict[str, Observation]:
        """The observation's entries, for the car the task is bound to."""
        raise NotImplementedError

    @staticmethod
    def limits(kwargs: Mapping[str, Any]) -> str | None:
        """What of the env's keywords a batched env cannot run with this task (None:
        nothing)."""
        return None

    # -- cars ----------------------------------------------------------------------------------
    def attach(self, num: int) -> None:
        """The per-car numbers for ``num`` cars (subclasses add theirs, then call this)."""
        self.num = num

    def for_cars(self, num: int) -> Task:
        """A copy of this task (its settings) with per-car numbers for ``num`` cars."""
        task = copy.copy(self)
        task.attach(num)
        return task

    def take(self, car: int, builder: Task) -> None:
        """Car ``car``'s episode becomes the one ``builder`` (the same task in a single env)
        has just built for its car: every ``per_car`` attribute's row."""
        for name in self.per_car:
            getattr(self, name)[car] = getattr(builder, name)[0]

    def only_build(self) -> None:
        """This task now serves a batch's builder: its episodes are copied (``take``) and
        begun by the batch's own task, so its env's reset skips ``begin`` (``builds_only``)
        and what only a run needs may go (a laser map's grids and planning)."""
        self.builds_only = True

    # -- reset ---------------------------------------------------------------------------------
    def check_options(self, options: Any, vector: bool) -> list[Mapping[str, Any]]:
        """``reset``'s options checked (before anything is touched), one mapping per car
        (``NO_OPTIONS`` for each where none were given): ``vector`` says whether they are a
        vector env's (``num`` cars; values may be per car)."""
        if options is None:
            return list(no_options(self.num))
        if not isinstance(options, Mapping):
            raise TypeError(f"reset options must be a dict of {self.options_help()}, got "
                            f"{type(options).__name__}: {options!r}")
        unknown = set(options) - set(self.option_keys)
        if unknown:
            raise ValueError(f"unknown reset option(s) {sorted(unknown, key=str)}; "
                             f"{self.label} takes {self.options_help()}")
        cars: list[dict[str, Any]] = [{} for _ in range(self.num)]
        for key in self.option_keys:
            if key in options:
                values = self.check_option(key, options[key], vector)
                for car, value in zip(cars, values, strict=True):
                    car[key] = value
        return cars

    def options_help(self) -> str:
        """The option keys, as messages list them."""
        return ", ".join(map(repr, self.option_keys)) or "no options"

    def check_option(self, key: str, value: Any, vector: bool) -> list[Any]:
        """Option ``key``'s value for each car, checked."""
        raise NotImplementedError(key)

    def start(self, cars: Cars, idx: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """The listed cars' episodes: what is drawn before the car is spawned (``options[i]``:
        car i's checked options)."""

    def build(self, cars: Cars, idx: np.ndarray, options: Sequence[Mapping[str, Any]]) -> None:
        """What the listed cars' worlds hold this episode (after the spawn; a single env's)."""

    def begin(self, cars: Cars, idx: np.ndarray) -> None:
        """The listed cars' numbers once their state is read at the start."""

    # -- step ----------------------------------------------------------------------------------
    @one_or_many
    def score(self, cars: Cars, action: np.ndarray) -> Score:
        """Every car's reward, success and failure after a step (``action``: (N, 2), clipped);
        terminated is success or failure."""
        raise NotImplementedError

    @one_or_many
    def truncated(self, cars: Cars) -> np.ndarray:
        """Which cars the task cuts short this step (before any time limit)."""
        return cars.values(np.zeros(self.num, dtype=bool))

    @one_or_many
    def columns(self, cars: Cars) -> dict[str, Any]:
        """Every observation entry's values as columns over the cars (by the entry's key)."""
        raise NotImplementedError

    @one_or_many
    def observe(self, cars: Cars) -> Any:
        """Every car's observation ((N, D) float32, or a dict of them; one car's values:
        (D,))."""
        observation = self.observation()
        assert isinstance(observation, Observation)
        return observation.build(self.columns(cars))

    @staticmethod
    def car_obs(obs: Any, car: int) -> Any:
        """Car ``car``'s observation, copied out of ``observe``'s."""
        if isinstance(obs, dict):
            return {key: value[car].copy() for key, value in obs.items()}
        return obs[car].copy()

    @one_or_many
    def info(self, cars: Cars, success: np.ndarray) -> dict[str, np.ndarray]:
        """Every car's ``info`` values by key (arrays over the cars, or one car's values)."""
        return {}

