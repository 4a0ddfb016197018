"""The engine-neutral part of a simulator: the integer-ns clock and event-driven stepping.

``EventClock`` keeps the time, the event sources and the registry of named bodies; an engine's
simulator (``sim.pybullet.simulator``, ``sim.mujoco.simulator``, ``sim.planar.simulator``)
subclasses it and steps its physics in ``_step_physics``. Nothing here imports a physics engine.

**Time.** The clock counts integer nanoseconds from the start of an episode, so event times
(the board's 34 ms PID frames, the controller's 0.1 s updates) are exact. ``run_until`` steps
the physics from event to event: each interval between two events is split into the fewest
equal substeps no longer than ``max_substep_s``. Event sources (``EventSource``) say when they
next need to act; the simulator never looks inside them.
"""

from __future__ import annotations

import abc
import math
import shutil
import tempfile
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

NS_PER_S = 1_000_000_000
DEFAULT_MAX_SUBSTEP_S = 0.01
# A substep below 0.1 ms only burns time (1e7 Hz made one env step take 17 s); above 20 ms the
# car's contacts jitter (they start to between 10 and 16 ms).
MAX_SUBSTEP_RANGE_S = (1e-4, 0.02)
MAX_FIRINGS_PER_INSTANT = 100
#: what a batch raises when one of its cars' boards is due again after that many firings
BATCH_STILL_DUE = (f"a car's board is still due after {MAX_FIRINGS_PER_INSTANT} firings at one "
                   "instant")


class EventSource(Protocol):
    """Something that acts at instants of simulated time (a board's PID frames, a controller)."""

    def next_event_ns(self, now_ns: int) -> int | None:
        """The earliest time (ns, >= ``now_ns``) at which it must act; None: nothing pending."""
        ...

    def on_event(self, now_ns: int) -> None:
        """Act at ``now_ns`` (everything due by then)."""
        ...


def seconds_to_ns(seconds: float) -> int:
    """Seconds to the clock's integer nanoseconds (rounded to the nearest)."""
    return round(seconds * NS_PER_S)


def check_max_substep(value: object, name: str = "max_substep_s",
                      allowed: tuple[float, float] = MAX_SUBSTEP_RANGE_S) -> float:
    """``value`` as a float in ``allowed`` (an engine's range; ``MAX_SUBSTEP_RANGE_S`` for
    pybullet and MuJoCo); ValueError naming ``name`` otherwise."""
    low, high = allowed
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float | np.floating | np.integer)
        or not math.isfinite(value)
        or not low <= value <= high
    ):
        raise ValueError(
            f"{name} must be a number of seconds in [{low:g}, {high:g}] (the longest physics "
            f"substep; default {DEFAULT_MAX_SUBSTEP_S}, 0.002 steps at a fixed 500 Hz), "
            f"got {value!r}"
        )
    return float(value)


class ScratchFolder:
    """A temporary folder of ``owner``'s, removed by ``remove()`` or, when ``owner`` is
    collected unclosed (an env copy, an env dropped), by the collector without a word (a
    ``TemporaryDirectory`` warns then, inside whatever warning check is running)."""

    def __init__(self, owner: object) -> None:
        self.path = Path(tempfile.mkdtemp(prefix="smartcar_gym_"))
        self.remove = weakref.finalize(owner, shutil.rmtree, self.path, ignore_errors=True)


