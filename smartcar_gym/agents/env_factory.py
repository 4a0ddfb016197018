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


def check_env(env_id: str, env_kwargs: dict[str, Any] | None = None) -> None:
    """Make and close one env in this process: bad ``env_kwargs`` then fail here, with the env's
    own message naming the argument, instead of inside a worker process."""
    try:
        env = gym.make(env_id, **(env_kwargs or {}))
    except (gym.error.Error, TypeError, ValueError) as err:
        given = ", ".join(f"{k}={v!r}" for k, v in (env_kwargs or {}).items()) or "no env kwargs"
        raise EnvSetupError(f"cannot make {env_id} with {given}: {err}") from err
    env.close()


def make_env(
    env_id: str,
    env_kwargs: dict[str, Any] | None = None,
    monitor_file: str | None = None,
    monitor: bool = False,
    override_existing: bool = True,
    ignore_sigterm: bool = False,
) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)``, optionally in an SB3 ``Monitor`` logging is_success.

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

        env = Monitor(
            env, filename=monitor_file, info_keywords=INFO_KEYWORDS,
            override_existing=override_existing,
        )
    return env


def env_fns(
    env_id: str,
    n_envs: int,
    env_kwargs: dict[str, Any] | None = None,
    monitor_dir: str | os.PathLike | None = None,
    monitor_prefix: str = "",
    monitor: bool = True,
) -> list[Callable[[], gym.Env]]:
    """Picklable constructors of ``n_envs`` envs; env i logs to ``<monitor_dir>/<prefix><i>``."""
    fns = []
    for rank in range(n_envs):
        monitor_file = (
            None if monitor_dir is None else os.path.join(monitor_dir, f"{monitor_prefix}{rank}")
        )
        fns.append(functools.partial(
            make_env, env_id, dict(env_kwargs or {}), monitor_file=monitor_file, monitor=monitor,
            ignore_sigterm=True,
        ))
    return fns


def make_vec_env(
    env_id: str,
    n_envs: int,
    seed: int | None = None,
    env_kwargs: dict[str, Any] | None = None,
    monitor_dir: str | os.PathLike | None = None,
    monitor_prefix: str = "",
):
    """An SB3 VecEnv of Monitor-wrapped envs: ``SubprocVecEnv`` if ``n_envs > 1``.

    With a ``seed``, env i is reset with ``seed + i`` the first time.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    if n_envs < 1:
        raise ValueError(f"n_envs must be >= 1, got {n_envs}")
    if monitor_dir is not None:
        os.makedirs(monitor_dir, exist_ok=True)
    fns = env_fns(env_id, n_envs, env_kwargs, monitor_dir, monitor_prefix)
    venv = SubprocVecEnv(fns) if n_envs > 1 else DummyVecEnv(fns)
    if seed is not None:
        venv.seed(seed)
    return venv


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
