"""How fast the planar engine steps, against one pybullet SmartCar-v0 env, measured interleaved.

    python benchmarks/planar_speed.py --rounds 7          # about 5 minutes on 2 cores

Each round times, one after the other in this process, with random actions:
- one pybullet ``SmartCar-v0`` env (the reference);
- one planar env (numba's compiled loop when installed), and the same without numba
  (Python floats: ``dynamics.COMPILED`` off for that env);
- the planar batch (``gym.make_vec(..., vectorization_mode="vector_entry_point",
  engine="planar")``) at ``--cars`` cars: numba's loops (the physics, ``dynamics``, and the boards
  and controllers, ``controller.compiled``; from 1,024 cars a period's events and physics in
  one loop, ``sim/planar/period.py``), and numpy arrays (both switched off).

Figures are env steps (car-steps for the batch) per second of this process's CPU time (the
steadier figure on a shared machine) and by the wall clock; each ratio cell is the median over
rounds of the round's ratio to pybullet, with the lowest and highest round in brackets.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401
from smartcar_gym.controller import compiled as controller_jit
from smartcar_gym.sim.planar import dynamics


def single(engine: str, steps: int, compiled: bool = True) -> tuple[float, float]:
    """(steps per CPU second, per wall second) of one env with random actions."""
    saved = dynamics.COMPILED, controller_jit.COMPILED
    dynamics.COMPILED, controller_jit.COMPILED = saved[0] and compiled, saved[1] and compiled
    try:
        env = gym.make("SmartCar-v0", engine=engine)
        env.reset(seed=0)
        actions = np.random.default_rng(0).uniform(-1, 1, (steps, 2)).astype(np.float32)
        cpu, wall = time.process_time(), time.perf_counter()
        for a in actions:
            *_, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        env.close()
    finally:
        dynamics.COMPILED, controller_jit.COMPILED = saved
    return steps / cpu, steps / wall


def batch(cars: int, steps: int, compiled: bool = True) -> tuple[float, float]:
    """(car-steps per CPU second, per wall second) of the planar batch."""
    saved = dynamics.COMPILED, controller_jit.COMPILED
    dynamics.COMPILED, controller_jit.COMPILED = saved[0] and compiled, saved[1] and compiled
    try:
        venv = gym.make_vec("SmartCar-v0", num_envs=cars, engine="planar",
                            vectorization_mode="vector_entry_point")
        venv.reset(seed=0)
        actions = np.random.default_rng(0).uniform(-1, 1, (steps + 1, cars, 2)).astype(
            np.float32)
        venv.step(actions[0])
        cpu, wall = time.process_time(), time.perf_counter()
        for a in actions[1:]:
            venv.step(a)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        venv.close()
    finally:
        dynamics.COMPILED, controller_jit.COMPILED = saved
    return cars * steps / cpu, cars * steps / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    # 600 steps a round let the one-env ratio move between 3.5 and 7.1 from round to round
    parser.add_argument("--steps", type=int, default=1500, help="steps of each single env")
    parser.add_argument("--cars", type=int, default=4096)
    parser.add_argument("--batch-steps", type=int, default=20)
    args = parser.parse_args()
    variants: dict[str, Callable[[], tuple[float, float]]] = {
        "pybullet env": lambda: single("pybullet", args.steps),
        "planar env": lambda: single("planar", args.steps),
        "planar env, no numba": lambda: single("planar", args.steps, compiled=False),
        f"planar batch N={args.cars}": lambda: batch(args.cars, args.batch_steps),
        f"planar batch N={args.cars}, no numba": lambda: batch(args.cars, args.batch_steps,
                                                               compiled=False),
    }
    if not dynamics.COMPILED:
        print("numba is not installed: the 'planar' and 'no numba' rows are the same code")
    batch(64, 3)  # numba compiles (or loads its cache) before the first round
    rows: dict[str, list[tuple[float, float]]] = {name: [] for name in variants}
    for r in range(args.rounds):
        for name, run in variants.items():
            rows[name].append(run())
        print(f"round {r + 1}/{args.rounds} done", flush=True)
    reference = rows["pybullet env"]
    print("\n| | steps/s (CPU) | steps/s (wall) | x pybullet (CPU) | x pybullet (wall) |")
    print("|---|---|---|---|---|")
    for name, values in rows.items():
        cpu = statistics.median(v[0] for v in values)
        wall = statistics.median(v[1] for v in values)
        ratios = [[v[k] / ref[k] for v, ref in zip(values, reference, strict=True)]
                  for k in (0, 1)]
        cells = [f"x{statistics.median(x):.1f} ({min(x):.1f}-{max(x):.1f})" for x in ratios]
        print(f"| {name} | {cpu:,.0f} | {wall:,.0f} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()
