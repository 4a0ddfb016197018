"""An observation declared once: named entries with bounds, each reading its values from inputs.

The space, ``observation_names``, the docstring's table and the vector itself all come from the
same ``Entry`` list, so they cannot disagree. Entries read from ``Readings``: what the robot
knows (odometry, wheel joint states, sensors), the goal in the ``odom`` frame and the previous
action; the ROS bridge fills the same ``Readings`` from messages, so a node and the env build
bit-identical observations.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces


@dataclass(frozen=True)
class Readings:
    """What an observation may be built from (no ground truth)."""

    odometry: Any  # smartcar_gym.controller.Odometry, or anything with x, y, theta, v, omega
    joint_position: Sequence[float]  # rad, wheel order
    joint_velocity: Sequence[float]  # rad/s, wheel order
    goal: Sequence[float]  # (x, y) in the odom frame
    previous_action: Sequence[float]
    extra: Mapping[str, Sequence[float]] = field(default_factory=dict)  # sensors, by name


@dataclass(frozen=True)
class Entry:
    """One row of the observation table: ``len(names)`` values sharing bounds, unit and meaning.

    ``key`` names the row for composing observations; ``bounds_doc`` writes the bounds as the
    docstring shows them (e.g. ``("-2A", "2A")``).
    """

    key: str
    names: tuple[str, ...]
    low: float
    high: float
    unit: str
    doc: str
    read: Callable[[Readings], Sequence[float] | np.ndarray]
    bounds_doc: tuple[str, str] | None = None

    @property
    def size(self) -> int:
        return len(self.names)


class Observation:
    """The observation vector of an env: its entries in order."""

    def __init__(self, entries: Sequence[Entry]) -> None:
        self.entries = tuple(entries)
        keys = [e.key for e in self.entries]
        if len(set(keys)) != len(keys):
            raise ValueError(f"observation entry keys repeat: {keys}")
        self.names: tuple[str, ...] = tuple(n for e in self.entries for n in e.names)
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"observation names repeat: {self.names}")
        self.high = np.concatenate([[e.high] * e.size for e in self.entries]).astype(np.float32)
        self.low = np.concatenate([[e.low] * e.size for e in self.entries]).astype(np.float32)
        self.space = spaces.Box(self.low, self.high, dtype=np.float32)

    def build(self, readings: Readings) -> np.ndarray:
        """The observation for ``readings``: float32, clipped into the bounds."""
        values: list[float] = []
        for entry in self.entries:
            values.extend(entry.read(readings))
        if len(values) != len(self.names):
            raise ValueError(
                f"observation entries gave {len(values)} values for {len(self.names)} names"
            )
        # as float64 first, then float32: each value is rounded once
        obs = np.array(values, dtype=np.float64).astype(np.float32)
        return np.minimum(np.maximum(obs, self.low, out=obs), self.high, out=obs)

    @classmethod
    def compose(cls, order: Sequence[str], *parts: Sequence[Entry]) -> Observation:
        """The entries of ``parts`` (robot, task, sensors, ...) in the ``order`` of their keys."""
        available = {e.key: e for part in parts for e in part}
        missing = [k for k in order if k not in available]
        if missing:
            raise KeyError(f"no observation entry {missing}; available: {sorted(available)}")
        return cls([available[k] for k in order])

    def index(self, name: str) -> int:
        """Position of the value called ``name``."""
        return self.names.index(name)

    def table(self) -> str:
        """The observation table in Markdown (Num, Observation, Min, Max, Unit)."""
        rows = ["| Num   | Observation | Min | Max | Unit |", "|---|---|---|---|---|"]
        start = 0
        for entry in self.entries:
            end = start + entry.size - 1
            num = str(start) if entry.size == 1 else (
                f"{start}, {end}" if entry.size == 2 else f"{start}-{end}")
            low, high = entry.bounds_doc or (_number(entry.low), _number(entry.high))
            rows.append(f"| {num} | {entry.doc} | {low} | {high} | {entry.unit} |")
            start = end + 1
        return "\n".join(rows)


def _number(value: float) -> str:
    if abs(value - np.pi) < 1e-12:
        return "pi"
    if abs(value + np.pi) < 1e-12:
        return "-pi"
    return f"{value:g}"
