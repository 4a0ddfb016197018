"""A task's laser on every car of a batch: an event source on each car's clock.

Each car scans at t = 0 of its episode (where the single env that built the episode would
have: the builder leaves it to the batch) and every period after; the engine casts every
due car's beams at once (``CarBatch.cast``) and the ranges are ``SimulatedLaser.ranges`` on
them (REP 117, noise from each car's own generator), written into the state's ``scan``
reading with the time it was taken.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smartcar_gym.envs.sensors.laser import SimulatedLaser
from smartcar_gym.envs.sensors.scan import LaserConfig
from smartcar_gym.envs.state import SCAN, SCAN_TIME, CarState


class BatchLaser:
    """``config``'s laser at ``mount`` on ``num`` cars."""

    def __init__(self, config: LaserConfig, mount: np.ndarray, num: int) -> None:
        #: the scanner's arithmetic (beams, ranges), shared by the cars
        self.laser = SimulatedLaser(config, mount)
        self.period_ns = self.laser.period_ns
        #: each car's next scan (ns on its clock)
        self.next_scan = np.zeros(num, dtype=np.int64)
        self.rngs: list[np.random.Generator | None] = [None] * num

    def start(self, car: int, rng: np.random.Generator | None) -> None:
        """Car ``car`` starts an episode: its noise from ``rng`` on, its next scan a period
        after the one at t = 0 (``scan``)."""
        self.next_scan[car] = self.period_ns
        self.rngs[car] = rng

    def fire(self, cars: Any, state: CarState, mask: np.ndarray) -> None:
        """The masked cars' scans due at their clocks."""
        due = mask & (self.next_scan <= state.now_ns)
        if due.any():
            self.scan(cars, state, np.flatnonzero(due))
            self.next_scan[due] += self.period_ns

    def scan(self, cars: Any, state: CarState, idx: np.ndarray) -> None:
        """``SimulatedLaser.scan`` for the listed cars: the engine casts, the ranges here."""
        laser = self.laser
        hit, fraction = cars.cast(idx, laser)
        ranges = state.readings[SCAN]
        if laser.config.noise_std_m > 0:
            for k, i in enumerate(idx.tolist()):
                ranges[i] = laser.ranges(fraction[k], hit[k], self.rngs[i])
        else:
            ranges[idx] = laser.ranges(fraction, hit, None)
        state.readings[SCAN_TIME][idx] = state.now_ns[idx]
