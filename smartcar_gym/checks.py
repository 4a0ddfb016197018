"""Shared value checks: each returns the normalised value or raises naming what was wrong.

``name`` is how the user wrote the value (a keyword argument, or ``file: key`` for a config),
so every message says which value was wrong, what it was and what was expected.
"""

from __future__ import annotations

import difflib
import math
import numbers
import operator
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

Error = type[Exception]


def is_real(value: Any) -> bool:
    """A real number (numpy scalars count; bool does not)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_finite(value: Any) -> bool:
    """A finite real number."""
    return is_real(value) and math.isfinite(value)


def is_whole(value: Any) -> bool:
    """An integer (numpy integers count; bool and integral floats do not)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def flag(name: str, value: Any, error: Error = ValueError) -> bool:
    """``value`` as a bool if it is True or False (numpy's bools count; 0 and 1 do not)."""
    if not isinstance(value, bool | np.bool_):
        raise error(f"{name} must be True or False, got {value!r}")
    return bool(value)


def positive_number(name: str, value: Any, upper: float | None = None,
                    why: str = "", error: Error = ValueError) -> float:
    """``value`` as a float if it is a finite number > 0 (and <= ``upper``, if given)."""
    if not (is_finite(value) and value > 0):
        raise error(f"{name} must be a positive number, got {value!r}")
    if upper is not None and value > upper:
        raise error(f"{name} must be at most {upper:g}{f' ({why})' if why else ''}, "
                    f"got {value!r}")
    return float(value)


def non_negative_number(name: str, value: Any, error: Error = ValueError) -> float:
    """``value`` as a float if it is a finite number >= 0."""
    if not (is_finite(value) and value >= 0):
        raise error(f"{name} must be a number >= 0, got {value!r}")
    return float(value)


def car_indices(label: str, cars: Sequence[int] | np.ndarray, n: int) -> np.ndarray:
    """``cars`` as distinct int64 indices into ``n`` cars (``label``: whose cars, in the
    error); IndexError for one out of range, ValueError for a repeated one."""
    idx = np.asarray(cars, dtype=np.int64).reshape(-1)
    if len(idx) and (idx.min() < 0 or idx.max() >= n):
        raise IndexError(f"{label} cars must be in [0, {n}), got {idx.tolist()}")
    if len(np.unique(idx)) != len(idx):
        raise ValueError(f"{label} cars must be distinct, got {idx.tolist()}")
    return idx


def car_index(label: str, car: int, n: int) -> int:
    """One car's index, checked as ``car_indices`` checks many (without its arrays)."""
    i = operator.index(car)
    if not 0 <= i < n:
        raise IndexError(f"{label} cars must be in [0, {n}), got [{i}]")
    return i


def positive_int(name: str, value: Any, upper: int | None = None, why: str = "",
                 error: Error = ValueError) -> int:
    """``value`` as an int if it is a whole number >= 1 (and <= ``upper``, if given)."""
    if not (is_whole(value) and value >= 1):
        raise error(f"{name} must be a positive integer, got {value!r}")
    if upper is not None and value > upper:
        raise error(f"{name} must be at most {upper}{f' ({why})' if why else ''}, got {value!r}")
    return int(value)


def integer_in(name: str, value: Any, low: int, high: int, why: str = "",
               error: Error = ValueError) -> int:
    """``value`` as an int in ``low..high``."""
    if not (is_whole(value) and low <= value <= high):
        raise error(f"{name} must be an integer in {low}..{high}{f' ({why})' if why else ''}, "
                    f"got {value!r}")
    return int(value)


def number_pair(name: str, value: Any, error: Error = ValueError) -> tuple[float, float]:
    """``value`` as two finite floats, e.g. ``goal_range=(0.5, 1.5)``."""
    try:
        low, high = value
    except (TypeError, ValueError):
        raise error(f"{name} must be a (min, max) pair of numbers, got {value!r}") from None
    if not all(is_finite(v) for v in (low, high)):
        raise error(f"{name} must be a (min, max) pair of finite numbers, got {value!r}")
    return float(low), float(high)


def one_of(name: str, value: Any, choices: Sequence[Any], error: Error = ValueError,
           none_ok: bool = False) -> Any:
    """``value`` if it is one of ``choices`` (or None, if ``none_ok``), without type coercion."""
    if none_ok and value is None:
        return value
    if not any(type(value) is type(c) and value == c for c in choices):
        also = "None or " if none_ok else ""
        raise error(f"{name} must be {also}one of {tuple(choices)}, got {value!r}")
    return value


def source(name: str, value: Any, loaded: type) -> Any:
    """A file argument: ``None`` (the shipped default), a path, or an already loaded object."""
    if isinstance(value, str | os.PathLike) and not os.fspath(value):
        raise ValueError(
            f"{name} is an empty path: pass a file path, or None (the default) for the shipped one"
        )
    if value is None or isinstance(value, str | os.PathLike | loaded):
        return value
    raise TypeError(
        f"{name} must be a file path or a {loaded.__name__} (or None for the shipped one), "
        f"got {type(value).__name__}: {value!r}"
    )


def check_keywords(name: str, kwargs: dict[str, Any] | Sequence[str], names: Sequence[str],
                   error: Error = TypeError) -> None:
    """``error`` naming each key of ``kwargs`` not in ``names`` with the closest of ``names``
    (difflib), or all of ``names`` where none is close; nothing if all are known."""
    unknown = [key for key in kwargs if key not in names]
    if not unknown:
        return
    parts = []
    for key in unknown:
        close = difflib.get_close_matches(str(key), sorted(names), n=1, cutoff=0.6)
        parts.append(f"{key!r} (did you mean {close[0]!r}?)" if close else repr(key))
    what = "argument" if len(unknown) == 1 else "arguments"
    hint = "" if all("did you mean" in p for p in parts) else \
        f"; it takes {', '.join(sorted(names))}"
    raise error(f"{name} got an unexpected keyword {what} {', '.join(parts)}{hint}")


def distinct_figure(value: float, mark: float, decimals: int) -> str:
    """``value`` with ``decimals`` decimals, or with more until it does not read as ``mark``
    (96.45 against 96.5 is 96.45, not 96.5): a pass-mark line never contradicts itself."""
    while (decimals < 9 and value != mark
           and float(f"{value:.{decimals}f}") == float(f"{mark:.{decimals}f}")):
        decimals += 1
    return f"{value:.{decimals}f}"
