"""The emulated ArbotiX base: host controller, board, encoders and motors, wired together.

The simulator is reached only through the narrow ``WheelDrive`` protocol, so this module (like
the whole ``controller`` package) imports no physics engine.
"""

from __future__ import annotations

from typing import Any, Protocol

from smartcar_gym.controller.board import ArbotixBoard
from smartcar_gym.controller.config import ArbotixConfig
from smartcar_gym.controller.diff_controller import (
    FRAMES_PER_S,
    HARDWARE,
    KINEMATIC,
    MODES,
    DiffController,
    Mode,
    Odometry,
)
from smartcar_gym.controller.encoder import WheelEncoder
from smartcar_gym.controller.motor import DCMotor, MotorOutput


class WheelDrive(Protocol):
    """What the base needs from the simulator."""

    def encoder_angles(self) -> tuple[float, float]:
        """Forward-positive cumulative angles (rad) of the left and right encoder wheels."""
        ...

    def set_motor_output(self, left: MotorOutput, right: MotorOutput) -> None:
        """Apply each side's output, shared by the wheels of that side, until the next call.

        Each physics step the simulator applies ``drive - damping*omega`` per wheel.
        """
        ...


def board_millis(now_s: float) -> int:
    """The board's ``millis()`` at simulated time ``now_s`` (board booted at t = 0)."""
    return int(now_s * 1000.0 + 1e-6)


