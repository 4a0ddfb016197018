"""Command latency: ``cmd_vel`` messages that reach the driver whole controller periods late.

On a real robot a twist crosses a network, a USB serial link and the driver's loop before the
controller acts on it. ``CommandDelay`` holds each published message and hands it over a fixed
number of controller periods after it was published, so that it acts that many updates later
than it would otherwise.
"""

from __future__ import annotations

from collections import deque

from smartcar_gym import checks

MAX_LATENCY_PERIODS = 10  # 1 s at the shipped 10 Hz: the driver's command timeout


class CommandDelay:
    """A first-in first-out line of ``(linear_x, angular_z)`` messages with a fixed delay.

    Args:
        periods: the delay in controller periods (0..``MAX_LATENCY_PERIODS``).
        period_ns: one controller period (ns).

    ``publish`` at time t queues a message; ``arrivals(now)`` returns, in order, every message
    due by ``now`` (published at or before ``now - periods * period_ns``). The robot calls
    ``arrivals`` right after each controller update, so a message published at t acts at the
    update ``periods + 1`` periods after t instead of the next one.
    """

    def __init__(self, periods: int, period_ns: int) -> None:
        self.periods = checks.integer_in("latency", periods, 0, MAX_LATENCY_PERIODS,
                                         "controller periods")
        self.period_ns = checks.positive_int("period_ns", period_ns)
        self._queue: deque[tuple[int, float, float]] = deque()

    def clear(self) -> None:
        """Drop every message in flight (the robot is spawned afresh)."""
        self._queue.clear()

    def publish(self, linear_x: float, angular_z: float, now_ns: int) -> None:
        """A message published at ``now_ns``."""
        self._queue.append((now_ns + self.periods * self.period_ns, linear_x, angular_z))

    def arrivals(self, now_ns: int) -> list[tuple[float, float]]:
        """The messages that have arrived by ``now_ns``, oldest first (removed from the line)."""
        out = []
        while self._queue and self._queue[0][0] <= now_ns:
            _, linear_x, angular_z = self._queue.popleft()
            out.append((linear_x, angular_z))
        return out

    def __len__(self) -> int:
        return len(self._queue)
