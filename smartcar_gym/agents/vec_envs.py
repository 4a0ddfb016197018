"""Every vector env that training and evaluation use, built in one place.

* ``make_vec_env``: the SB3 VecEnv that ``smartcar-train`` trains and evaluates on: Monitor-
  wrapped single envs (``SubprocVecEnv`` if ``n_envs > 1``), or with
  ``vectorization="batched"`` (``make_batched_vec_env``) the id's ``vector_entry_point``
  (``SameStep`` autoreset) as an SB3 VecEnv (``sb3_vec_env.GymVectorVecEnv``) in a
  ``VecMonitor``.
* ``make_batched_env``: the id's ``vector_entry_point`` (``NextStep`` autoreset), for the
  batched evaluation episodes (``episodes.evaluate_batched_episodes``).
* ``make_single_env_vector``: single envs in Gymnasium's ``SyncVectorEnv`` (one) or
  ``AsyncVectorEnv`` (worker processes), autoreset off: the sequential evaluation episodes.

Also ``wrap_normalize`` (VecNormalize) and ``close_vec_env``. Stable-Baselines3 is imported
lazily: the evaluation's worker processes, which import this module, do not load torch.
"""

from __future__ import annotations

import functools
import multiprocessing
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
from gymnasium.vector import AutoresetMode

from smartcar_gym.agents.env_factory import INFO_KEYWORDS, EnvSetupError, cannot_make, make_env

__all__ = ["FORKSERVER_PRELOAD", "VECTORIZATIONS", "close_vec_env", "env_fns", "make_batched_env",
           "make_batched_vec_env", "make_single_env_vector", "make_vec_env", "wrap_normalize"]

#: the ways ``make_vec_env`` runs a run's envs (``--vectorization``)
VECTORIZATIONS = ("subproc", "batched")
# modules the SubprocVecEnv workers need, imported once by the forkserver they are forked from
FORKSERVER_PRELOAD = ("stable_baselines3.common.vec_env.subproc_vec_env",
                      "smartcar_gym.envs.smartcar_env")


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
    vectorization: str = "subproc",
) -> Any:
    """An SB3 VecEnv of ``n_envs`` envs logging is_success (and ``monitor_kwargs``: zoo's):

    * ``vectorization="subproc"``: Monitor-wrapped single envs (env i logging to
      ``<monitor_dir>/<prefix><i>``) in zoo's ``env_wrapper`` classes, in a ``SubprocVecEnv``
      if ``n_envs > 1`` (else a ``DummyVecEnv``);
    * ``"batched"``: ``n_envs`` cars of the id's ``vector_entry_point`` (``SameStep``
      autoreset) as a ``GymVectorVecEnv`` in a ``VecMonitor`` (file
      ``<monitor_dir>/<prefix>batched.monitor.csv``); ``EnvSetupError`` (one line) if it cannot
      be made. It has no single envs for an ``env_wrapper``.

    With a ``seed``, env i is reset with ``seed + i`` the first time.
    """
    if vectorization == "batched":
        if env_wrapper is not None:
            raise ValueError("env_wrapper wraps single envs; a batched vector env has none")
        venv = _batched_vec_env(env_id, n_envs, env_kwargs, monitor_dir, monitor_prefix,
                                monitor_kwargs)
    elif vectorization == "subproc":
        venv = _subproc_vec_env(env_id, n_envs, env_kwargs, monitor_dir, monitor_prefix,
                                env_wrapper, monitor_kwargs)
    else:
        raise ValueError(f"vectorization: expected {' or '.join(VECTORIZATIONS)}, got "
                         f"{vectorization!r}")
    if seed is not None:
        venv.seed(seed)
    return venv


def make_batched_vec_env(env_id: str, n_envs: int, **kwargs: Any) -> Any:
    """``make_vec_env(env_id, n_envs, vectorization="batched", **kwargs)``: the cars of the
    id's ``vector_entry_point`` as an SB3 VecEnv (``--vectorization batched``)."""
    return make_vec_env(env_id, n_envs, vectorization="batched", **kwargs)


