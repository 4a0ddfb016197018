"""Each id's ``vector_entry_point``: ``smartcar_gym.envs.vector.entries:<id>`` is
``make_vector_env`` for that id (any registered task's id; a string, so that specs stay
serialisable)."""

from __future__ import annotations

import functools
from typing import Any


def __getattr__(name: str) -> Any:
    from smartcar_gym.envs.tasks.registry import task_of

    if task_of(name) is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r} (no task has the "
                             "id)")
    from smartcar_gym.envs.vector.make import make_vector_env

    return functools.partial(make_vector_env, name)
