"""What every smartcar vector env shares: the checks of their arguments (size, threads, episode
limit, autoreset mode), of ``reset``'s seeds and of ``step``'s actions."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from smartcar_gym import checks

#: the autoreset modes the smartcar vector envs implement (Gymnasium 1.x's two automatic ones)
AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)


class CannotBatch(ValueError):
    """What a batched env cannot run, found once its single env is made (the robot's drive):
    the ``vector_entry_point`` then falls back to the loop."""


def available_memory_bytes() -> int | None:
    """The memory the kernel says is available (``MemAvailable``), None where it says nothing."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_num_envs(num_envs: Any, env_id: str, bytes_per_car: int) -> int:
    """``num_envs`` as an int >= 1 whose cars fit in the available memory; one line otherwise."""
    if not checks.is_whole(num_envs) or num_envs < 1:
        raise ValueError(f"{env_id}: num_envs must be an integer >= 1, got {num_envs!r}")
    need = int(num_envs) * bytes_per_car
    free = available_memory_bytes()
    if free is not None and need > free:
        raise MemoryError(
            f"{env_id}: num_envs={num_envs} needs about {need / 2**30:.1f} GiB "
            f"({bytes_per_car / 2**20:.2f} MiB per car), more than the "
            f"{free / 2**30:.1f} GiB available; lower num_envs"
        )
    return int(num_envs)


def check_autoreset_mode(mode: Any) -> AutoresetMode:
    """``mode`` (an ``AutoresetMode`` or its value, e.g. ``"SameStep"``) if implemented here."""
    try:
        mode = mode if isinstance(mode, AutoresetMode) else AutoresetMode(mode)
    except ValueError:
        mode = None
    if mode not in AUTORESET_MODES:
        raise ValueError(
            f"autoreset_mode must be one of {[m.value for m in AUTORESET_MODES]}, got {mode!r}"
        )
    return mode


def check_max_episode_steps(value: Any, env_id: str) -> int | None:
    """The episode limit ``max_episode_steps`` means, as ``gym.make`` reads it: None is the
    id's registered limit, -1 no limit (None is returned), a positive integer itself; anything
    else (0, -5, 2.5) is one line."""
    from gymnasium.envs.registration import registry

    spec = registry.get(env_id.split(":")[-1])  # "smartcar_gym:SmartCar-v0" as gym.make
    registered = None if spec is None else spec.max_episode_steps
    if value is None:
        return registered
    if checks.is_whole(value) and (value >= 1 or value == -1):
        return None if value == -1 else int(value)
    default = f"{env_id}'s limit, {registered} steps" if registered else "the id's limit"
    raise ValueError(f"max_episode_steps must be a positive integer, None ({default}) or -1 "
                     f"(no limit), got {value!r}")


def check_num_threads(value: Any) -> int:
    """``num_threads`` (worker threads stepping the cars' physics): an integer >= 1, None for
    ``os.cpu_count()``; one line otherwise."""
    if value is None:
        return os.cpu_count() or 1
    if not checks.is_whole(value) or value < 1:
        raise ValueError(f"num_threads must be an integer >= 1 (worker threads stepping the "
                         f"physics) or None (one per CPU), got {value!r}")
    return int(value)


def check_seeds(seed: Any, num_envs: int) -> list[int | None]:
    """Each car's seed from ``reset(seed=...)``: an integer s seeds car i with s + i, a list
    (one integer or None per car) each car; None keeps every car's generator."""
    expected = (f"reset(seed=...) must be an integer >= 0, None or a list of {num_envs} "
                "(an integer or None per car)")
    if seed is None:
        return [None] * num_envs
    if checks.is_whole(seed):
        if seed < 0:
            raise ValueError(f"{expected}, got {seed!r}")
        return [int(seed) + i for i in range(num_envs)]
    if not isinstance(seed, list | tuple | np.ndarray):
        raise ValueError(f"{expected}, got {type(seed).__name__} {seed!r}")
    seeds = list(seed)
    if len(seeds) != num_envs:
        raise ValueError(f"reset(seed=[...]) needs {num_envs} seeds (one per car), got "
                         f"{len(seeds)}")
    bad = [s for s in seeds if s is not None and not (checks.is_whole(s) and s >= 0)]
    if bad:
        raise ValueError(f"{expected}, got {bad[0]!r} in the list")
    return [None if s is None else int(s) for s in seeds]


def check_actions(actions: Any, num_envs: int) -> np.ndarray:
    """An ``(num_envs, 2)`` float64 batch of actions clipped to [-1, 1], as each car's env
    would take its own; a wrong shape, complex numbers or a NaN/inf is one line naming what
    was expected."""
    expected = f"actions must be an array of shape ({num_envs}, 2) (linear, angular per car)"
    try:
        raw = np.asarray(actions)
    except ValueError as err:  # ragged rows: "inhomogeneous shape"
        shapes = sorted({np.shape(a) for a in actions}) if isinstance(actions, list | tuple) \
            else None
        raise ValueError(f"{expected}, got a mixed batch (row shapes {shapes})") from err
    if raw.dtype.kind == "c":  # float64 would drop the imaginary parts with only a warning
        raise ValueError(f"actions must be real numbers (linear, angular per car), got "
                         f"complex values ({raw.dtype})")
    try:
        arr = raw.astype(np.float64, copy=False)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{expected} of numbers, got {raw.dtype} values") from err
    if arr.shape != (num_envs, 2):
        raise ValueError(f"{expected}, got shape {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ValueError(f"actions must be finite; cars {np.flatnonzero(bad)[:10].tolist()} "
                         "have NaN or inf")
    return np.clip(arr, -1.0, 1.0)


def check_reset_mask(mask: Any, num_envs: int) -> np.ndarray:
    """``options["reset_mask"]``: a bool array of shape (num_envs,) naming a car, copied."""
    if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_
            and mask.shape == (num_envs,) and mask.any()):
        raise ValueError(f"options['reset_mask'] must be a bool array of shape "
                         f"({num_envs},) with a car to reset, got {mask!r}")
    return mask.copy()


