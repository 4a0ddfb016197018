"""Which task an id runs: a registry of tasks, each with the Gymnasium ids made from it.

A task is a ``Task`` subclass (``envs.tasks.base``) registered under a name with its ids
(``register_task``); every id is then ``SmartCarEnv(task=name, **its kwargs)`` for
``gym.make`` and a batched or looped vector env for ``gym.make_vec(...,
vectorization_mode="vector_entry_point")``. The built-in tasks are reach (SmartCar-v0,
SmartCarSim-v0, SmartCarArrive-v0), nav, goal and barn; an installed package adds its own
through an entry point of the ``smartcar_gym.tasks`` group (its object: a ``TaskEntry``).
Listing the tasks imports none of them: a task's class is imported when an env is first
made. docs/tasks.md shows how to write one (``examples/task_plugin.py``).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any

#: the single env of every id
ENTRY_POINT = "smartcar_gym.envs.smartcar_env:SmartCarEnv"
#: the module whose attribute named after an id makes that id's vector env
VECTOR_ENTRIES = "smartcar_gym.envs.vector.entries"
#: the entry-point group another package registers its tasks in
ENTRY_POINT_GROUP = "smartcar_gym.tasks"


@dataclass(frozen=True)
class EnvId:
    """How one id of a task is registered: its episode limit (steps), reward threshold and
    the env keywords it sets."""

    max_episode_steps: int | None
    reward_threshold: float | None = None
    kwargs: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TaskEntry:
    """A task by name: its class (or ``"package.module:Class"``, imported when first needed),
    its ids and a line saying what it is."""

    name: str
    task: Any
    ids: Mapping[str, EnvId]
    summary: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"a task's name must be an identifier, got {self.name!r}")
        if not self.ids:
            raise ValueError(f"task {self.name!r} needs at least one id")

    def load(self) -> type:
        """The task's class."""
        if isinstance(self.task, str):
            module, name = self.task.split(":")
            return getattr(importlib.import_module(module), name)
        return self.task


def _built_in() -> tuple[TaskEntry, ...]:
    from smartcar_gym.controller.config_yaml import calibrated_config_path

    return (
        TaskEntry("reach", "smartcar_gym.envs.tasks.reach:ReachTask", {
            # reward threshold: the mean return of a policy that reaches the goal reliably
            "SmartCar-v0": EnvId(200, 15.0),
            "SmartCarSim-v0": EnvId(200, 15.0, {"controller_mode": "sim"}),
            # drive to a goal 0.3-2 m away and stop there, on calibrated odometry: what a ROS
            # user clicking 2D Nav Goals expects (docs/ros.md); `smartcar-ros policy` drives it
            "SmartCarArrive-v0": EnvId(200, 15.0, {
                "controller_config": calibrated_config_path(), "goal_range": (0.3, 2.0),
                "stop_speed": 0.01}),
        }, "reach a goal on an empty plane"),
        # 20 s, as SmartCar-v0: goals up to 2 m away and a detour take at most 10 s
        TaskEntry("nav", "smartcar_gym.envs.tasks.nav:NavTask",
                  {"SmartCarNav-v0": EnvId(200)}, "reach a goal among obstacles, by laser"),
        # 10 s: HER learns from short episodes; goals 0.5-1.5 m away take 3-5 s
        TaskEntry("goal", "smartcar_gym.envs.tasks.goal:GoalTask",
                  {"SmartCarGoal-v0": EnvId(100)}, "goal-conditioned reaching, for HER"),
        # no step limit: the env ends every run at the protocol's timeout, which follows the
        # car (1675 steps for the shipped car, 3349 at max_linear=0.25), with its own outcome
        TaskEntry("barn", "smartcar_gym.envs.tasks.barn:BarnTask",
                  {"SmartCarBARN-v0": EnvId(None)}, "the BARN challenge's worlds and score"),
    )


_REGISTRY: dict[str, TaskEntry] = {}
_loaded = False


def _load() -> None:
    """The built-in tasks, then those of the ``smartcar_gym.tasks`` entry points."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    for entry in _built_in():
        _add(entry)
    for point in entry_points(group=ENTRY_POINT_GROUP):
        entry = point.load()
        if not isinstance(entry, TaskEntry):
            raise TypeError(f"entry point {point.name!r} of {ENTRY_POINT_GROUP} ({point.value}) "
                            f"is a {type(entry).__name__}, not a TaskEntry")
        _add(entry)


def _add(entry: TaskEntry) -> None:
    taken = {i: t.name for t in _REGISTRY.values() for i in t.ids}
    for env_id in entry.ids:
        if env_id in taken and taken[env_id] != entry.name:
            raise ValueError(f"id {env_id!r} belongs to task {taken[env_id]!r} already")
    _REGISTRY[entry.name] = entry


def register_task(name: str, task: Any, ids: Mapping[str, EnvId],
                  summary: str = "") -> TaskEntry:
    """Add the task ``task`` (a ``Task`` subclass, or ``"package.module:Class"``) as ``name``
    with its ``ids``, each registered with Gymnasium at once; one line if the name or an id
    is taken."""
    _load()
    if name in _REGISTRY:
        raise ValueError(f"task {name!r} is registered already")
    entry = TaskEntry(name, task, dict(ids), summary)
    _add(entry)
    register_ids(entry)
    return entry


def task_names() -> tuple[str, ...]:
    """Every registered task's name, the built-in ones first."""
    _load()
    return tuple(_REGISTRY)


def get_task(name: object) -> TaskEntry:
    """The registered task called ``name``; ValueError listing the tasks otherwise."""
    _load()
    if not isinstance(name, str) or name not in _REGISTRY:
        raise ValueError(f"task must be one of {', '.join(map(repr, _REGISTRY))}, got {name!r}")
    return _REGISTRY[name]


def task_of(env_id: str) -> TaskEntry | None:
    """The task an id runs (None: not a smartcar id)."""
    _load()
    return next((t for t in _REGISTRY.values() if env_id in t.ids), None)


def env_ids() -> tuple[str, ...]:
    """Every id of every registered task."""
    _load()
    return tuple(i for t in _REGISTRY.values() for i in t.ids)


def built_in_ids() -> tuple[str, ...]:
    """Every id of the built-in tasks."""
    return tuple(i for t in _built_in() for i in t.ids)


def register_ids(entry: TaskEntry) -> None:
    """Register ``entry``'s ids with Gymnasium (those not registered yet)."""
    from gymnasium.envs.registration import register, registry

    for env_id, how in entry.ids.items():
        if env_id in registry:
            continue
        register(id=env_id, entry_point=ENTRY_POINT,
                 vector_entry_point=f"{VECTOR_ENTRIES}:{env_id}",
                 max_episode_steps=how.max_episode_steps,
                 reward_threshold=how.reward_threshold,
                 kwargs={"task": entry.name, **how.kwargs})


def register_all() -> None:
    """Register every id of every registered task."""
    _load()
    for entry in _REGISTRY.values():
        register_ids(entry)
