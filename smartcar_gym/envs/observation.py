"""An observation declared once: named entries with bounds, their values given as columns.

The space, ``observation_names``, the docstring's table and the vectors themselves all come
from the same ``Entry`` list, so they cannot disagree. A task computes every entry's values as
columns over its cars from their state (``Task.columns``: what the robot knows, the goal in
the ``odom`` frame, the previous action, the sensors); the ROS bridge fills a one-car state
from messages and calls the same task, so a node and the env build bit-identical
observations.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import chain
from typing import Any

import numpy as np
from gymnasium import spaces


@dataclass(frozen=True)
class Entry:
    """One row of the observation table: ``len(names)`` values sharing bounds, unit and meaning.

    ``key`` names the row for composing observations and its columns
    (``Observation.build``); ``bounds_doc`` writes the bounds as the docstring shows them
    (e.g. ``("-2A", "2A")``).
    """

    key: str
    names: tuple[str, ...]
    low: float
    high: float
    unit: str
    doc: str
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
        self._sizes = tuple((e.key, e.size) for e in self.entries)
        self._keys = tuple(e.key for e in self.entries)

    def build(self, columns: Mapping[str, Sequence[Any]]) -> np.ndarray:
        """Every car's observation from each entry's ``columns`` (by key: one float64 array or
        number per name, over the N cars, or a (names, N) array): (N, D) float32, each value
        rounded once, clipped into the bounds. Numbers alone (one car's values: a number per
        name, or a (names,) array) give that car's (D,)."""
        values = list(chain.from_iterable(map(columns.__getitem__, self._keys)))
        if len(values) != len(self.names):
            for key, size in self._sizes:
                if len(columns[key]) != size:
                    raise ValueError(f"observation entry {key!r} gave {len(columns[key])} "
                                     f"columns for its {size} names")
        # each float64 value rounded to float32 once, as it is copied
        try:  # every column an (N,) array (or every value a number): one copy
            table = np.array(values, dtype=np.float32)
        except ValueError:  # numbers among arrays: each broadcast over the cars
            table = None
        if table is None:
            n = max(np.size(v) for v in values)
            table = np.array([np.broadcast_to(v, (n,)) for v in values], dtype=np.float32)
        obs = table if table.ndim == 1 else np.ascontiguousarray(table.T)
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


def space_and_names(observation: Observation | Mapping[str, Observation]) -> tuple[Any, Any]:
    """An env's observation space and ``observation_names`` from its declaration (a dict of
    them: a ``Dict`` space, and the names per key)."""
    if isinstance(observation, Mapping):
        return (spaces.Dict({k: o.space for k, o in observation.items()}),
                {k: o.names for k, o in observation.items()})
    return observation.space, observation.names
