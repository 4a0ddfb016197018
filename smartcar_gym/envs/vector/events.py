"""Every car's clock in a batch: the single env's event stepping (``Simulator.run_until``) for
N cars, each on its own clock from its own reset.

At each of a car's events (the controller every 0.1 s, the board's PID frame every 35 ms while
it drives, the laser's scans) the batched ArbotiX fires for the cars that are due, their
motor outputs go to the engine, and every car steps to its own next event in the fewest equal
substeps no longer than ``max_substep_s``. After autoresets cars are at different points of
the 35 ms frame cycle, so no common schedule is assumed.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.controller.latency import CommandDelay
from smartcar_gym.envs.state import CarState
from smartcar_gym.envs.vector.laser import BatchLaser
from smartcar_gym.sim.clock import BATCH_STILL_DUE, MAX_FIRINGS_PER_INSTANT, NS_PER_S

_NEVER = np.iinfo(np.int64).max


class Clocks:
    """The events of ``state``'s cars: ``base``'s boards, the engine's ``cars`` and the task's
    ``laser`` (None: none); ``report`` issues the engine's warnings of unstable cars."""

    def __init__(self, state: CarState, base: BatchedArbotix, cars: Any, period_ns: int,
                 max_substep_ns: int, laser: BatchLaser | None,
                 report: Callable[[Sequence[Warning]], None]) -> None:
        self.state, self.base, self.cars = state, base, cars
        self.period_ns, self.max_substep_ns = period_ns, max_substep_ns
        self.laser, self.report = laser, report
        #: each car's next controller update (ns on its clock)
        self.next_update = np.zeros(state.num, dtype=np.int64)
        #: per car whose robot delays its commands (``randomize``'s latency): the delay
        self.delays: dict[int, CommandDelay] = {}

    def reset(self, idx: np.ndarray) -> None:
        """The listed cars' clocks at t = 0, their controllers first due one period on."""
        self.state.now_ns[idx] = 0
        self.next_update[idx] = self.period_ns

    def command(self, linear_x: np.ndarray, angular_z: np.ndarray) -> None:
        """Every car's ``cmd_vel`` now (``SmartCarRobot.cmd_vel``): a delayed car's into its
        line, the others' to the boards."""
        now = self.state.now_ns
        now_s = now / NS_PER_S
        if not self.delays:
            self.base.cmd_vel(linear_x, angular_z, now_s)
            return
        direct = np.ones(self.state.num, dtype=bool)
        for i, delay in self.delays.items():
            delay.publish(float(linear_x[i]), float(angular_z[i]), int(now[i]))
            direct[i] = False
        self.base.cmd_vel(linear_x, angular_z, now_s, direct)

    def _deliver(self, updated: np.ndarray, now_s: np.ndarray) -> None:
        """The delayed commands that arrive at the updates just run (``on_event``)."""
        now = self.state.now_ns
        for i in np.flatnonzero(updated).tolist():
            delay = self.delays.get(i)
            if delay is None:
                continue
            for linear_x, angular_z in delay.arrivals(int(now[i])):
                one = np.zeros(self.state.num, dtype=bool)
                one[i] = True
                self.base.cmd_vel(linear_x, angular_z, now_s, one)

    def _fire(self, mask: np.ndarray) -> np.ndarray:
        """Every masked car's events due at its clock: controller update, then PID frame (the
        robot's), then the laser, in the single env's order. Returns each car's next robot
        event after them (``_robot_due``; the laser's scans do not move it)."""
        now, cars, base = self.state.now_ns, self.cars, self.base
        for _ in range(MAX_FIRINGS_PER_INSTANT):
            due = self._robot_due()
            firing = mask & (due <= now)
            if not firing.any():
                if self.laser is not None:
                    self.laser.fire(cars, self.state, mask)
                return due
            now_s = now / NS_PER_S
            angles = cars.encoder_angles()
            update = firing & (now >= self.next_update)
            if update.any():
                base.update(now_s, angles, update)
                if self.delays:
                    self._deliver(update, now_s)
                self.next_update[update] += self.period_ns
            base.board_tick(now_s, angles, firing)
            cars.set_drive(firing, base.drive_torque, base.damping)
        raise RuntimeError(BATCH_STILL_DUE)

    def _next_due(self, due: np.ndarray) -> np.ndarray:
        """Each car's next event (ns on its clock), of any source (``due``: its next robot
        event, ``_robot_due``)."""
        if self.laser is not None:
            due = np.minimum(due, self.laser.next_scan)
        return due

    def _robot_due(self) -> np.ndarray:
        """Each car's next robot event (ns on its clock): ``SmartCarRobot.next_event_ns``."""
        return np.minimum(self.next_update, self.base.next_frame_ns(self.state.now_ns, _NEVER))

    def run_period(self) -> None:
        """``run_until(now + period)`` for every car not parked, from event to event."""
        now = self.state.now_ns
        end = now + self.period_ns
        pending = ~self.state.parked
        # the engine's own loop over the cars' events, where it has one (the planar batch's
        # compiled ``run_period``, which says itself where it cannot run): the same sequence
        # per car, without this loop's costs
        fused = getattr(self.cars, "run_period", None)
        if fused is not None and self.laser is None and not self.delays and \
                fused(self.base, now, self.next_update, end, pending, self.period_ns,
                      self.max_substep_ns):
            return
        while True:
            due = self._fire(pending)
            target = np.minimum(self._next_due(due), end)
            if COMPILED:  # read at each call: a test switches it off
                # pending becomes the cars still short of the period's end (``active``)
                cars, nstep, timestep = _substeps(pending, now, end, target,
                                                  self.max_substep_ns)
                if cars is None:
                    return
            else:
                pending = pending & (now < end)
                if not pending.any():
                    return
                cars = np.flatnonzero(pending)
                interval = target[cars] - now[cars]
                nstep = -(-interval // self.max_substep_ns)
                timestep = interval.astype(np.float64) / (nstep * NS_PER_S).astype(np.float64)
                moving = interval > 0
                cars, nstep, timestep = cars[moving], nstep[moving], timestep[moving]
            self.cars.step(cars, nstep, timestep)
            unstable = self.cars.take_unstable()
            if unstable:
                self.report(unstable)
            np.copyto(now, target, where=pending)


try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

#: whether numba's loop plans each iteration's substeps (the ``fast`` extra, as
#: ``controller.compiled``): the same integer and float operations per car as numpy's
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"
_substeps: Callable[..., tuple[Any, Any, Any]] | None = None
if COMPILED:

    @numba.njit(cache=True)
    def _plan(pending: np.ndarray, now: np.ndarray, end: np.ndarray, target: np.ndarray,
              max_substep_ns: int, cars: np.ndarray, nstep: np.ndarray,
              timestep: np.ndarray) -> tuple[int, int]:
        """Each pending car short of ``end`` stays pending (the others stop); of those, the
        ones with time to go to ``target`` get their substeps (``cars``, ``nstep``,
        ``timestep``: the first of the returned counts, the pending ones the second)."""
        k = active = 0
        for i in range(pending.shape[0]):
            if pending[i] and now[i] < end[i]:
                active += 1
                interval = target[i] - now[i]
                if interval > 0:
                    n = -(-interval // max_substep_ns)
                    cars[k], nstep[k] = i, n
                    timestep[k] = np.float64(interval) / np.float64(n * NS_PER_S)
                    k += 1
            else:
                pending[i] = False
        return k, active

    def _substeps(pending: np.ndarray, now: np.ndarray, end: np.ndarray, target: np.ndarray,
                  max_substep_ns: int) -> tuple[Any, Any, Any]:
        """``_plan`` into new arrays; (None, None, None) when no car is pending."""
        n = pending.shape[0]
        cars, nstep = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
        timestep = np.empty(n)
        k, active = _plan(pending, now, end, target, max_substep_ns, cars, nstep, timestep)
        if not active:
            return None, None, None
        return cars[:k], nstep[:k], timestep[:k]
