"""Soak: one SmartCar-v0 for a million random steps with resets; memory and speed over time.

    python benchmarks/soak.py [--steps 1000000] [--every 100000] [--render]

Prints, every ``--every`` steps, the process's resident memory (RSS, from /proc) and the env
steps per second since the previous line. Memory that keeps growing line after line is a leak;
a rise that flattens after the first lines is warm-up (allocator pools, pybullet's caches).
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401


def rss_mb() -> float:
    """Resident set size of this process now (MB)."""
    try:
        with open("/proc/self/statm") as stream:
            pages = int(stream.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:  # no /proc: the peak instead
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000)
    parser.add_argument("--every", type=int, default=100_000)
    parser.add_argument("--render", action="store_true",
                        help="rgb_array mode, one frame every 1000 steps (the markers' bodies)")
    args = parser.parse_args()
    env = gym.make("SmartCar-v0", render_mode="rgb_array" if args.render else None,
                   render_width=160, render_height=120)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    episodes = 0
    print("| steps | episodes | RSS (MB) | env steps/s since the last line |")
    print("|---:|---:|---:|---:|")
    print(f"| 0 | 0 | {rss_mb():.1f} | - |", flush=True)
    start = time.perf_counter()
    for step in range(1, args.steps + 1):
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        if args.render and step % 1000 == 0:
            env.render()
        if terminated or truncated:
            env.reset()
            episodes += 1
        if step % args.every == 0:
            now = time.perf_counter()
            rate = args.every / (now - start)
            print(f"| {step:,} | {episodes:,} | {rss_mb():.1f} | {rate:,.0f} |", flush=True)
            start = now
    env.close()


if __name__ == "__main__":
    main()
