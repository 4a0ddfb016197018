"""Quadrature wheel encoders as the ArbotiX counts them: cumulative signed 32-bit ticks."""

from __future__ import annotations

import math

from smartcar_gym.controller._cint import wrap_int32


def ticks_from_angle(angle_rad: float, wheel_radius_m: float, ticks_meter: float) -> int:
    """Encoder count for a forward-positive wheel angle: ``floor(angle*r*ticks_meter)``, int32.

    The count wraps like the firmware's ``long`` counter (after 2^31 ticks, about 524 km at
    4100 ticks/m).
    """
    travel_ticks = angle_rad * wheel_radius_m * ticks_meter
    if not math.isfinite(travel_ticks):
        raise ValueError(f"wheel angle {angle_rad!r} rad gives no encoder count")
    return wrap_int32(math.floor(travel_ticks))


class WheelEncoder:
    """One wheel's encoder: counts ticks of wheel travel since ``reset`` (board power-up)."""

    #: whether it counts exactly ``ticks_meter`` ticks a metre (a batch counts those in arrays)
    exact = True

    def __init__(self, wheel_radius_m: float, ticks_meter: float) -> None:
        if not wheel_radius_m > 0 or not ticks_meter > 0:
            raise ValueError(
                f"wheel_radius_m and ticks_meter must be > 0, got {wheel_radius_m}, {ticks_meter}"
            )
        self.wheel_radius_m = float(wheel_radius_m)
        self.ticks_meter = float(ticks_meter)
        self.zero_angle_rad = 0.0

    def reset(self, angle_rad: float, phase_ticks: float = 0.0) -> None:
        """Zero the count at the wheel's current angle (the firmware's counters start at 0).

        ``phase_ticks``: where the wheel stands within its first tick, in ticks past the edge
        that counts it backwards: 0 on that edge (the least creep back counts -1), 0.5 in the
        middle (half a tick either way before the count changes).
        """
        if not 0.0 <= phase_ticks < 1.0:
            raise ValueError(f"encoder phase_ticks must be in [0, 1), got {phase_ticks!r}")
        self.zero_angle_rad = float(angle_rad) - phase_ticks / (
            self.wheel_radius_m * self.ticks_meter)

    def count(self, angle_rad: float) -> int:
        """Ticks since ``reset`` for the wheel's current forward-positive angle."""
        return ticks_from_angle(
            angle_rad - self.zero_angle_rad, self.wheel_radius_m, self.ticks_meter
        )