class ArbotixBase:
    """The ArbotiX ROS driver's base controller and board, in ``hardware`` or ``sim`` mode.

    ``hardware``: ``cmd_vel`` -> integer wheel targets -> slew limit -> board write; the board's
    PID frames (``board_tick``) turn encoder counts into PWM, and the DC-motor model into
    wheel torques applied through ``drive``; odometry comes from the encoders. ``sim`` (the
    driver's ``sim: true``): odometry integrates the commanded twist, which the simulator
    applies kinematically (``commanded_twist``); no drive, PID or timeout effect.

    Joint states are not produced here: the simulator reports the real wheel angles. Upstream
    publishes ``base_l_wheel_joint``/``base_r_wheel_joint`` always at 0 in both modes.

    Call ``reset`` (after the wheels exist) before use, ``board_tick`` whenever the board's next
    frame is due (``next_frame_ms``; calling it more often is harmless), and ``update`` once per
    controller period (``1/config.rate_hz``).
    """

    def __init__(
        self,
        config: ArbotixConfig,
        mode: Mode,
        wheel_radius_m: float,
        drive: WheelDrive | None = None,
        encoder_phase_ticks: float = 0.0,
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if mode == HARDWARE and drive is None:
            raise ValueError("hardware mode needs a WheelDrive to read encoders and drive motors")
        self.config = config
        self.mode: Mode = mode
        self.drive = drive
        #: where each wheel stands within its first encoder tick at ``reset`` (see WheelEncoder)
        self.encoder_phase_ticks = encoder_phase_ticks
        self.motor = DCMotor(config.motor)
        self.encoders = (
            WheelEncoder(wheel_radius_m, config.ticks_meter),
            WheelEncoder(wheel_radius_m, config.ticks_meter),
        )
        self.controller = DiffController(config, mode, 0.0)
        self.board = ArbotixBoard(config.frame_ms)
        self.ticks: tuple[int, int] = (0, 0)
        self._applied_pwm: tuple[int, int] = (0, 0)
        self._ready = mode == KINEMATIC

    # -- lifecycle -------------------------------------------------------------------------
    def reset(self, now_s: float = 0.0) -> None:
        """Power up afresh at ``now_s``: new controller and board, encoders zeroed, motors off."""
        self.controller = DiffController(self.config, self.mode, now_s)
        self.board = ArbotixBoard(self.config.frame_ms)
        self.ticks = (0, 0)
        self._applied_pwm = (0, 0)
        if self.mode == HARDWARE:
            drive = self._wheel_drive()
            left, right = drive.encoder_angles()
            self.encoders[0].reset(left, self.encoder_phase_ticks)
            self.encoders[1].reset(right, self.encoder_phase_ticks)
            self.board.setup(*self.config.gains)
            drive.set_motor_output(self.motor.output(0), self.motor.output(0))
        self._ready = True

    # -- host side -------------------------------------------------------------------------
    def cmd_vel(self, linear_x: float, angular_z: float, now_s: float) -> None:
        """A ``cmd_vel`` message at ``now_s`` (m/s, rad/s)."""
        self.controller.cmd_vel(linear_x, angular_z, now_s)

    def update(self, now_s: float) -> Odometry:
        """One controller firing: odometry, timeout, and (hardware) the write to the board."""
        self._check_ready()
        if self.mode == KINEMATIC:
            return self.controller.update(now_s, None)
        ticks = self._read_encoders()
        odometry = self.controller.update(now_s, ticks)
        written = self.controller.last_write
        if written is not None:
            self.board.write(written[0], written[1], ticks)
            self._apply_pwm()
        return odometry

    # -- board side ------------------------------------------------------------------------
    def next_frame_ms(self) -> int | None:
        """The board's ``millis()`` of its next PID frame; None while it idles (or in sim mode)."""
        if self.mode == KINEMATIC:
            return None
        return self.board.next_frame_ms()

    def board_tick(self, now_s: float) -> None:
        """Let the board run a PID frame if one is due at ``now_s``; cheap otherwise."""
        if self.mode == KINEMATIC:
            return
        now_ms = board_millis(now_s)
        if not self.board.frame_due(now_ms):
            return
        self._check_ready()
        self.board.tick(now_ms, self._read_encoders())
        self._apply_pwm()

    # -- views -----------------------------------------------------------------------------
    @property
    def odometry(self) -> Odometry:
        """The latest published odometry."""
        return self.controller.odometry

    @property
    def commanded_twist(self) -> tuple[float, float]:
        """(v m/s, w rad/s) actually commanded.

        Sim mode: the latest ``cmd_vel`` (kept after the timeout, as upstream). Hardware: the
        wheel speeds last written to the board, converted back at upstream's 30 frames/s.
        """
        c = self.controller
        if self.mode == KINEMATIC:
            return c.dx, c.dr
        scale = FRAMES_PER_S / self.config.ticks_meter
        left, right = c.v_left * scale, c.v_right * scale
        return (left + right) / 2.0, (right - left) / self.config.base_width_m

    def state(self) -> dict[str, Any]:
        """Controller and board internals, for debugging and ``info`` dicts."""
        c = self.controller
        return {
            "mode": self.mode,
            "v_des": (c.v_des_left, c.v_des_right),
            "v": (c.v_left, c.v_right),
            "last_write": c.last_write,
            "last_cmd_s": c.last_cmd,
            "commanded_twist": self.commanded_twist,
            "pwm": self.board.pwm,
            "encoder_ticks": self.ticks,
            "board": self.board.state(),
        }

    # -- internals -------------------------------------------------------------------------
    def _check_ready(self) -> None:
        if not self._ready:
            raise RuntimeError("ArbotixBase.reset() must be called before use in hardware mode")

    def _wheel_drive(self) -> WheelDrive:
        if self.drive is None:
            raise RuntimeError("no WheelDrive attached")
        return self.drive

    def _read_encoders(self) -> tuple[int, int]:
        left, right = self._wheel_drive().encoder_angles()
        self.ticks = (self.encoders[0].count(left), self.encoders[1].count(right))
        return self.ticks

    def _apply_pwm(self) -> None:
        """Send the board's PWM to the motors if it changed since the last time."""
        pwm = self.board.pwm
        if pwm != self._applied_pwm:
            left, right = self.motor.output(pwm[0]), self.motor.output(pwm[1])
            self._wheel_drive().set_motor_output(left, right)
            self._applied_pwm = pwm