class EventClock(abc.ABC):
    """The clock, the event sources and the named bodies of one simulated world.

    Subclasses set ``max_substep_s`` / ``max_substep_ns``, fill ``_bodies`` and implement
    ``_step_physics(interval_ns, probe)``; ``reset`` must call ``_restart_clock``.
    """

    #: the engine's name, as ``engine=`` takes it
    engine = ""
    max_substep_s: float
    max_substep_ns: int

    def _restart_clock(self) -> None:
        self._bodies: dict[str, Any] = {}
        self._sources: list[EventSource] = []
        self.now_ns = 0
        self.physics_steps = 0  # physics steps since the last reset (for benchmarks)

    # -- bodies --------------------------------------------------------------------------------
    def body(self, name: str) -> Any:
        """The body called ``name``."""
        try:
            return self._bodies[name]
        except KeyError:
            raise KeyError(f"no body named {name!r}; bodies: {sorted(self._bodies)}") from None

    def has_body(self, name: str) -> bool:
        return name in self._bodies

    def _check_new_name(self, name: str) -> None:
        if name in self._bodies:
            raise ValueError(
                f"a body named {name!r} already exists; bodies: {sorted(self._bodies)}"
            )

    @property
    def scratch_dir(self) -> Path:
        """A folder of this simulator's own for the files the engine must read (a robot's URDF,
        rewritten at each spawn), made on first use and removed by ``close()`` (or when the
        simulator is collected)."""
        if getattr(self, "_scratch", None) is None:
            self._scratch = ScratchFolder(self)
        return self._scratch.path

    def _remove_scratch(self) -> None:
        scratch = getattr(self, "_scratch", None)
        if scratch is not None:
            scratch.remove()
            self._scratch = None

    # -- clock and stepping --------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Simulated time since the last ``reset`` or ``settle`` (s)."""
        return self.now_ns / NS_PER_S

    def add_event_source(self, source: EventSource) -> None:
        """Let ``source`` act at the instants it asks for (until the next ``reset``).

        Sources due at the same instant act in the order they were added.
        """
        self._sources.append(source)

    def settle(self, seconds: float) -> None:
        """Let the world come to rest for ``seconds`` before time starts: the clock stays at 0.

        Used once bodies are placed (wheels onto the ground) and before anything is scheduled.
        """
        if self.now_ns != 0:
            raise RuntimeError(f"settle() is for t = 0, before time starts; now {self.time_s} s")
        self._step_physics(seconds_to_ns(seconds), None)
        self.now_ns = 0

    def run_for(self, seconds: float, *, physics: bool = True,
                probe: Callable[[float], None] | None = None) -> None:
        """``run_until`` the current time plus ``seconds``."""
        self.run_until(self.now_ns + seconds_to_ns(seconds), physics=physics, probe=probe)

    def run_until(self, end_ns: int, *, physics: bool = True,
                  probe: Callable[[float], None] | None = None) -> None:
        """Advance the clock to ``end_ns``, stepping the physics from event to event.

        Every event source acts at each instant it asks for, the last ones at ``end_ns``
        itself. ``physics=False`` moves the clock without stepping the physics (bodies that
        are moved kinematically). ``probe(time_s)``, if given, runs after every physics
        substep (for logging).
        """
        if end_ns < self.now_ns:
            raise ValueError(f"time cannot go back: run_until({end_ns} ns) at {self.now_ns} ns")
        while True:
            now = self.now_ns
            target = end_ns
            for source in self._sources:  # each acts on what is due, in the order added
                due = self._fire(source, now)
                if due is not None and due < target:
                    target = due
            if now >= end_ns:
                return
            if physics:
                self._step_physics(target - now, probe)
            self.now_ns = target

    @staticmethod
    def _fire(source: EventSource, now: int) -> int | None:
        """Let ``source`` act while it is due at ``now``; its next event time after that."""
        due = source.next_event_ns(now)
        firings = 0
        while due is not None and due <= now:
            if firings == MAX_FIRINGS_PER_INSTANT:
                raise RuntimeError(
                    f"{type(source).__name__} is still due after {firings} firings at {now} ns: "
                    "an event source must move its next event past the present"
                )
            source.on_event(now)
            firings += 1
            due = source.next_event_ns(now)
        return due

    def _substeps(self, interval_ns: int) -> tuple[int, float]:
        """The fewest equal substeps no longer than ``max_substep_s`` in ``interval_ns``, and
        their length (s)."""
        n = -(-interval_ns // self.max_substep_ns)
        return n, interval_ns / (n * NS_PER_S)

    @abc.abstractmethod
    def _step_physics(self, interval_ns: int, probe: Callable[[float], None] | None) -> None:
        """Step ``interval_ns`` in ``_substeps(interval_ns)``, calling ``probe(time_s)`` after
        each substep if given."""
