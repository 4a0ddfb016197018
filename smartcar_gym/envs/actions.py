"""A single env's action, checked: two real, finite numbers, clipped to [-1, 1]."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def check_action(action: Any) -> np.ndarray:
    """``action`` as a float64 (2,) array clipped to [-1, 1]; ValueError naming what was wrong
    (a wrong shape, complex numbers, NaN or inf)."""
    if type(action) is np.ndarray and action.shape == (2,) and action.dtype.kind == "f":
        a0, a1 = float(action[0]), float(action[1])  # the usual case, in a few microseconds
        if math.isfinite(a0) and math.isfinite(a1):
            return np.array([min(max(a0, -1.0), 1.0), min(max(a1, -1.0), 1.0)])
    if np.iscomplexobj(action):
        raise ValueError(f"action must be real numbers, got {np.asarray(action).tolist()}")
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"action must be 2 numbers (linear, angular), got {action!r}") from err
    if arr.shape != (2,):
        raise ValueError(f"action must have shape (2,) (linear, angular), got shape "
                         f"{arr.shape}: {action!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"action must be finite, got {arr.tolist()}")
    return np.clip(arr, -1.0, 1.0)
