"""The rl-baselines3-zoo keys that shape a run rather than the algorithm.

Read as rl_zoo3's ``ExperimentManager`` reads them::

    env_wrapper: my_pkg.wrappers.Wrapper             # or a list; {path: {kwarg: value}} for kwargs
    vec_env_wrapper: stable_baselines3.common.vec_env.VecCheckNan
    frame_stack: 4                                   # VecFrameStack, outside VecNormalize
    callback: [{my_pkg.callbacks.Log: {every: 10}}]  # SB3 callbacks, added to smartcar-train's
    monitor_kwargs: "dict(info_keywords=('is_success',))"   # Monitor(...) arguments
    env_kwargs: {goal_range: [0.5, 1.0]}             # gym.make arguments (--env-kwargs wins)

A wrapper or callback is an import path ``module.Name``, a list of them, or one-key mappings
``{module.Name: {keyword: value}}``; wrappers are applied in the order given (the first
innermost), each env's wrappers outside its ``Monitor``, as the zoo does. ``smartcar-train``
always logs ``is_success`` in the Monitor files, whatever ``monitor_kwargs`` says.
"""

from __future__ import annotations

import importlib
from typing import Any

from smartcar_gym.agents.hyperparams import HyperparamsError, parse_kwargs

SUCCESS_KEY = "is_success"
# Monitor(...) arguments that smartcar-train sets itself, and why they cannot be set.
MONITOR_RESERVED = {
    "filename": "Monitor files always go to <run-dir>/monitor",
    "override_existing": "smartcar-train appends to them on --resume itself",
    "reset_keywords": "SB3 vector envs reset without keyword arguments, so Monitor would fail "
                      "at the first reset",
}
MONITOR_KEYS = ("info_keywords", "allow_early_resets")


def import_object(path: Any, key: str) -> Any:
    """The object at import path ``module.Name``; ``HyperparamsError`` naming ``key`` if none."""
    if not isinstance(path, str) or "." not in path.strip("."):
        raise HyperparamsError(f"{key}: expected an import path such as module.Name, got {path!r}")
    module_name, _, name = path.rpartition(".")
    try:
        module = importlib.import_module(module_name)
    except ImportError as err:
        raise HyperparamsError(f"{key}: cannot import {module_name} (for {path}): {err}") from err
    try:
        return getattr(module, name)
    except AttributeError as err:
        raise HyperparamsError(f"{key}: module {module_name} has no {name!r}") from err


def class_specs(value: Any, key: str) -> list[tuple[str, dict[str, Any]]]:
    """zoo's ``Path``, ``[Path, ...]`` or ``[{Path: {kwargs}}, ...]`` as (path, kwargs) pairs."""
    if value is None:
        return []
    specs = []
    for item in value if isinstance(value, list) else [value]:
        path, kwargs = item, {}
        if isinstance(item, dict):
            if len(item) != 1:
                raise HyperparamsError(
                    f"{key}: each entry is an import path or a one-key mapping "
                    f"{{module.Name: {{keyword: value}}}}, got {item!r} (check the indentation)"
                )
            ((path, kwargs),) = item.items()
            kwargs = {} if kwargs is None else kwargs
            if not isinstance(kwargs, dict):
                raise HyperparamsError(f"{key}: the arguments of {path} must be a mapping, got "
                                       f"{kwargs!r}")
        if not isinstance(path, str):
            raise HyperparamsError(f"{key}: expected an import path such as module.Name, got "
                                   f"{path!r}")
        specs.append((path, dict(kwargs)))
    return specs


def _instantiate(cls: Any, first: tuple[Any, ...], kwargs: dict[str, Any], path: str,
                 key: str) -> Any:
    if not callable(cls):
        raise HyperparamsError(f"{key}: {path} is not a class")
    try:
        return cls(*first, **kwargs)
    except Exception as err:  # user code: whatever fails, the setting is the cause
        given = ", ".join(f"{k}={v!r}" for k, v in kwargs.items()) or "no arguments"
        raise HyperparamsError(f"{key}: {path}({given}) failed: {type(err).__name__}: {err}"
                               ) from err


