"""Registration of the smartcar environments with Gymnasium (idempotent).

Every id is made from a registered task (``envs.tasks.registry``): ``ENV_IDS`` lists the
built-in tasks' ids, ``register_envs`` registers every registered task's.
"""

from __future__ import annotations

# the env's module reserves its keywords (no engine may declare them) before any plug-in
from smartcar_gym.envs import smartcar_env  # noqa: F401
from smartcar_gym.envs.tasks.registry import ENTRY_POINT, built_in_ids, register_all

#: every id of the built-in tasks
ENV_IDS: tuple[str, ...] = built_in_ids()

__all__ = ["ENTRY_POINT", "ENV_IDS", "register_envs"]


def register_envs() -> None:
    """Register every id of every registered task that is not registered yet."""
    register_all()
