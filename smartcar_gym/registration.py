"""Registration of the smartcar environments with Gymnasium (idempotent), and the one check of
the env a policy's own files name (``check_policy_env``).

Every id is made from a registered task (``envs.tasks.registry``): ``ENV_IDS`` lists the
built-in tasks' ids, ``register_envs`` registers every registered task's.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

# the env's module reserves its keywords (no engine may declare them) before any plug-in
from smartcar_gym.envs import smartcar_env  # noqa: F401
from smartcar_gym.envs.tasks.registry import (
    ENTRY_POINT,
    built_in_ids,
    env_ids,
    register_all,
    task_of,
)

#: every id of the built-in tasks
ENV_IDS: tuple[str, ...] = built_in_ids()
#: what ``gym.make`` itself takes besides the env's keywords (a run may set its episode limit;
#: in a spec they are its fields, not its kwargs)
MAKE_KEYWORDS = ("max_episode_steps", "disable_env_checker")
#: env keywords a policy's file may not set: they name a robot description, which is xacro
#: (xacro evaluates the expressions in it), or what it reads; the user passes them, not the file
FILE_KEYWORDS = ("model", "model_args", "package_path")

__all__ = ["ENTRY_POINT", "ENV_IDS", "FILE_KEYWORDS", "MAKE_KEYWORDS", "PolicyEnvError",
           "check_policy_env", "policy_keywords", "register_envs"]


class PolicyEnvError(ValueError):
    """A policy's file names an env this package will not make (one line naming the file,
    the key and what was expected)."""


def register_envs() -> None:
    """Register every id of every registered task that is not registered yet."""
    register_all()


def policy_keywords(env_id: str) -> tuple[str, ...]:
    """The env keywords a policy's file may set for the registered ``env_id``: the env's own,
    its task's and the engines' (less ``task``: the id names it, those the task refuses and
    ``FILE_KEYWORDS``), and ``MAKE_KEYWORDS``."""
    from smartcar_gym.envs.settings import own_keywords
    from smartcar_gym.envs.smartcar_env import SmartCarEnv
    from smartcar_gym.sim.engines import engine_kwargs

    entry = task_of(env_id)
    if entry is None:
        raise ValueError(f"{env_id!r} is not a smartcar id")
    task = entry.load()
    names = {*own_keywords(SmartCarEnv.__init__), *own_keywords(task.__init__),
             *engine_kwargs(), *MAKE_KEYWORDS}
    return tuple(sorted(names - set(task.refused_keywords) - set(FILE_KEYWORDS) - {"task"}))


def check_policy_env(where: str, env_id: object, env_kwargs: object,
                     engine: object = None) -> tuple[str, dict[str, Any]]:
    """``(env_id, env_kwargs)`` as a policy's file at ``where`` names them (an ONNX file's
    metadata, its ``.json``, a run folder's ``config.yaml``, ``args.yml`` or
    ``provenance.json``), checked before anything is imported or built for them:
    ``env_id`` a plain id this package registered (Gymnasium imports the module named before
    a ``:``), ``env_kwargs`` a mapping of the keywords that id's env declares
    (``policy_keywords``), its ``engine`` and ``engine`` (the metadata's, if given) a
    registered engine and the same. ``PolicyEnvError`` with one line otherwise."""
    from smartcar_gym.sim.engines import DEFAULT_ENGINE, engine_names

    ids = env_ids()
    if not isinstance(env_id, str) or env_id not in ids:
        hint = (" (a policy's file cannot name a module to import)"
                if isinstance(env_id, str) and ":" in env_id else "")
        raise PolicyEnvError(f"{where}: env id {env_id!r} is not an id smartcar-gym registered"
                             f"{hint}; expected one of {', '.join(ids)}")
    if not isinstance(env_kwargs, Mapping) or not all(isinstance(k, str) for k in env_kwargs):
        raise PolicyEnvError(f"{where}: env_kwargs must be a mapping of keyword names to "
                             f"values, got {env_kwargs!r}")
    allowed = policy_keywords(env_id)
    for key in env_kwargs:
        if key in FILE_KEYWORDS:
            raise PolicyEnvError(f"{where}: env_kwargs {key!r} is not taken from a policy's "
                                 f"file (it names a robot description, and xacro evaluates "
                                 f"what that holds); pass it yourself (env_kwargs=, "
                                 f"--env-kwargs) if you trust it")
        if key not in allowed:
            raise PolicyEnvError(f"{where}: env_kwargs {key!r} is not a keyword {env_id} "
                                 f"takes; expected some of {', '.join(allowed)}")
    checker = env_kwargs.get("disable_env_checker")
    if checker is not None and not isinstance(checker, bool):
        raise PolicyEnvError(f"{where}: env_kwargs disable_env_checker must be true or false, "
                             f"got {checker!r}")
    steps = env_kwargs.get("max_episode_steps")
    if steps is not None and (type(steps) is not int or steps <= 0):
        raise PolicyEnvError(f"{where}: env_kwargs max_episode_steps must be a whole number "
                             f"> 0, got {steps!r}")
    engines = engine_names()
    named = env_kwargs.get("engine")
    for key, value in (("env_kwargs engine", named), ("engine", engine)):
        if value is not None and (not isinstance(value, str) or value not in engines):
            raise PolicyEnvError(f"{where}: {key} {value!r} is not a registered engine; "
                                 f"expected one of {', '.join(engines)}")
    if engine is not None and engine != (named or DEFAULT_ENGINE):
        raise PolicyEnvError(f"{where}: engine {engine!r} but env_kwargs run on "
                             f"{named or DEFAULT_ENGINE!r}; expected the same engine")
    return env_id, dict(env_kwargs)
