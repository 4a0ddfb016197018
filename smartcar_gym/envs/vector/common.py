"""What every smartcar vector env shares: the size check, the action check, the autoreset mode."""

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


def check_actions(actions: Any, num_envs: int) -> np.ndarray:
    """An ``(num_envs, 2)`` float64 batch of actions clipped to [-1, 1], as each car's env
    would take its own; a wrong shape or a NaN/inf is one line naming what was expected."""
    expected = f"actions must be an array of shape ({num_envs}, 2) (linear, angular per car)"
    try:
        arr = np.asarray(actions, dtype=np.float64)
    except (TypeError, ValueError) as err:  # ragged rows: "inhomogeneous shape"
        shapes = sorted({np.shape(a) for a in actions}) if isinstance(actions, list | tuple) \
            else None
        raise ValueError(f"{expected}, got a mixed batch (row shapes {shapes})") from err
    if arr.shape != (num_envs, 2):
        raise ValueError(f"{expected}, got shape {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ValueError(f"actions must be finite; cars {np.flatnonzero(bad)[:10].tolist()} "
                         "have NaN or inf")
    return np.clip(arr, -1.0, 1.0)


def vector_info(values: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, Any]:
    """A Gymnasium vector ``info``: each key's per-car array and its ``_key`` mask."""
    info: dict[str, Any] = {}
    for key, value in values.items():
        info[key] = value
        info[f"_{key}"] = mask.copy()
    return info
