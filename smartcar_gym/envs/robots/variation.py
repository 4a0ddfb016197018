"""How the simulated robot differs from its model and its YAML: the plant of one episode.

A ``Variation`` says, factor by factor, what the real robot would have that its description
does not claim: other masses and friction, other motors, bigger or smaller wheels, a wider or
narrower effective track, encoders that count off scale, jitter and slip, and commands that
arrive late. ``SmartCarRobot.vary`` takes one before ``spawn``; everything here is applied at
spawn through the simulator facade (body dynamics, force-limited motors) or in the emulated
controller (motor model, encoders, command delay), never by calling pybullet directly.

Every factor is a plain number with a neutral value (1 for the scales, 0 for the others), and a
neutral factor is not applied at all: ``Variation()`` gives the nominal robot bit for bit.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.controller.encoder_faults import FaultyEncoder
from smartcar_gym.model import RobotModel, Wheel
from smartcar_gym.model.contact import round_wheel_shapes
from smartcar_gym.model.urdf import parse_xml, serialize_xml
from smartcar_gym.sim.contracts import BASE, Body
from smartcar_gym.sim.dynamics import scale_lateral_friction, scale_mass


@dataclass(frozen=True)
class Variation:
    """One episode's plant, relative to the model and YAML (scales are true / claimed).

    Attributes:
        wheel_friction: scale of the drive wheels' lateral friction coefficient.
        base_mass, wheel_mass: scales of the base link's and each drive wheel's mass (and
            inertia).
        stall_torque, no_load_speed, gearbox_friction, reflected_inertia: scales of the
            YAML's ``smartcar_gym.motor`` values (the side's gearmotor as the wheels see it).
        wheel_radius: scale of the drive wheels' true radius (their round collision shapes).
            The encoders still convert angle to travel with the model's radius.
        track: scale of the true effective track against the model's: the emulated driver
            converts twists and encoder counts with ``base_width / track`` (see ``config``).
        left_encoder_scale, right_encoder_scale: true encoder ticks per metre of wheel travel
            / the YAML's ``ticks_meter``.
        encoder_noise: standard deviation (ticks) of each reading's jitter.
        encoder_slip: standard deviation of the relative error of each reading's increment.
        latency: delay of every ``cmd_vel``, in controller periods.
        noise_seed: seeds the encoder noise and slip.
    """

    wheel_friction: float = 1.0
    base_mass: float = 1.0
    wheel_mass: float = 1.0
    stall_torque: float = 1.0
    no_load_speed: float = 1.0
    gearbox_friction: float = 1.0
    reflected_inertia: float = 1.0
    wheel_radius: float = 1.0
    track: float = 1.0
    left_encoder_scale: float = 1.0
    right_encoder_scale: float = 1.0
    encoder_noise: float = 0.0
    encoder_slip: float = 0.0
    latency: int = 0
    noise_seed: int = 0

    # -- the emulated controller ---------------------------------------------------------------
    def config(self, claimed: ArbotixConfig) -> ArbotixConfig:
        """The configuration the emulation runs with: the true motor, and the track.

        The motor section of the YAML describes the plant, so its values are scaled. The
        track: a robot whose effective track is ``track`` times the model's turns, for the wheel
        speeds a twist asks, ``1 / track`` times as fast as the model, and its odometry (which
        divides by the YAML's ``base_width``) overstates its turns by ``track`` times what it
        does for the model. Dividing the driver's ``base_width`` by ``track`` gives exactly
        these wheel speeds and this odometry; the contact geometry (how much the skid-steer
        slips) stays the model's.
        """
        motor = claimed.motor
        scaled = {
            "stall_torque_nm": (motor.stall_torque_nm, self.stall_torque),
            "no_load_speed_rad_s": (motor.no_load_speed_rad_s, self.no_load_speed),
            "friction_torque_nm": (motor.friction_torque_nm, self.gearbox_friction),
            "reflected_inertia_kg_m2": (motor.reflected_inertia_kg_m2, self.reflected_inertia),
        }
        changes = {k: value * scale for k, (value, scale) in scaled.items() if scale != 1.0}
        config = claimed
        if changes:
            config = dataclasses.replace(config, motor=dataclasses.replace(motor, **changes))
        if self.track != 1.0:
            config = dataclasses.replace(config, base_width_m=claimed.base_width_m / self.track)
        return config

    def encoders(self, wheel_radius_m: float, ticks_meter: float) -> tuple[FaultyEncoder,
                                                                            FaultyEncoder]:
        """The (left, right) encoders, sharing one generator seeded with ``noise_seed``."""
        rng = np.random.default_rng(self.noise_seed)
        return tuple(
            FaultyEncoder(wheel_radius_m, ticks_meter, scale, self.encoder_noise,
                          self.encoder_slip, rng)
            for scale in (self.left_encoder_scale, self.right_encoder_scale)
        )

    # -- the body ------------------------------------------------------------------------------
    def urdf(self, text: str, model: RobotModel) -> str:
        """The simulated URDF ``text`` with the drive wheels' round collision shapes resized.

        In each drive wheel link the first cylinder or sphere collision (the one that gives the
        wheel its radius) gets ``wheel_radius`` times its radius; visuals and inertia are kept.
        """
        if self.wheel_radius == 1.0:
            return text
        root = parse_xml(text, str(model.source))
        for shape in round_wheel_shapes(root, model):
            shape.set("radius", repr(float(shape.get("radius")) * self.wheel_radius))
        return serialize_xml(root)

    def spawn_height(self, wheels: Sequence[Wheel]) -> float:
        """Height of base_link above the ground when every (resized) wheel touches it."""
        return max(w.radius_m * self.wheel_radius - w.position_m[2] for w in wheels)

    def apply_to_body(self, body: Body, wheel_links: Sequence[int]) -> None:
        """Masses and wheel friction of a body just loaded (before it settles)."""
        if self.base_mass != 1.0:
            scale_mass(body, [BASE], self.base_mass)
        if self.wheel_mass != 1.0:
            scale_mass(body, wheel_links, self.wheel_mass)
        if self.wheel_friction != 1.0:
            scale_lateral_friction(body, wheel_links, self.wheel_friction)
