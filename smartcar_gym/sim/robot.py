"""The smartcar in the simulator: a loaded model, its wheels, and its emulated ArbotiX base.

The robot implements the controller's narrow ``WheelDrive`` interface (read the encoder wheels'
angles, apply a motor output per side) and advances the world by one controller period per
call. In ``hardware`` mode the wheels are driven by the board's PWM through the DC-motor model;
in ``sim`` mode (the driver's ``sim: true``) the body follows the commanded twist kinematically.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from smartcar_gym._bullet import pybullet
from smartcar_gym.controller import ArbotixBase, ArbotixConfig, MotorOutput, Odometry
from smartcar_gym.model import RobotModel, Wheel
from smartcar_gym.model.contact import WheelContact, simulated_urdf
from smartcar_gym.sim.simulator import Simulator

MODES = ("hardware", "sim")


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


class SmartCarRobot:
    """A wheeled robot model plus its emulated ArbotiX base controller in a ``Simulator``.

    Args:
        sim: the simulator facade that owns the pybullet client.
        model: the loaded robot model (see ``smartcar_gym.load_model``).
        config: the ArbotiX controller configuration.
        mode: ``"hardware"`` (PID, encoders, DC motors) or ``"sim"`` (kinematic, as ``sim: true``).
        name: body name in the simulator.
        wheel_contact: ``"sphere"`` (one ground contact per drive wheel) or ``"urdf"`` (the
            model's own wheel collision shapes); see ``smartcar_gym.model.contact``.
    """

    def __init__(
        self,
        sim: Simulator,
        model: RobotModel,
        config: ArbotixConfig,
        mode: str = "hardware",
        name: str = "smartcar",
        wheel_contact: WheelContact = "sphere",
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"controller_mode must be one of {MODES}, got {mode!r}")
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
        self.base = ArbotixBase(config, mode, model.wheel_radius_m, drive=self)
        # Height of base_link above the ground when every wheel touches it.
        self.spawn_z = max(w.radius_m - w.position_m[2] for w in self.wheels)
        self._body = -1
        self._joint_index: dict[str, int] = {}
        self._wheel_idx: list[int] = []
        self._signs = np.array([w.forward_sign for w in self.wheels], dtype=float)
        self._left = np.array([w.side == "left" for w in self.wheels])
        # Each side's motor drives its wheels through a 1:1 chain: they share its output.
        n_left = int(self._left.sum())
        self._share = np.where(self._left, 1.0 / n_left, 1.0 / (len(self.wheels) - n_left))
        self._torque = np.zeros(len(self.wheels))
        self._damping = np.zeros(len(self.wheels))
        self._com_to_link: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        self._link_to_com: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        self._kinematic_pose = (0.0, 0.0, 0.0)

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
        self, x: float = 0.0, y: float = 0.0, yaw: float = 0.0, settle_s: float = 0.1
    ) -> None:
        """Load the robot into a freshly reset world, let it settle, and start the controller.

        After settling the simulator clock is restarted, so the controller starts at t = 0 with
        its odometry origin at the robot's pose.
        """
        sim, c = self.sim, self.sim.client
        with tempfile.TemporaryDirectory(prefix="smartcar_gym_") as tmp:
            # pybullet parses the file while loading it: nothing needs to outlive this block
            urdf_path = self.model.write_urdf(tmp, self._urdf)
            self._body = sim.load_urdf(self.name, urdf_path, (x, y, self.spawn_z), yaw)
        self._joint_index = sim.joint_indices(self.name)
        self._wheel_idx = [self._joint_index[w.joint] for w in self.wheels]
        # pybullet's velocity motor on each wheel, held at speed 0 with at most the gearbox's
        # friction torque, is the gearbox's Coulomb friction; the DC motors add their torque.
        c.setJointMotorControlArray(
            self._body, self._wheel_idx, pybullet.VELOCITY_CONTROL,
            targetVelocities=[0.0] * len(self.wheels),
            forces=list(self._share * self.config.motor.friction_torque_nm),
        )
        for wheel, idx, share in zip(self.wheels, self._wheel_idx, self._share, strict=True):
            # The side's gearmotor rotor, seen through the gearbox, spins with the wheels: add
            # this wheel's share of its inertia about the axle (the joint axis).
            inertia = list(c.getDynamicsInfo(self._body, idx)[2])
            axis = int(np.argmax(np.abs(self.model.joints[wheel.joint].axis)))
            inertia[axis] += share * self.config.motor.reflected_inertia_kg_m2
            c.changeDynamics(self._body, idx, jointDamping=0.0, linearDamping=0.0,
                             angularDamping=0.0, localInertiaDiagonal=inertia)
        self._chain_wheels()
        c.changeDynamics(self._body, -1, linearDamping=0.0, angularDamping=0.0)
        info = c.getDynamicsInfo(self._body, -1)
        self._link_to_com = (tuple(info[3]), tuple(info[4]))
        self._com_to_link = c.invertTransform(*self._link_to_com)
        self._torque[:] = 0.0
        self._damping[:] = 0.0
        self._kinematic_pose = (x, y, yaw)  # sim mode keeps the pose in doubles
        if self.mode == "hardware" and settle_s > 0:
            sim.step(round(settle_s * sim.physics_hz))
        sim.restart_clock()
        self.base.reset(0.0)

    def _chain_wheels(self) -> None:
        """Link each side's wheels to its first wheel 1:1 with gear constraints (the chain)."""
        c = self.sim.client
        for side in ("left", "right"):
            idx = [i for w, i in zip(self.wheels, self._wheel_idx, strict=True) if w.side == side]
            signs = [w.forward_sign for w in self.wheels if w.side == side]
            for other, sign in zip(idx[1:], signs[1:], strict=True):
                cid = c.createConstraint(
                    self._body, idx[0], self._body, other, pybullet.JOINT_GEAR,
                    [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0],
                )
                # the gear constraint holds q0 + ratio * q1 = const: equal forward speeds
                c.changeConstraint(cid, gearRatio=-signs[0] * sign, maxForce=100.0)

    # -- WheelDrive (the controller's view of the simulator) -----------------------------------
    def encoder_angles(self) -> tuple[float, float]:
        """Forward-positive cumulative angles (rad) of the left and right encoder wheels."""
        c = self.sim.client
        left, right = self.encoder_wheels
        states = c.getJointStates(
            self._body, [self._joint_index[left.joint], self._joint_index[right.joint]]
        )
        return states[0][0] * left.forward_sign, states[1][0] * right.forward_sign

    def set_motor_output(self, left: MotorOutput, right: MotorOutput) -> None:
        """Apply each side's motor output, shared by its wheels, until the next change."""
        drive = np.where(self._left, left.drive_torque_nm, right.drive_torque_nm) * self._share
        damping = (
            np.where(self._left, left.damping_nm_s_per_rad, right.damping_nm_s_per_rad)
            * self._share
        )
        self._torque = drive * self._signs  # joint-space torque
        c = self.sim.client
        for i, idx in enumerate(self._wheel_idx):
            if damping[i] != self._damping[i]:
                c.changeDynamics(self._body, idx, jointDamping=float(damping[i]))
        self._damping = damping

    # -- stepping ------------------------------------------------------------------------------
    def advance(
        self,
        linear_x: float | None,
        angular_z: float | None,
        ticks: int,
        probe: Callable[[float], None] | None = None,
    ) -> Odometry:
        """Send a cmd_vel, run the world for ``ticks`` physics steps, then fire the controller.

        ``None`` for the twist publishes no cmd_vel this period (the 1 s timeout keeps running).
        ``probe(time_s)``, if given, is called after every physics step (for logging).
        Returns the odometry the controller published at the end of the period.
        """
        sim = self.sim
        if linear_x is not None and angular_z is not None:
            self.base.cmd_vel(linear_x, angular_z, sim.time_s)
        if self.mode == "hardware":
            c, body, idx = sim.client, self._body, self._wheel_idx
            torque_control = pybullet.TORQUE_CONTROL
            # bound methods looked up once: BulletClient wraps every attribute access
            base_tick, step = self.base.physics_tick, c.stepSimulation
            set_joints = c.setJointMotorControlArray
            hz = sim.physics_hz
            for _ in range(ticks):
                base_tick(sim.ticks / hz)
                set_joints(body, idx, torque_control, forces=self._torque)
                step()
                sim.ticks += 1
                if probe is not None:
                    probe(sim.ticks / hz)
        else:
            self._move_kinematically(ticks)
        return self.base.update(sim.time_s)

    def _move_kinematically(self, ticks: int) -> None:
        """``sim`` mode: move with the commanded twist (no physics) and spin the wheels.

        The body takes the same explicit Euler step as the driver's fake odometry (heading at the
        start of the period), so in ``sim`` mode the robot is where its odometry says it is.
        """
        v, w = self.base.commanded_twist
        duration = ticks / self.sim.physics_hz
        x, y, th = self._kinematic_pose
        x += v * math.cos(th) * duration
        y += v * math.sin(th) * duration
        th += w * duration
        self._kinematic_pose = (x, y, th)
        c = self.sim.client
        orn = c.getQuaternionFromEuler([0.0, 0.0, th])
        com = c.multiplyTransforms((x, y, self.spawn_z), orn, *self._link_to_com)
        c.resetBasePositionAndOrientation(self._body, com[0], com[1])
        half = self.config.base_width_m / 2.0
        r = self.model.wheel_radius_m
        for i, (wheel, idx) in enumerate(zip(self.wheels, self._wheel_idx, strict=False)):
            speed = (v - w * half if self._left[i] else v + w * half) / r * wheel.forward_sign
            angle = c.getJointState(self._body, idx)[0] + speed * duration
            c.resetJointState(self._body, idx, angle, speed)
        self.sim.ticks += ticks

    # -- sensing -------------------------------------------------------------------------------
    def pose(self) -> Pose2D:
        """Ground-truth pose of base_link (not available to a real robot: for reward and info)."""
        c = self.sim.client
        com_pos, com_orn = c.getBasePositionAndOrientation(self._body)
        pos, orn = c.multiplyTransforms(com_pos, com_orn, *self._com_to_link)
        qx, qy, qz, qw = orn
        yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        up_z = 1.0 - 2.0 * (qx * qx + qy * qy)
        return Pose2D(pos[0], pos[1], yaw, pos[2], up_z)

    def joint_states(self) -> JointStates:
        """Wheel joint states read from the simulator (name, rad, rad/s, N m)."""
        states = self.sim.client.getJointStates(self._body, self._wheel_idx)
        position = np.array([s[0] for s in states])
        velocity = np.array([s[1] for s in states])
        if self.mode == "hardware":
            effort = self._torque - self._damping * velocity
        else:
            effort = np.zeros(len(self.wheels))
        return JointStates(tuple(w.joint for w in self.wheels), position, velocity, effort)