def check_park_mask(mask: Any, num_envs: int) -> np.ndarray:
    """``park``'s mask: a bool array of shape (num_envs,)."""
    if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_
            and mask.shape == (num_envs,)):
        got = (f"a {mask.dtype} array of shape {mask.shape}" if isinstance(mask, np.ndarray)
               else f"a {type(mask).__name__}")
        raise ValueError(f"park: expected a bool mask of shape ({num_envs},) (a numpy "
                         f"array of dtype bool), got {got}")
    return mask


def vector_info(values: dict[str, Any], mask: np.ndarray) -> dict[str, Any]:
    """A Gymnasium vector ``info``: each key's per-car array and its ``_key`` mask (a dict of
    them, such as ``randomization``'s, as a vector info of its own)."""
    info: dict[str, Any] = {}
    for key, value in values.items():
        info[key] = vector_info(value, mask) if isinstance(value, dict) else value
        info[f"_{key}"] = mask.copy()
    return info


def batch_limits(kwargs: dict[str, Any]) -> str | None:
    """What no physics batch runs of these single-env kwargs (None: nothing): the batched env
    (``SmartCarBatchVectorEnv``, whatever its engine) falls back to the loop for them. What a
    task cannot run batched is its own to say (``Task.limits``), and ``randomize`` the
    batch's: it runs where a single env builds each car's episode (``Task.builds_worlds``)."""
    if kwargs.get("render_mode") == "human":
        return "render_mode='human' is a GUI"
    if kwargs.get("controller_mode") not in (None, "hardware"):
        return "controller_mode='sim' steps no physics (SmartCarSim-v0 is batched in numpy)"
    return None
