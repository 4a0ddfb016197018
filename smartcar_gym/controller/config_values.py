"""Checks of single ArbotiX config values, and the limits the emulated board's integers set.

Each checker takes ``(value, where)`` and returns the normalised value, or raises
``ControllerConfigError`` naming ``where`` (file and key), the value and what was expected.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from typing import Any

from smartcar_gym import checks


class ControllerConfigError(ValueError):
    """An ArbotiX controller configuration that upstream would reject or we cannot emulate."""


Checker = Callable[[Any, str], Any]

# -- the board's integers ----------------------------------------------------------------------
# The firmware runs on an AVR, where `int` is 16 bits and `long` 32. The driver sends each wheel
# target, int(speed * ticks_meter / 30) ticks per 1/30 s frame, as a 16-bit int (the firmware
# decodes `params[1] + (params[2] << 8)` into `int Velocity`); the encoder counts are 32-bit
# `long`s, which the driver's odometry differences as plain integers (a wrap is a jump).
INT16_MAX = 2**15 - 1
INT32_MAX = 2**31 - 1
FRAMES_PER_S = 30  # upstream's target unit: ticks per 1/30 s frame
# ticks_meter is refused above the value at which a 1 m/s wheel target no longer fits the 16-bit
# int: 32767 * 30 / 1 = 983010 ticks/m. No base this board drives needs more (the smartcar tops
# out at 0.84 m/s; the tutorial's encoders give 4100 ticks/m, and the board's pin-change
# interrupts could not count 983010 ticks/m at any useful speed anyway), and at this limit the
# 32-bit count still covers 2.18 km of wheel travel before it wraps. Which speeds a given
# ticks_meter allows is ArbotixConfig.max_target_speed_m_s.
MIN_TARGET_SPEED_M_S = 1.0
TICKS_METER_MAX = INT16_MAX * FRAMES_PER_S / MIN_TARGET_SPEED_M_S


def is_number(text: str) -> bool:
    """Whether ``float(text)`` accepts the string."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def close_hint(word: str, choices: Any) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``choices``, or ``""``."""
    match = difflib.get_close_matches(word, [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean {match[0]!r}?)" if match else ""


def number(value: Any, where: str) -> float:
    """A finite int or float (bools and numeric text refused, the latter with a YAML hint)."""
    if not checks.is_finite(value):
        hint = ""
        if isinstance(value, str) and is_number(value):
            hint = (
                " (a string: YAML 1.1 reads a number such as 1e-3 without a '.' as text; "
                "write 1.0e-3)"
            )
        raise ControllerConfigError(f"{where}: expected a finite number, got {value!r}{hint}")
    return float(value)


def positive(value: Any, where: str) -> float:
    """A finite number > 0."""
    result = number(value, where)
    if result <= 0:
        raise ControllerConfigError(f"{where}: must be > 0, got {value!r}")
    return result


def non_negative(value: Any, where: str) -> float:
    """A finite number >= 0."""
    result = number(value, where)
    if result < 0:
        raise ControllerConfigError(f"{where}: must be >= 0, got {value!r}")
    return result


def float_cast(value: Any, where: str) -> float:
    """A required key that upstream casts with ``float(...)``: numeric strings count."""
    if isinstance(value, str) and is_number(value):
        value = float(value)
    return positive(value, where)


def ticks_meter(value: Any, where: str) -> float:
    """``float_cast``, and at most ``TICKS_METER_MAX``: more overflows the board's integers."""
    result = float_cast(value, where)
    if result > TICKS_METER_MAX:
        raise ControllerConfigError(
            f"{where}: {result:g} ticks/m overflows the emulated board's integers: a 1 m/s wheel "
            f"target would be {MIN_TARGET_SPEED_M_S * result / FRAMES_PER_S:.6g} ticks per 1/30 s "
            f"frame, beyond the 16-bit int the board takes ({INT16_MAX}), and its 32-bit "
            f"encoder count would wrap after {1000 * (INT32_MAX + 1) / result:.3g} mm of travel; "
            f"expected at most {TICKS_METER_MAX:.0f} (a 16-bit target up to "
            f"{MIN_TARGET_SPEED_M_S:g} m/s)"
        )
    return result


def integer(value: Any, where: str, low: int, high: int, why: str) -> int:
    """An int (not a bool, not a float) in ``low..high``; ``why`` says where the range is from."""
    if not (checks.is_whole(value) and low <= value <= high):
        raise ControllerConfigError(
            f"{where}: expected an integer in {low}..{high} ({why}), got {value!r}"
        )
    return value


def gain(value: Any, where: str) -> int:
    """Kp, Kd, Ki: one byte each in the setup packet."""
    return integer(value, where, 0, 255, "the driver sends each gain as one byte")


def ko(value: Any, where: str) -> int:
    """Ko: one byte, and a divisor in the firmware."""
    return integer(value, where, 1, 255, "one byte, and the firmware divides by it")


def frame_ms(value: Any, where: str) -> int:
    """The firmware's FRAME_RATE in ms."""
    return integer(value, where, 1, 1000, "the firmware's FRAME_RATE in ms")


def text(value: Any, where: str) -> str:
    """A non-empty string."""
    if not isinstance(value, str) or not value.strip():
        raise ControllerConfigError(f"{where}: expected a non-empty string, got {value!r}")
    return value


def flag(value: Any, where: str) -> bool:
    """A YAML boolean."""
    if not isinstance(value, bool):
        raise ControllerConfigError(f"{where}: expected true or false, got {value!r}")
    return value


PWM_ZERO_MODES = ("coast", "brake")


def pwm_zero(value: Any, where: str) -> str:
    """What PWM 0 does: one of ``PWM_ZERO_MODES``."""
    if value not in PWM_ZERO_MODES:
        raise ControllerConfigError(f"{where}: expected one of {PWM_ZERO_MODES}, got {value!r}")
    return value
