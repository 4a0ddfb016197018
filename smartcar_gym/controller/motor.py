"""A side's DC gearmotor driven by the ArbotiX PWM: a linear torque-speed curve."""

from __future__ import annotations

from dataclasses import dataclass

from smartcar_gym.controller.config import MotorConfig

MAX_PWM = 255


@dataclass(frozen=True)
class MotorOutput:
    """What the simulator applies to a side's wheels in all: ``drive - damping*omega`` (N m)."""

    drive_torque_nm: float
    damping_nm_s_per_rad: float

    def torque(self, omega_rad_s: float) -> float:
        """Torque (N m) at wheel speed ``omega_rad_s`` (forward-positive)."""
        return self.drive_torque_nm - self.damping_nm_s_per_rad * omega_rad_s


COAST = MotorOutput(0.0, 0.0)


class DCMotor:
    """Linear DC-motor model at the wheel: ``torque = stall*pwm/255 - (stall/no_load)*omega``.

    The two parts are exposed separately because the simulator applies the speed-dependent part
    implicitly (as joint damping, stable at any step) and the drive part as a joint torque,
    both updated only when the PWM changes. At PWM 0 with ``pwm_zero: coast`` the ArbotiX
    disconnects the output, so there is no back-EMF braking either.
    """

    def __init__(self, config: MotorConfig) -> None:
        self.config = config
        self.back_emf_damping = config.stall_torque_nm / config.no_load_speed_rad_s

    def drive_torque(self, pwm: int) -> float:
        """Torque (N m) at zero speed for a signed PWM, capped at +-255 like ``Motors2::set``."""
        pwm = max(-MAX_PWM, min(MAX_PWM, pwm))
        return self.config.stall_torque_nm * pwm / MAX_PWM

    def damping(self, pwm: int) -> float:
        """Back-EMF damping (N m s/rad): 0 when PWM 0 disconnects the motor (``coast``)."""
        if pwm == 0 and self.config.pwm_zero == "coast":
            return 0.0
        return self.back_emf_damping

    def torque(self, pwm: int, omega_rad_s: float) -> float:
        """Wheel torque (N m) for a signed PWM at wheel speed ``omega_rad_s``."""
        return self.drive_torque(pwm) - self.damping(pwm) * omega_rad_s

    def output(self, pwm: int) -> MotorOutput:
        """The drive torque and damping for a PWM, as the simulator applies them."""
        return MotorOutput(self.drive_torque(pwm), self.damping(pwm))
