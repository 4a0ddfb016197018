"""Checks for SmartCar-v0's keyword arguments: each error names the kwarg and what it expects."""

from __future__ import annotations

import math
import numbers
import os
from typing import Any


def _is_real(value: Any) -> bool:
    # numbers.Real: numpy scalars count; bool does not
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def positive_number(name: str, value: Any) -> float:
    """``value`` as a float if it is a finite number > 0."""
    if not (_is_real(value) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def positive_int(name: str, value: Any) -> int:
    """``value`` as an int if it is a whole number >= 1 (numpy integers count)."""
    if not (isinstance(value, numbers.Integral) and not isinstance(value, bool) and value >= 1):
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def number_pair(name: str, value: Any) -> tuple[float, float]:
    """``value`` as two finite floats, e.g. ``goal_range=(0.5, 1.5)``."""
    try:
        low, high = value
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (min, max) pair of numbers, got {value!r}") from None
    if not all(_is_real(v) and math.isfinite(v) for v in (low, high)):
        raise ValueError(f"{name} must be a (min, max) pair of finite numbers, got {value!r}")
    return float(low), float(high)


def source(name: str, value: Any, loaded: type) -> Any:
    """A file argument: ``None`` (the shipped default), a path, or an already loaded object."""
    if value is None or isinstance(value, str | os.PathLike | loaded):
        return value
    raise TypeError(
        f"{name} must be a file path or a {loaded.__name__} (or None for the shipped one), "
        f"got {type(value).__name__}: {value!r}"
    )
