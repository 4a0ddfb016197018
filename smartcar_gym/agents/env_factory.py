"""Environments for training and evaluation: single envs, SB3 vector envs, VecNormalize.

``make_env`` is a module-level function so it pickles into ``SubprocVecEnv`` and
``gymnasium.vector.AsyncVectorEnv`` workers; importing this module registers the smartcar envs
there. Stable-Baselines3 is imported lazily, so evaluation workers do not load torch.
"""

from __future__ import annotations

import functools
import multiprocessing
import os
import signal
from collections.abc import Callable
from typing import Any

import gymnasium as gym

import smartcar_gym  # noqa: F401  (registers SmartCar-v0 in worker processes)

INFO_KEYWORDS = ("is_success",)


class EnvSetupError(ValueError):
    """The env cannot be made with the given id and keyword arguments."""


# modules the SubprocVecEnv workers need, imported once by the forkserver they are forked from
FORKSERVER_PRELOAD = ("stable_baselines3.common.vec_env.subproc_vec_env",
                      "smartcar_gym.envs.smartcar_env")

#: what gym.make appends to an env creator's TypeError (the id and kwargs, said already)
GYM_CREATOR_SUFFIX = " was raised from the environment creator for "


def check_env_id(env_id: str) -> None:
    """``EnvSetupError`` if Gymnasium knows no ``env_id``: gym.make's reason, the closest
    registered id and the smartcar ids, in one line (before any file is read for it)."""
    import difflib

    from smartcar_gym.registration import ENV_IDS

    try:
        gym.spec(env_id)
    except gym.error.Error as err:
        close = (difflib.get_close_matches(env_id, ENV_IDS, n=1, cutoff=0.6)
                 or difflib.get_close_matches(env_id, list(gym.registry), n=1, cutoff=0.8))
        hint = f"did you mean {close[0]!r}? " if close else ""
        reason = " ".join(str(err).replace("`", "").split()).split(" Did you mean")[0]
        reason = reason.rstrip(".")
        raise EnvSetupError(f"unknown env id {env_id!r}: {reason}; {hint}registered smartcar "
                            f"ids: {', '.join(ENV_IDS)}") from None


def check_env(env_id: str, env_kwargs: dict[str, Any] | None = None,
              env_wrapper: Any = None, monitor_kwargs: dict[str, Any] | None = None) -> None:
    """Make and close one env in this process: bad ``env_kwargs`` then fail here, with the env's
    own message naming the argument, instead of inside a worker process.

    With ``env_wrapper`` (zoo's ``env_wrapper``) or ``monitor_kwargs``, the env is also wrapped
    as training wraps it, reset and stepped once, and its ``info`` must hold every Monitor
    ``info_keywords`` key (``HyperparamsError`` otherwise)."""
    check_env_id(env_id)
    try:
        env = gym.make(env_id, **(env_kwargs or {}))
    except (gym.error.Error, TypeError, ValueError) as err:
        given = ", ".join(f"{k}={v!r}" for k, v in (env_kwargs or {}).items()) or "no env kwargs"
        reason = str(err).split(GYM_CREATOR_SUFFIX)[0]
        raise EnvSetupError(f"cannot make {env_id} with {given}: {reason}") from err
    if env_wrapper is None and monitor_kwargs is None:
        env.close()
        return
    from smartcar_gym.agents.hyperparams import HyperparamsError
    from smartcar_gym.agents.zoo_keys import wrap_env

    try:
        env = wrap_env(env, env_wrapper)
        env.reset(seed=0)
        _, _, _, _, info = env.step(env.action_space.sample())
    except HyperparamsError:
        raise
    except Exception as err:  # user code: whatever fails, the wrapper is the cause
        raise HyperparamsError(f"env_wrapper {env_wrapper!r}: the wrapped env fails to reset "
                               f"or step: {type(err).__name__}: {err}") from err
    finally:
        env.close()
    keywords = (monitor_kwargs or {}).get("info_keywords", INFO_KEYWORDS)
    missing = [key for key in keywords if key not in info]
    if missing:
        raise HyperparamsError(f"monitor_kwargs: info_keywords {', '.join(missing)} not in the "
                               f"info of {env_id} (it has {', '.join(sorted(info))})")


