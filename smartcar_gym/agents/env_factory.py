"""Single envs for training and evaluation: ``make_env`` (Monitor, zoo's env_wrapper) and the
checks that an env id and its kwargs can be made, in one line (``EnvSetupError``).

``make_env`` is a module-level function so it pickles into ``SubprocVecEnv`` and
``gymnasium.vector.AsyncVectorEnv`` workers; importing this module registers the smartcar envs
there. Stable-Baselines3 is imported lazily, so evaluation workers do not load torch. The
vector envs are built in ``vec_envs``.
"""

from __future__ import annotations

import multiprocessing
import signal
from typing import Any

import gymnasium as gym

import smartcar_gym  # noqa: F401  (registers SmartCar-v0 in worker processes)

INFO_KEYWORDS = ("is_success",)


class EnvSetupError(ValueError):
    """The env cannot be made with the given id and keyword arguments."""


#: what gym.make appends to an env creator's TypeError (the id and kwargs, said already)
GYM_CREATOR_SUFFIX = " was raised from the environment creator for "


def given_kwargs(env_kwargs: dict[str, Any] | None) -> str:
    """``env_kwargs`` as a message names them: ``key=value, ...`` or "no env kwargs"."""
    return ", ".join(f"{k}={v!r}" for k, v in (env_kwargs or {}).items()) or "no env kwargs"


def cannot_make(what: str, env_kwargs: dict[str, Any] | None, err: BaseException) -> str:
    """One line: ``what`` (an env id, or a batch of them) cannot be made with ``env_kwargs``,
    and the env's own reason (without what gym.make appends, on one line)."""
    given = given_kwargs(env_kwargs)
    reason = " ".join(str(err).split(GYM_CREATOR_SUFFIX)[0].split())
    return f"cannot make {what} with {given}: {reason}"


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
        raise EnvSetupError(cannot_make(env_id, env_kwargs, err)) from err
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
