"""Env steps per second for SmartCar-v0, against raw pybullet stepping of the same model.

The ratio is the figure of merit: how much the emulated ArbotiX base, the sensing and the
Gymnasium plumbing cost on top of the physics itself (same model, same physics rate, same
number of physics steps per env step). Also times sync vs async vectors of 2 envs.

    python benchmarks/env_speed.py [--steps 2000] [--mode hardware]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401
from smartcar_gym.model import load_model
from smartcar_gym.sim.simulator import Simulator


def raw_pybullet(steps: int, ticks_per_step: int, physics_hz: float) -> float:
    """Env-step-equivalents per second of bare stepSimulation with the car on the plane."""
    sim = Simulator(physics_hz=physics_hz)
    model = load_model()
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        sim.load_urdf("car", model.write_urdf(tmp))
    step = sim.client.stepSimulation
    start = time.perf_counter()
    for _ in range(steps * ticks_per_step):
        step()
    elapsed = time.perf_counter() - start
    sim.close()
    return steps / elapsed


def single_env(steps: int, mode: str) -> tuple[float, int, float]:
    env = gym.make("SmartCar-v0", controller_mode=mode)
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
    env.close()
    return steps / elapsed, ticks, hz


def vector_env(steps: int, mode: str, vectorization_mode: str) -> float:
    envs = gym.make_vec(
        "SmartCar-v0", num_envs=2, vectorization_mode=vectorization_mode,
        controller_mode=mode,
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
    args = parser.parse_args()
    env_rate, ticks, hz = single_env(args.steps, args.mode)
    raw_rate = raw_pybullet(args.steps, ticks, hz)
    sync_rate = vector_env(args.steps, args.mode, "sync")
    async_rate = vector_env(args.steps, args.mode, "async")
    print(f"SmartCar-v0 ({args.mode}), {hz:.0f} Hz physics, {ticks} physics steps per env step")
    print("| what | env steps/s | relative |")
    print("|---|---:|---:|")
    print(f"| raw pybullet stepSimulation, same model and substeps | {raw_rate:,.0f} | 1.00 |")
    print(f"| one env (gym.make) | {env_rate:,.0f} | {env_rate / raw_rate:.2f} |")
    print(f"| 2 envs, sync vector | {sync_rate:,.0f} | {sync_rate / raw_rate:.2f} |")
    print(f"| 2 envs, async vector | {async_rate:,.0f} | {async_rate / raw_rate:.2f} |")
    print(f"(random actions, {args.steps} steps each; numpy {np.__version__})")


if __name__ == "__main__":
    main()
