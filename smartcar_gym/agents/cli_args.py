"""The value types of the command lines' options (``smartcar-train``, ``smartcar-eval``,
``smartcar-tune``, ``smartcar-ros``): each refuses a bad value in one line naming it."""

from __future__ import annotations

import argparse
import math
from typing import Any

from smartcar_gym.agents.hyperparams import HyperparamsError, parse_key_value

__all__ = ["distance_arg", "key_value_arg", "non_negative_int_arg", "percent_arg",
           "positive_int_arg"]


def key_value_arg(text: str) -> tuple[str, Any]:
    """argparse type for ``key=value`` (the value read as YAML)."""
    try:
        return parse_key_value(text)
    except HyperparamsError as err:
        raise argparse.ArgumentTypeError(str(err)) from err


def _integer(text: str, expected: str, low: int) -> int:
    """``text`` as a whole number (``2e5`` allowed) >= ``low``; ``expected`` names the range
    in the refusal of a number below it."""
    try:
        value = int(float(text)) if "e" in text.lower() else int(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from err
    if value < low:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
    return value


def non_negative_int_arg(text: str) -> int:
    """argparse type for a whole number >= 0 (``2e5`` allowed)."""
    return _integer(text, "a non-negative integer", 0)


def positive_int_arg(text: str) -> int:
    """argparse type for a whole number >= 1."""
    return _integer(text, "a positive integer", 1)


def _number(text: str) -> float:
    """``text`` as a float; NaN (refused by every range) if it is not a number."""
    try:
        return float(text)
    except ValueError:
        return math.nan


def percent_arg(text: str) -> float:
    """argparse type for a percentage from 0 to 100."""
    value = _number(text)
    if not 0.0 <= value <= 100.0:
        raise argparse.ArgumentTypeError(f"expected a percentage from 0 to 100, got {text!r}")
    return value


def rate_arg(text: str) -> float:
    """argparse type for a rate in Hz (> 0, finite)."""
    value = _number(text)
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a rate in Hz > 0, got {text!r}")
    return value


def distance_arg(text: str) -> float:
    """argparse type for a distance in metres (> 0, finite)."""
    value = _number(text)
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a distance in metres > 0, got {text!r}")
    return value