def make_env(
    env_id: str,
    env_kwargs: dict[str, Any] | None = None,
    monitor_file: str | None = None,
    monitor: bool = False,
    override_existing: bool = True,
    ignore_sigterm: bool = False,
    env_wrapper: Any = None,
    monitor_kwargs: dict[str, Any] | None = None,
) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)``, optionally in an SB3 ``Monitor`` logging is_success
    (and ``monitor_kwargs``), then in zoo's ``env_wrapper`` classes (outside the Monitor).

    In a worker process, SIGINT (and SIGTERM if ``ignore_sigterm``: training workers, which the
    main process closes itself) is ignored so that a Ctrl-C or a ``kill`` sent to the whole
    process group reaches only the main process, which saves a checkpoint and closes them.
    """
    if multiprocessing.parent_process() is not None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if ignore_sigterm:
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
    env = gym.make(env_id, **(env_kwargs or {}))
    if monitor or monitor_file is not None:
        from stable_baselines3.common.monitor import Monitor

        kwargs = {"info_keywords": INFO_KEYWORDS, **(monitor_kwargs or {})}
        env = Monitor(env, filename=monitor_file, override_existing=override_existing, **kwargs)
    if env_wrapper is not None:
        from smartcar_gym.agents.zoo_keys import wrap_env

        env = wrap_env(env, env_wrapper)
    return env


def env_fns(
    env_id: str,
    n_envs: int,
    env_kwargs: dict[str, Any] | None = None,
    monitor_dir: str | os.PathLike | None = None,
    monitor_prefix: str = "",
    monitor: bool = True,
    env_wrapper: Any = None,
    monitor_kwargs: dict[str, Any] | None = None,
) -> list[Callable[[], gym.Env]]:
    """Picklable constructors of ``n_envs`` envs; env i logs to ``<monitor_dir>/<prefix><i>``."""
    fns = []
    for rank in range(n_envs):
        monitor_file = (
            None if monitor_dir is None else os.path.join(monitor_dir, f"{monitor_prefix}{rank}")
        )
        fns.append(functools.partial(
            make_env, env_id, dict(env_kwargs or {}), monitor_file=monitor_file, monitor=monitor,
            ignore_sigterm=True, env_wrapper=env_wrapper, monitor_kwargs=monitor_kwargs,
        ))
    return fns


def make_vec_env(
    env_id: str,
    n_envs: int,
    seed: int | None = None,
    env_kwargs: dict[str, Any] | None = None,
    monitor_dir: str | os.PathLike | None = None,
    monitor_prefix: str = "",
    env_wrapper: Any = None,
    monitor_kwargs: dict[str, Any] | None = None,
):
    """An SB3 VecEnv of Monitor-wrapped envs: ``SubprocVecEnv`` if ``n_envs > 1``.

    With a ``seed``, env i is reset with ``seed + i`` the first time. ``env_wrapper`` and
    ``monitor_kwargs`` are zoo's (see ``make_env``).
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    if n_envs < 1:
        raise ValueError(f"n_envs must be >= 1, got {n_envs}")
    if monitor_dir is not None:
        os.makedirs(monitor_dir, exist_ok=True)
    fns = env_fns(env_id, n_envs, env_kwargs, monitor_dir, monitor_prefix,
                  env_wrapper=env_wrapper, monitor_kwargs=monitor_kwargs)
    if n_envs > 1:
        # SB3 starts its workers from a forkserver; each would import torch (through SB3's
        # worker module) and the env on its own: 8 workers took 30-40 s to start on 2 busy
        # cores. Imported once in the server, they are forked ready (11-18 s).
        multiprocessing.set_forkserver_preload(list(FORKSERVER_PRELOAD))
    venv = SubprocVecEnv(fns) if n_envs > 1 else DummyVecEnv(fns)
    if seed is not None:
        venv.seed(seed)
    return venv


def close_vec_env(venv: Any, force: bool = False) -> None:
    """Close a VecEnv; with ``force`` (after an abrupt interrupt) do not wait for pending
    worker replies and kill workers that are still alive."""
    base = venv
    while hasattr(base, "venv"):
        base = base.venv
    if force and hasattr(base, "waiting"):
        base.waiting = False  # the replies of an interrupted step may never come
    try:
        venv.close()
    except (EOFError, OSError):
        pass
    for process in getattr(base, "processes", []):
        if process.is_alive():
            process.kill()  # workers ignore SIGTERM (see make_env)
            process.join(timeout=5)


def wrap_normalize(
    venv,
    normalize: dict[str, Any] | None,
    gamma: float = 0.99,
    load_path: str | os.PathLike | None = None,
    training: bool = True,
):
    """Wrap ``venv`` in ``VecNormalize`` (new, or with statistics from ``load_path``).

    For evaluation (``training=False``) the statistics are frozen and rewards are left raw.
    Returns ``venv`` unchanged when ``normalize`` is None and there is nothing to load.
    """
    from stable_baselines3.common.vec_env import VecNormalize

    if load_path is not None:
        venv = VecNormalize.load(str(load_path), venv)
    elif normalize is not None:
        venv = VecNormalize(venv, gamma=gamma, **normalize)
    else:
        return venv
    venv.training = training
    if not training:
        venv.norm_reward = False
    return venv
