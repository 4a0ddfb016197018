"""Time in the bridge: the simulator's clock, publication instants, wall-clock pacing.

The simulator owns time. The bringup node steps it to each publication instant (``Schedule``),
then waits until the wall clock reaches that instant (``Pacer``: ``speed`` simulated seconds per
wall second) and publishes. Message stamps are simulated time: with ``/use_sim_time`` they are
the simulator's clock itself (published on ``/clock``), otherwise the ROS time at which the
simulation started plus the simulated time, so that at ``speed`` 1 they follow the wall clock.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from smartcar_gym.sim.clock import NS_PER_S

# Behind the wall clock by more than this (s), the pacer stops catching up: it lets the
# simulated time fall behind (the lag is reported) instead of running a burst of steps.
MAX_CATCH_UP_S = 0.25


@dataclass
class Stream:
    """Something published every ``period_ns`` of simulated time, first at ``period_ns``."""

    name: str
    period_ns: int
    next_ns: int = field(init=False)

    def __post_init__(self) -> None:
        if self.period_ns <= 0:
            raise ValueError(f"{self.name}: the period must be positive, got {self.period_ns} ns")
        self.next_ns = self.period_ns


class Schedule:
    """Publication instants of several streams on the simulator's integer-ns clock."""

    def __init__(self, streams: list[Stream]) -> None:
        self.streams = streams

    def next_ns(self) -> int:
        """The earliest instant at which some stream is due."""
        return min(s.next_ns for s in self.streams)

    def due(self, now_ns: int) -> list[str]:
        """The streams due at ``now_ns`` (in the order given); each moves to its next instant."""
        names = []
        for stream in self.streams:
            if stream.next_ns <= now_ns:
                names.append(stream.name)
                stream.next_ns += stream.period_ns
        return names


def period_ns(rate_hz: float) -> int:
    """The period of ``rate_hz`` in integer ns (as ``SmartCarRobot.update_period_ns``)."""
    return round(NS_PER_S / rate_hz)


class Pacer:
    """Holds simulated time to ``speed`` times the wall clock and measures how far behind it is.

    ``wait(sim_ns)`` sleeps until the wall clock reaches the instant of ``sim_ns``; a lag of
    up to ``MAX_CATCH_UP_S`` is caught up (no sleep until back on time), a longer one is
    accepted: the pacer restarts from the present and ``behind_s`` grows by the time lost.
    """

    def __init__(self, speed: float, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be a positive number, got {speed!r}")
        self.speed = speed
        self._clock, self._sleep = clock, sleep
        self._wall0 = clock()
        self._sim0_ns = 0
        self.behind_s = 0.0  # simulated seconds lost to falling behind, in total
        self.falls = 0  # how many times it fell behind by more than MAX_CATCH_UP_S

    def start(self, sim_ns: int) -> None:
        """Simulated ``sim_ns`` is now."""
        self._wall0, self._sim0_ns = self._clock(), sim_ns

    def wait(self, sim_ns: int) -> float:
        """Sleep until the wall-clock instant of ``sim_ns``; returns the lag (s) found, >= 0."""
        target = self._wall0 + (sim_ns - self._sim0_ns) / NS_PER_S / self.speed
        lag = self._clock() - target
        if lag < 0:
            self._sleep(-lag)
            return 0.0
        if lag > MAX_CATCH_UP_S:
            self.behind_s += lag * self.speed
            self.falls += 1
            self.start(sim_ns)
        return lag
