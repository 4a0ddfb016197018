"""The smartcar robot: a diff-drive body in the simulator plus its emulated ArbotiX base.

It takes ``cmd_vel`` twists and reports what the ROS driver publishes (odometry) and the wheel
``joint_states``, plus its ground-truth pose (which a real robot does not know: for rewards and
``info``). It is an event source of the simulator: the controller fires every ``1 / rate`` s and
the board runs a PID frame whenever the firmware would; the simulator steps the physics between
those instants. In ``hardware`` mode the wheels are driven by the board's PWM through the
DC-motor model; in ``sim`` mode (the driver's ``sim: true``, kinematic) the body follows the
commanded twist and no physics is stepped.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from smartcar_gym.controller import (
    HARDWARE,
    KINEMATIC,
    MODES,
    ArbotixBase,
    ArbotixConfig,
    MotorOutput,
    Odometry,
)
from smartcar_gym.controller.latency import CommandDelay
from smartcar_gym.envs.robots.variation import Variation
from smartcar_gym.model import ModelError, RobotModel, Wheel
from smartcar_gym.model.contact import WheelContact, simulated_urdf
from smartcar_gym.sim.clock import NS_PER_S, seconds_to_ns
from smartcar_gym.sim.contracts import BASE, Body, ConvergesContacts, Simulator

GEAR_MAX_FORCE_NM = 100.0  # the chain between a side's wheels: far above any motor torque
SETTLE_S = 0.1  # wheels onto the ground before the controller starts
# A differential-drive robot's encoders start mid-tick: on the edge, the sign of each standing
# wheel's rounding-sized creep decided whether it counted -1, and one count split the sides'
# PWM for good (docs/stepping.md, "Driving straight").
DIFFERENTIAL_ENCODER_PHASE_TICKS = 0.5


@dataclass(frozen=True)
class JointStates:
    """A ``sensor_msgs/JointState`` for the wheel joints: rad, rad/s, N m."""

    name: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


@dataclass(frozen=True)
class Pose2D:
    """Ground-truth planar pose of ``base_link`` in the world (m, m, rad) and its uprightness."""

    x: float
    y: float
    yaw: float
    z: float
    up_z: float  # z component of base_link's z axis: 1 upright, < 0 upside down


def pose_from(position: tuple[float, float, float],
              orientation: tuple[float, float, float, float]) -> Pose2D:
    """A ``Pose2D`` from a position and an (x, y, z, w) quaternion."""
    qx, qy, qz, qw = orientation
    yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    up_z = 1.0 - 2.0 * (qx * qx + qy * qy)
    return Pose2D(position[0], position[1], yaw, position[2], up_z)


class SmartCarRobot:
    """A wheeled robot model plus its emulated ArbotiX base controller in a ``Simulator``.

    Args:
        sim: the simulator facade that owns the pybullet client and the clock.
        model: the loaded robot model (see ``smartcar_gym.load_model``).
        config: the ArbotiX controller configuration.
        mode: ``"hardware"`` (PID, encoders, DC motors) or ``"sim"`` (kinematic, as the
            driver's ``sim: true``).
        name: body name in the simulator.
        wheel_contact: ``"sphere"`` (one ground contact per drive wheel) or ``"urdf"`` (the
            model's own wheel collision shapes); see ``smartcar_gym.model.contact``.

    Use: ``spawn`` into a freshly reset world, then ``cmd_vel`` and ``sim.run_until``; read
    ``odometry``, ``joint_states()`` and ``pose()``. ``vary`` before ``spawn`` makes the robot
    differ from its model and YAML (domain randomisation).

    A differential-drive model (one drive wheel per side, ``model.drive_kind``) spawns with its
    contacts solved to convergence (``contracts.ConvergesContacts``) and its encoders starting
    mid-tick, so that a mirror-symmetric robot drives straight; a skid base (the smartcar)
    steps exactly as before.
    """

    def __init__(
        self,
        sim: Simulator,
        model: RobotModel,
        config: ArbotixConfig,
        mode: str = HARDWARE,
        name: str = "smartcar",
        wheel_contact: WheelContact = "sphere",
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"controller_mode must be one of {MODES}, got {mode!r}")
        if model.errors:  # a model from inspect_model(): simulated, it would explode
            raise ModelError(
                "non-physical model, cannot be simulated: "
                + "; ".join(f"{d.element}: {d.kind}: {d.message}" for d in model.errors),
                file=model.source,
            )
        self._urdf = simulated_urdf(model, wheel_contact)  # ValueError naming a bad choice
        self.wheel_contact = wheel_contact
        self.sim = sim
        self.model = model
        self.config = config
        self.mode = mode
        self.name = name
        self.wheels: tuple[Wheel, ...] = tuple(model.left_wheels) + tuple(model.right_wheels)
        self.encoder_wheels = (
            self._encoder_wheel("left", config.encoder_left),
            self._encoder_wheel("right", config.encoder_right),
        )
        #: where the encoders start within their first tick (0 for a skid base, as ever)
        self.encoder_phase_ticks = (DIFFERENTIAL_ENCODER_PHASE_TICKS
                                    if model.drive_kind == "differential" else 0.0)
        self.base = self._new_base(config)
        #: the controller's period (ns): it fires at every whole multiple of it after spawn
        self.update_period_ns = seconds_to_ns(1.0 / config.rate_hz)
        # Height of base_link above the ground when every wheel touches it.
        self.spawn_z = max(w.radius_m - w.position_m[2] for w in self.wheels)
        self.body: Body | None = None
        self._wheel_idx: list[int] = []
        #: the simulator's joint indices of the encoder wheels, left then right (after spawn)
        self.encoder_joint_indices: list[int] = []
        #: per wheel of ``wheels``: its joint's forward sign (a forward torque is sign times it)
        self.wheel_signs = [float(w.forward_sign) for w in self.wheels]
        #: each encoder wheel's forward sign (its joint angle times it: forward-positive)
        self.encoder_signs = tuple(w.forward_sign for w in self.encoder_wheels)
        #: per wheel: whether the left motor drives it (else the right)
        self.wheel_left = [w.side == "left" for w in self.wheels]
        # Each side's motor drives its wheels through a 1:1 chain: they share its output.
        n_left = sum(self.wheel_left)
        #: per wheel: its share of its side's motor output (1 / the side's wheel count)
        self.wheel_shares = [1.0 / n_left if left else 1.0 / (len(self.wheels) - n_left)
                             for left in self.wheel_left]
        self._torque = [0.0] * len(self.wheels)
        self._damping = [0.0] * len(self.wheels)
        self._next_update_ns = 0
        self._last_update_ns = 0
        self._kinematic_pose = (0.0, 0.0, 0.0)
        #: the plant of the next spawn (None: the model and YAML as written); see ``vary``
        self.variation: Variation | None = None
        self._nominal = (config, self._urdf, self.spawn_z)
        self._delay: CommandDelay | None = None

    def vary(self, variation: Variation | None) -> None:
        """Make the next ``spawn`` build this plant; None: the model and YAML as written.

        ``config`` and ``base`` become the emulation's (true motor, effective track), the
        wheels are resized, and encoders, command latency, masses and wheel friction follow
        ``variation`` until the next call.
        """
        config, urdf, spawn_z = self._nominal
        self._delay = None
        if variation is not None:
            config = variation.config(config)
            urdf = variation.urdf(urdf, self.model)
            spawn_z = variation.spawn_height(self.wheels)
            if variation.latency:
                self._delay = CommandDelay(variation.latency, self.update_period_ns)
        self.variation = variation
        self.config, self._urdf, self.spawn_z = config, urdf, spawn_z
        self.base = self._new_base(config)
        if variation is not None:
            self.base.encoders = variation.encoders(self.model.wheel_radius_m,
                                                    config.ticks_meter)

    def _new_base(self, config: ArbotixConfig) -> ArbotixBase:
        return ArbotixBase(config, self.mode, self.model.wheel_radius_m, drive=self,
                           encoder_phase_ticks=self.encoder_phase_ticks)

    @property
    def command_delay(self) -> CommandDelay | None:
        """The line ``cmd_vel`` waits in (``Variation.latency``; None: no latency)."""
        return self._delay

    @property
    def wheel_joint_indices(self) -> list[int]:
        """The simulator's joint indices of ``wheels`` (after ``spawn``)."""
        return self._wheel_idx

    @property
    def kinematic(self) -> bool:
        """True in ``sim`` mode: the body is moved kinematically, no physics is stepped."""
        return self.mode == KINEMATIC

    def _encoder_wheel(self, side: str, choice: str) -> Wheel:
        candidates = self.model.left_wheels if side == "left" else self.model.right_wheels
        if choice == "auto":
            return max(candidates, key=lambda w: w.position_m[0])  # the front-most wheel
        for wheel in candidates:
            if choice in (wheel.joint, wheel.link):
                return wheel
        raise ValueError(
            f"{self.config.source}: smartcar_gym.encoder.{side}: {choice!r} is not a {side} drive "
            f"wheel of {self.model.source}; {side} wheels: {[w.joint for w in candidates]}"
        )

    # -- lifecycle -----------------------------------------------------------------------------
    def spawn(
        self, x: float = 0.0, y: float = 0.0, yaw: float = 0.0, settle_s: float = SETTLE_S
    ) -> None:
        """Load the robot into a freshly reset world, let it settle, and start the controller.

        The simulator settles the world before its clock starts, so the controller starts at
        t = 0 with its odometry origin at the robot's pose; it fires first at t = 1 / rate.
        """
        sim = self.sim
        # pybullet parses the file while loading it; the next spawn overwrites it
        urdf_path = self.model.write_urdf(sim.scratch_dir, self._urdf)
        body = sim.load_urdf(self.name, urdf_path, (x, y, self.spawn_z), yaw)
        self.body = body
        # its yaw feels any lopsided solve (an engine that solves contacts exactly has no
        # solver to converge)
        if self.model.drive_kind == "differential" and isinstance(sim, ConvergesContacts):
            sim.converge_contacts()
        self._wheel_idx = [body.joint_index(w.joint) for w in self.wheels]
        self.encoder_joint_indices = [body.joint_index(w.joint) for w in self.encoder_wheels]
        if self.variation is not None:
            self.variation.apply_to_body(body, self._wheel_idx)
        # pybullet's velocity motor on each wheel, held at speed 0 with at most the gearbox's
        # friction torque, is the gearbox's Coulomb friction; the DC motors add their torque.
        body.set_velocity_motors(
            self._wheel_idx, [0.0] * len(self.wheels),
            [share * self.config.motor.friction_torque_nm for share in self.wheel_shares],
            key="gearbox",
        )
        for wheel, idx, share in zip(self.wheels, self._wheel_idx, self.wheel_shares, strict=True):
            # The side's gearmotor rotor, seen through the gearbox, spins with the wheels: add
            # this wheel's share of its inertia about the axle (the joint axis).
            body.clear_damping(idx)
            body.add_axle_inertia(idx, self.model.joints[wheel.joint].axis,
                                  share * self.config.motor.reflected_inertia_kg_m2)
        self._chain_wheels(body)
        body.clear_damping(BASE)
        self._torque = [0.0] * len(self.wheels)
        self._damping = [0.0] * len(self.wheels)
        body.hold_torques(self._wheel_idx, self._torque, key="motors")
        self._kinematic_pose = (x, y, yaw)  # sim mode keeps the pose in doubles
        if not self.kinematic and settle_s > 0:
            sim.settle(settle_s)
        self.base.reset(sim.time_s)
        if self._delay is not None:
            self._delay.clear()
        self._last_update_ns = sim.now_ns
        self._next_update_ns = sim.now_ns + self.update_period_ns
        sim.add_event_source(self)

    def _chain_wheels(self, body: Body) -> None:
        """Link each side's wheels to its first wheel 1:1 with gear constraints (the chain)."""
        for side in ("left", "right"):
            idx = [i for w, i in zip(self.wheels, self._wheel_idx, strict=True) if w.side == side]
            signs = [w.forward_sign for w in self.wheels if w.side == side]
            for other, sign in zip(idx[1:], signs[1:], strict=True):
                # the gear constraint holds q0 + ratio * q1 = const: equal forward speeds
                body.add_gear(idx[0], other, -signs[0] * sign, GEAR_MAX_FORCE_NM)

    # -- commands ------------------------------------------------------------------------------
    def cmd_vel(self, linear_x: float, angular_z: float) -> None:
        """A ``geometry_msgs/Twist`` on ``cmd_vel`` now (m/s, rad/s); acts at the next update
        (or ``latency`` updates later, see ``vary``)."""
        if self._delay is not None:
            self._delay.publish(linear_x, angular_z, self.sim.now_ns)
            return
        self.base.cmd_vel(linear_x, angular_z, self.sim.time_s)

    # -- EventSource: the controller's updates and the board's PID frames ----------------------
    def next_event_ns(self, now_ns: int) -> int:
        """The next controller update or board PID frame, whichever comes first."""
        due = self._next_update_ns
        frame_ms = self.base.next_frame_ms()
        if frame_ms is not None:
            due = min(due, max(now_ns, frame_ms * 1_000_000))
        return due

    def on_event(self, now_ns: int) -> None:
        """At ``now_ns``: the controller fires if due, then the board runs a frame if due."""
        now_s = now_ns / NS_PER_S
        if now_ns >= self._next_update_ns:
            if self.kinematic:
                self._move_kinematically((now_ns - self._last_update_ns) / NS_PER_S)
            self.base.update(now_s)
            if self._delay is not None:  # messages that arrive now act at the next update
                for linear_x, angular_z in self._delay.arrivals(now_ns):
                    self.base.cmd_vel(linear_x, angular_z, now_s)
            self._last_update_ns = now_ns
            self._next_update_ns += self.update_period_ns
        self.base.board_tick(now_s)

    # -- WheelDrive (the controller's view of the simulator) -----------------------------------
    def encoder_angles(self) -> tuple[float, float]:
        """Forward-positive cumulative angles (rad) of the left and right encoder wheels."""
        left, right = self.body.joint_angles(self.encoder_joint_indices)
        return left * self.encoder_signs[0], right * self.encoder_signs[1]

    def set_motor_output(self, left: MotorOutput, right: MotorOutput) -> None:
        """Apply each side's motor output, shared by its wheels, until the next change."""
        torque, damping, changed = [], [], []
        for idx, is_left, share, sign, old in zip(
            self._wheel_idx, self.wheel_left, self.wheel_shares, self.wheel_signs, self._damping,
            strict=True,
        ):
            out = left if is_left else right
            torque.append(out.drive_torque_nm * share * sign)  # joint-space torque
            damping.append(out.damping_nm_s_per_rad * share)
            if damping[-1] != old:
                changed.append((idx, damping[-1]))
        self._torque = torque
        self.body.hold_torques(self._wheel_idx, torque, key="motors")
        if changed:
            self.body.set_joint_damping(*zip(*changed, strict=True))
        self._damping = damping

    # -- kinematic motion (sim mode) -----------------------------------------------------------
    def _move_kinematically(self, duration: float) -> None:
        """``sim`` mode: move with the commanded twist (no physics) and spin the wheels.

        The body takes the same explicit Euler step as the driver's fake odometry (heading at the
        start of the period), so in ``sim`` mode the robot is where its odometry says it is.
        """
        v, w = self.base.commanded_twist
        x, y, th = self._kinematic_pose
        x += v * math.cos(th) * duration
        y += v * math.sin(th) * duration
        th += w * duration
        self._kinematic_pose = (x, y, th)
        heading = (0.0, 0.0, math.sin(th / 2), math.cos(th / 2))
        self.body.set_link_pose((x, y, self.spawn_z), heading)
        half = self.config.base_width_m / 2.0
        r = self.model.wheel_radius_m
        angles, _ = self.body.joint_states(self._wheel_idx)
        for i, (wheel, idx) in enumerate(zip(self.wheels, self._wheel_idx, strict=True)):
            speed = (v - w * half if self.wheel_left[i] else v + w * half) / r * wheel.forward_sign
            self.body.reset_joint(idx, angles[i] + speed * duration, speed)

    # -- sensing -------------------------------------------------------------------------------
    @property
    def odometry(self) -> Odometry:
        """The latest ``odom`` the controller published."""
        return self.base.odometry

    def pose(self) -> Pose2D:
        """Ground-truth pose of base_link (not available to a real robot: for reward and info)."""
        return pose_from(*self.body.link_pose())

    def joint_states(self) -> JointStates:
        """Wheel joint states read from the simulator (name, rad, rad/s, N m)."""
        position, velocity = self.body.joint_states(self._wheel_idx)
        if self.kinematic:
            effort = np.zeros(len(self.wheels))
        else:
            effort = np.array(self._torque) - np.array(self._damping) * velocity
        return JointStates(tuple(w.joint for w in self.wheels), position, velocity, effort)


def drive(
    robot: SmartCarRobot,
    linear_x: float | None,
    angular_z: float | None,
    periods: int = 1,
    probe: Callable[[float], None] | None = None,
) -> Odometry:
    """Publish ``cmd_vel`` once per controller period for ``periods`` periods, as teleop would.

    Each period: the twist arrives (``None`` publishes nothing, so the 1 s timeout runs), the
    world runs to the next controller update, which fires. ``probe(time_s)`` runs after every
    physics substep. Returns the odometry published at the last update.
    """
    sim = robot.sim
    for _ in range(periods):
        if linear_x is not None and angular_z is not None:
            robot.cmd_vel(linear_x, angular_z)
        sim.run_until(sim.now_ns + robot.update_period_ns, physics=not robot.kinematic,
                      probe=probe)
    return robot.odometry
