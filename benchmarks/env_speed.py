"""Env steps per second for SmartCar-v0, against raw pybullet stepping of the same model.

The ratio is the figure of merit: how much the emulated ArbotiX base, the sensing and the
Gymnasium plumbing cost on top of the physics itself (same model, same physics rate, same
number of physics steps per env step). Also times sync vs async vectors of 2 envs.

    python benchmarks/env_speed.py [--steps 2000] [--mode hardware] [--wheel-contact sphere]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401
from smartcar_gym._bullet import pybullet
from smartcar_gym.controller import load_controller_config
from smartcar_gym.model import load_model
from smartcar_gym.model.contact import WHEEL_CONTACTS
from smartcar_gym.sim.robot import SmartCarRobot
from smartcar_gym.sim.simulator import Simulator


def raw_pybullet(
    steps: int, ticks_per_step: int, physics_hz: float, scale: tuple[float, float],
    wheel_contact: str = "sphere",
) -> tuple[float, float]:
    """Env-step-equivalents per second of bare stepping of the same robot, set up as the env does.

    The robot is spawned by ``SmartCarRobot`` (gearbox friction, the 1:1 chains, rotor inertia)
    and driven the way a bare pybullet script would: pybullet's velocity motors on the wheels,
    at most the stall torque, targets from random actions scaled as the env scales them (diff
    drive kinematics), redrawn every env-step period, then ``stepSimulation`` as many times as
    one env step does. Left out is everything the env adds: the ArbotiX driver and board, the
    DC motor model, sensing, the task and Gymnasium. Returns (rate, fraction of time upright).
    """
    sim = Simulator(physics_hz=physics_hz)
    config = load_controller_config()
    model = load_model()
    robot = SmartCarRobot(sim, model, config, mode="hardware", wheel_contact=wheel_contact)
    robot.spawn()
    c, body = sim.client, sim.body(robot.name)
    joints = sim.joint_indices(robot.name)
    idx = [joints[w.joint] for w in robot.wheels]
    signs = np.array([w.forward_sign for w in robot.wheels])
    left = np.array([w.side == "left" for w in robot.wheels])
    forces = [config.motor.stall_torque_nm / 2] * len(idx)  # each wheel's share of its motor
    half_track = config.base_width_m / 2
    rng = np.random.default_rng(0)
    step, set_motors = c.stepSimulation, c.setJointMotorControlArray
    upright = 0
    start = time.perf_counter()
    for _ in range(steps):
        v, w = rng.uniform(-1, 1, 2) * scale
        speeds = np.where(left, v - w * half_track, v + w * half_track) / model.wheel_radius_m
        set_motors(body, idx, pybullet.VELOCITY_CONTROL, targetVelocities=list(speeds * signs),
                   forces=forces)
        for _ in range(ticks_per_step):
            step()
        upright += c.getMatrixFromQuaternion(c.getBasePositionAndOrientation(body)[1])[8] > 0.5
    elapsed = time.perf_counter() - start
    sim.close()
    return steps / elapsed, upright / steps


def single_env(
    steps: int, mode: str, wheel_contact: str
) -> tuple[float, int, float, tuple[float, float]]:
    env = gym.make("SmartCar-v0", controller_mode=mode, wheel_contact=wheel_contact)
    env.action_space.seed(0)
    env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    unwrapped = env.unwrapped
    ticks, hz = unwrapped.ticks_per_step, unwrapped.sim.physics_hz
    scale = (unwrapped.max_linear, unwrapped.max_angular)
    env.close()
    return steps / elapsed, ticks, hz, scale


def vector_env(steps: int, mode: str, vectorization_mode: str, wheel_contact: str) -> float:
    envs = gym.make_vec(
        "SmartCar-v0", num_envs=2, vectorization_mode=vectorization_mode,
        controller_mode=mode, wheel_contact=wheel_contact,
    )
    envs.action_space.seed(0)
    envs.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps // 2):
        envs.step(envs.action_space.sample())
    elapsed = time.perf_counter() - start
    envs.close()
    return (steps // 2) * 2 / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--mode", default="hardware", choices=["hardware", "sim"])
    parser.add_argument("--wheel-contact", default="sphere", choices=WHEEL_CONTACTS)
    args = parser.parse_args()
    contact = args.wheel_contact
    env_rate, ticks, hz, scale = single_env(args.steps, args.mode, contact)
    raw_rate, upright = raw_pybullet(args.steps, ticks, hz, scale, contact)
    sync_rate = vector_env(args.steps, args.mode, "sync", contact)
    async_rate = vector_env(args.steps, args.mode, "async", contact)
    print(f"SmartCar-v0 ({args.mode}, wheel_contact={contact}), {hz:.0f} Hz physics, {ticks} "
          "physics steps per env step")
    print("| what | env steps/s | relative |")
    print("|---|---:|---:|")
    print(f"| raw pybullet: the same robot, spawned as the env spawns it, driven by pybullet's "
          f"velocity motors, `stepSimulation` {ticks} times per step | {raw_rate:,.0f} | 1.00 |")
    print(f"| one env (gym.make) | {env_rate:,.0f} | {env_rate / raw_rate:.2f} |")
    print(f"| 2 envs, sync vector | {sync_rate:,.0f} | {sync_rate / raw_rate:.2f} |")
    print(f"| 2 envs, async vector | {async_rate:,.0f} | {async_rate / raw_rate:.2f} |")
    print(f"(random actions, {args.steps} steps each; the raw car was upright {upright:.0%} "
          f"of the time; numpy {np.__version__})")
    if args.mode == "sim":
        print("(sim mode moves the car kinematically, with no physics steps: its ratio is the "
              "speed-up over stepping the physics, not an overhead)")


if __name__ == "__main__":
    main()
