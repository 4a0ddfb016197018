"""Wheel encoders that count the way a real robot's do: off scale, noisy, slipping.

``WheelEncoder`` counts exactly ``ticks_meter`` ticks per metre of wheel-surface travel, so the
odometry agrees with the wheels. A real encoder does not: its true count per metre differs from
the YAML's ``ticks_meter`` (an empirical 4100 for a nominal 4773 in the tutorial's own comment),
single readings jitter by a tick or so, and counts are gained or lost as it runs.
"""

from __future__ import annotations

import math

import numpy as np

from smartcar_gym.checks import is_real
from smartcar_gym.controller._cint import wrap_int32
from smartcar_gym.controller.encoder import WheelEncoder


class FaultyEncoder(WheelEncoder):
    """A ``WheelEncoder`` whose count is off scale, jittered and slipping.

    Args:
        wheel_radius_m, ticks_meter: as ``WheelEncoder`` (what the YAML claims).
        scale: true ticks per metre / ``ticks_meter`` (1: exact).
        noise_ticks: standard deviation (ticks) of a zero-mean error added to each reading and
            not carried to the next (read timing, edge bounce); rounded to whole ticks.
        slip: standard deviation of the relative error of the ticks counted between two
            readings (each reading's increment is multiplied by ``1 + slip * N(0, 1)``); the
            error stays in the count, so it accumulates like real missed or extra counts.
        rng: the generator of the noise (seeded by the caller: same seed, same counts).
    """

    def __init__(self, wheel_radius_m: float, ticks_meter: float, scale: float = 1.0,
                 noise_ticks: float = 0.0, slip: float = 0.0,
                 rng: np.random.Generator | None = None) -> None:
        super().__init__(wheel_radius_m, ticks_meter)
        if not (is_real(scale) and math.isfinite(scale) and scale > 0):
            raise ValueError(f"FaultyEncoder scale must be a finite number > 0, got {scale!r}")
        for name, value in (("noise_ticks", noise_ticks), ("slip", slip)):
            if not (is_real(value) and math.isfinite(value) and value >= 0):
                raise ValueError(f"FaultyEncoder {name} must be a finite number >= 0, got "
                                 f"{value!r}")
        if (noise_ticks > 0 or slip > 0) and rng is None:
            raise ValueError("FaultyEncoder with noise or slip needs a seeded rng")
        self.scale = float(scale)
        self.noise_ticks = float(noise_ticks)
        self.slip = float(slip)
        self.rng = rng
        self._travel = 0.0  # true ticks at the last reading (float)
        self._counted = 0.0  # ticks counted so far, slip included (float)

    @property
    def exact(self) -> bool:
        """No fault: on scale, no noise, no slip (it counts as a ``WheelEncoder``)."""
        return self.scale == 1.0 and not self.noise_ticks and not self.slip

    def reset(self, angle_rad: float, phase_ticks: float = 0.0) -> None:
        super().reset(angle_rad, phase_ticks)
        self._travel = self._counted = phase_ticks * self.scale

    def count(self, angle_rad: float) -> int:
        travel = (angle_rad - self.zero_angle_rad) * self.wheel_radius_m * self.ticks_meter
        travel *= self.scale
        if not math.isfinite(travel):
            raise ValueError(f"wheel angle {angle_rad!r} rad gives no encoder count")
        if self.slip > 0:
            self._counted += (travel - self._travel) * (1.0 + self.slip
                                                        * self.rng.standard_normal())
            self._travel = travel
            counted = self._counted
        else:
            counted = travel
        jitter = round(self.noise_ticks * self.rng.standard_normal()) if self.noise_ticks else 0
        return wrap_int32(math.floor(counted) + jitter)