def wrap_env(env: Any, value: Any) -> Any:
    """``env`` wrapped in the ``env_wrapper`` classes (the first innermost)."""
    for path, kwargs in class_specs(value, "env_wrapper"):
        env = _instantiate(import_object(path, "env_wrapper"), (env,), kwargs, path,
                           "env_wrapper")
    return env


def wrap_vec_env(venv: Any, value: Any) -> Any:
    """``venv`` wrapped in the ``vec_env_wrapper`` classes (inside VecNormalize, as the zoo)."""
    for path, kwargs in class_specs(value, "vec_env_wrapper"):
        venv = _instantiate(import_object(path, "vec_env_wrapper"), (venv,), kwargs, path,
                            "vec_env_wrapper")
    return venv


def make_callbacks(value: Any) -> list[Any]:
    """New instances of the ``callback`` classes (each must be an SB3 ``BaseCallback``)."""
    from stable_baselines3.common.callbacks import BaseCallback

    callbacks = []
    for path, kwargs in class_specs(value, "callback"):
        callback = _instantiate(import_object(path, "callback"), (), kwargs, path, "callback")
        if not isinstance(callback, BaseCallback):
            raise HyperparamsError(f"callback: {path} is not a Stable-Baselines3 callback "
                                   "(a subclass of BaseCallback)")
        callbacks.append(callback)
    return callbacks


def frame_stack(value: Any) -> int | None:
    """``frame_stack``: how many observations ``VecFrameStack`` stacks (None: no stacking)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise HyperparamsError(f"frame_stack must be a whole number >= 1, got {value!r}")
    return value


def monitor_kwargs(value: Any) -> dict[str, Any]:
    """``Monitor`` keyword arguments from ``monitor_kwargs`` (a mapping or a zoo ``dict(...)``
    string), with ``is_success`` always among ``info_keywords``."""
    kwargs = parse_kwargs(value, "monitor_kwargs")
    reserved = sorted(set(kwargs) & set(MONITOR_RESERVED))
    if reserved:
        raise HyperparamsError("; ".join(f"monitor_kwargs: {key} cannot be set: "
                                         f"{MONITOR_RESERVED[key]}" for key in reserved))
    unknown = sorted(set(kwargs) - set(MONITOR_KEYS))
    if unknown:
        raise HyperparamsError(f"monitor_kwargs: unknown Monitor argument(s) "
                               f"{', '.join(unknown)}; accepted: {', '.join(MONITOR_KEYS)}")
    keywords = kwargs.get("info_keywords", ())
    if isinstance(keywords, str) or not isinstance(keywords, (list, tuple)) or not all(
            isinstance(k, str) for k in keywords):
        raise HyperparamsError(f"monitor_kwargs: info_keywords must be a list of info keys, "
                               f"got {keywords!r}")
    kwargs["info_keywords"] = tuple(dict.fromkeys((SUCCESS_KEY, *keywords)))
    return kwargs


def env_kwargs(value: Any) -> dict[str, Any]:
    """``env_kwargs``: keyword arguments for ``gym.make`` (a mapping)."""
    if value is None:
        return {}
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise HyperparamsError(f"env_kwargs must be a mapping of argument names to values, got "
                               f"{value!r}")
    return dict(value)


def check(hyperparams: dict[str, Any]) -> None:
    """Check the run keys of a zoo entry before anything is made (imports the named classes
    and makes the callbacks once); raises ``HyperparamsError``."""
    for key in ("env_wrapper", "vec_env_wrapper"):
        for path, _ in class_specs(hyperparams.get(key), key):
            if not callable(import_object(path, key)):
                raise HyperparamsError(f"{key}: {path} is not a class")
    make_callbacks(hyperparams.get("callback"))
    frame_stack(hyperparams.get("frame_stack"))
    monitor_kwargs(hyperparams.get("monitor_kwargs"))
    env_kwargs(hyperparams.get("env_kwargs"))
