"""The ArbotiX board firmware's base controller (``ros.ino`` + ``diff_controller.h``).

An incremental integer PID per wheel, run in frames of at least ``FRAME_RATE + 1`` ms while
the base is moving, with the firmware's start/stop semantics and AVR integer widths (``int``
16-bit, ``long`` 32-bit, division truncating toward zero).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from smartcar_gym import checks
from smartcar_gym.controller._cint import wrap_int16, wrap_int32

MAX_OUTPUT = 255  # MAXOUTPUT: PWM limit
FRAME_RATE_MS = 33  # FRAME_RATE
BOOT_GAINS = (25, 30, 0, 100)  # setupPID(): Kp, Kd, Ki, Ko until the driver's setup packet
_B32, _M32, _B16, _M16 = 0x8000_0000, 0xFFFF_FFFF, 0x8000, 0xFFFF  # _cint's wraps, inlined


@dataclass
class WheelPID:
    """The firmware's ``SetPointInfo`` for one wheel (ticks per frame, ticks, PWM)."""

    velocity: int = 0  # int: target ticks/frame
    encoder: int = 0  # long: count read at the last frame
    prev_enc: int = 0  # long
    prev_err: int = 0  # int
    ierror: int = 0  # int
    output: int = 0  # int: current PWM, -255..255


class ArbotixBoard:
    """The board side of the ArbotiX base: setup/write packets in, PWM per side out."""

    def __init__(self, frame_ms: int = FRAME_RATE_MS) -> None:
        self.frame_ms = checks.positive_int("frame_ms", frame_ms)
        self.kp, self.kd, self.ki, self.ko = BOOT_GAINS
        self.f_time = 0  # setupPID(): f_time = 0
        self.moving = False
        self.pid_mode = False
        self.left = WheelPID()
        self.right = WheelPID()

    def setup(self, kp: int, kd: int, ki: int, ko: int) -> None:
        """The setup packet ``[10, Kp, Kd, Ki, Ko]``: one byte per gain, ``Ko`` >= 1."""
        for name, gain in (("Kp", kp), ("Kd", kd), ("Ki", ki)):
            checks.integer_in(name, gain, 0, 255, "one byte")
        checks.integer_in("Ko", ko, 1, 255, "one byte, and the firmware divides by it")
        self.kp, self.kd, self.ki, self.ko = kp, kd, ki, ko

    def write(self, left: int, right: int, encoders: tuple[int, int]) -> None:
        """The write packet: target ticks/frame per wheel, sent as 16-bit two's complement.

        Both 0: motors off and ``ClearPID`` (PID idle). From rest (both previous targets 0):
        arm the PID with ``PrevEnc`` = the current ``encoders`` counts. Otherwise only the
        targets change; the PID state is kept.
        """
        left, right = wrap_int16(left), wrap_int16(right)
        if left == 0 and right == 0:
            self._clear_pid()  # drive.set(0, 0); ClearPID()
        elif self.left.velocity == 0 and self.right.velocity == 0:
            self.pid_mode = self.moving = True
            self.left.prev_enc = wrap_int32(encoders[0])
            self.right.prev_enc = wrap_int32(encoders[1])
        self.left.velocity = left
        self.right.velocity = right

    def next_frame_ms(self) -> int | None:
        """The first ``millis()`` at which ``updatePID`` runs a frame; None while idle.

        Due when ``millis() > f_time``: at ``f_time + 1`` (a frame already due says so too).
        """
        if not (self.moving and self.pid_mode):
            return None
        return self.f_time + 1

    def frame_due(self, now_ms: int) -> bool:
        """Whether ``updatePID`` would run a frame at ``millis() == now_ms``."""
        return self.moving and self.pid_mode and now_ms > self.f_time

    def tick(self, now_ms: int, encoders: tuple[int, int]) -> bool:
        """One pass of ``updatePID``: run a PID frame if due; return whether one ran."""
        if not self.frame_due(now_ms):
            return False
        self.left.encoder = wrap_int32(encoders[0])
        self.right.encoder = wrap_int32(encoders[1])
        self._do_pid(self.left)
        self._do_pid(self.right)
        self.f_time = now_ms + self.frame_ms
        return True

    @property
    def pwm(self) -> tuple[int, int]:
        """The signed PWM on the (left, right) motor channels, -255..255."""
        return self.left.output, self.right.output

    def state(self) -> dict[str, Any]:
        """Gains, timing and per-wheel PID internals, for debugging."""
        return {
            "gains": (self.kp, self.kd, self.ki, self.ko),
            "moving": self.moving,
            "f_time_ms": self.f_time,
            "pwm": self.pwm,
            "left": asdict(self.left),
            "right": asdict(self.right),
        }

    def _do_pid(self, p: WheelPID) -> None:
        """``DoPid``: velocity-form PID with ``long`` error/output and ``int`` state.

        ``_cint``'s ``wrap_int32``, ``wrap_int16`` and ``c_div``, written out: this runs for
        each wheel at every PID frame, and a call costs more than the arithmetic (the same
        integers, tested against the calls).
        """
        delta = ((p.encoder - p.prev_enc + _B32) & _M32) - _B32
        perror = ((p.velocity - delta + _B32) & _M32) - _B32
        p_term = ((self.kp * perror + _B32) & _M32) - _B32
        d_term = ((self.kd * (((perror - p.prev_err + _B32) & _M32) - _B32) + _B32) & _M32) - _B32
        i_term = ((self.ki * p.ierror + _B16) & _M16) - _B16  # int * int: 16-bit product
        numerator = ((p_term + d_term + i_term + _B32) & _M32) - _B32
        ko = self.ko
        quotient = abs(numerator) // abs(ko)
        if (numerator >= 0) != (ko > 0):
            quotient = -quotient
        output = ((quotient + p.output + _B32) & _M32) - _B32
        p.prev_err = ((perror + _B16) & _M16) - _B16
        p.prev_enc = p.encoder
        if output >= MAX_OUTPUT:
            output = MAX_OUTPUT
        elif output <= -MAX_OUTPUT:
            output = -MAX_OUTPUT
        else:
            p.ierror = ((p.ierror + perror + _B16) & _M16) - _B16  # anti-windup: unsaturated
        p.output = output

    def _clear_pid(self) -> None:
        """``ClearPID``: idle, and zero error history and output (``PrevEnc`` is kept)."""
        self.pid_mode = self.moving = False
        for p in (self.left, self.right):
            p.prev_err = p.ierror = p.output = 0