def _subproc_vec_env(env_id: str, n_envs: int, env_kwargs: dict[str, Any] | None,
                     monitor_dir: str | os.PathLike | None, monitor_prefix: str,
                     env_wrapper: Any, monitor_kwargs: dict[str, Any] | None) -> Any:
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
    return SubprocVecEnv(fns) if n_envs > 1 else DummyVecEnv(fns)


def _batched_vec_env(env_id: str, n_envs: int, env_kwargs: dict[str, Any] | None,
                     monitor_dir: str | os.PathLike | None, monitor_prefix: str,
                     monitor_kwargs: dict[str, Any] | None) -> Any:
    from stable_baselines3.common.vec_env import VecMonitor

    from smartcar_gym.agents.sb3_vec_env import GymVectorVecEnv

    venv = _vector_entry_point(env_id, n_envs, env_kwargs, AutoresetMode.SAME_STEP)
    filename = None
    if monitor_dir is not None:
        os.makedirs(monitor_dir, exist_ok=True)
        filename = os.path.join(monitor_dir, f"{monitor_prefix}batched")
    keywords = (monitor_kwargs or {}).get("info_keywords", INFO_KEYWORDS)
    return VecMonitor(GymVectorVecEnv(venv), filename=filename, info_keywords=tuple(keywords))


def _vector_entry_point(env_id: str, num_envs: int, env_kwargs: dict[str, Any] | None,
                        autoreset_mode: AutoresetMode | None) -> gym.vector.VectorEnv:
    """``gym.make_vec(..., vectorization_mode="vector_entry_point")`` (with the entry point's
    own autoreset mode if ``autoreset_mode`` is None); ``EnvSetupError`` (one line) if it
    cannot be made."""
    kwargs = dict(env_kwargs or {})
    mode = {} if autoreset_mode is None else {"autoreset_mode": autoreset_mode}
    try:
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                            **mode, **kwargs)
    except (gym.error.Error, TypeError, ValueError, MemoryError) as err:
        raise EnvSetupError(cannot_make(f"{num_envs} batched {env_id}", kwargs, err)) from err


def make_batched_env(env_id: str, num_envs: int,
                     env_kwargs: dict[str, Any] | None = None) -> gym.vector.VectorEnv:
    """``num_envs`` cars of ``env_id`` through its ``vector_entry_point`` (its default
    autoreset: Gymnasium's ``"NextStep"``); ``EnvSetupError`` (one line) if it cannot be
    made."""
    return _vector_entry_point(env_id, num_envs, env_kwargs, None)


@dataclass
class _EnvFn:
    """A picklable env constructor for AsyncVectorEnv workers."""

    env_id: str
    env_kwargs: dict[str, Any]
    capture: bool = False  # add info["capture"] for recorders (smartcar_gym.viewers.capture)

    def __call__(self) -> gym.Env:
        env = make_env(self.env_id, self.env_kwargs)
        if self.capture:
            from smartcar_gym.viewers.capture import CaptureWrapper

            env = CaptureWrapper(env)
        return env


def make_single_env_vector(env_id: str, n_envs: int, env_kwargs: dict[str, Any] | None = None,
                           capture: bool = False) -> gym.vector.VectorEnv:
    """``n_envs`` single envs without autoreset: a ``SyncVectorEnv`` of one, else an
    ``AsyncVectorEnv`` of worker processes (forkserver). ``capture``: each env in a
    ``CaptureWrapper`` (``info["capture"]`` for recorders)."""
    fns = [_EnvFn(env_id, dict(env_kwargs or {}), capture) for _ in range(n_envs)]
    mode = AutoresetMode.DISABLED
    if n_envs == 1:
        return gym.vector.SyncVectorEnv(fns, autoreset_mode=mode)
    return gym.vector.AsyncVectorEnv(fns, autoreset_mode=mode, context="forkserver")


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
    venv: Any,
    normalize: dict[str, Any] | None,
    gamma: float = 0.99,
    load_path: str | os.PathLike | None = None,
    training: bool = True,
) -> Any:
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
