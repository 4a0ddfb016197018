"""Steps per second of this checkout against another commit, measured interleaved.

    python benchmarks/versus.py --base 094ff80 [--rounds 5] [--seconds 3]

The base commit is checked out into a temporary git worktree. Each round measures every case
once on each side, alternating which side goes first, each measurement in a fresh subprocess
with that side's checkout first on ``sys.path``. Cases: one env of each engine
(``gym.make("SmartCar-v0", engine=...)``), the MuJoCo batch at N = 64 and the planar batch at
N = 4096 (``gym.make_vec(..., vectorization_mode="vector_entry_point")``; its default
``num_threads``, one per CPU, and 1 and 2 threads: ``--only "planar batch N=4096,"``). The
table gives
the median steps (car-steps for batches) per second of each side and the median of the
per-round ratios (this checkout / base): ratios within a round, since this machine's speed
drifts by half within minutes.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from timed import worktree_at  # benchmarks/timed.py, beside this script

ROOT = Path(__file__).resolve().parent.parent
#: label: (env id, engine, cars (0: one env), num_threads (0: the env's default))
CASES = {
    "pybullet single": ("SmartCar-v0", "pybullet", 0, 0),
    "mujoco single": ("SmartCar-v0", "mujoco", 0, 0),
    "planar single": ("SmartCar-v0", "planar", 0, 0),
    "mujoco batch N=64": ("SmartCar-v0", "mujoco", 64, 0),
    "planar batch N=4096": ("SmartCar-v0", "planar", 4096, 0),
    "planar batch N=4096, 1 thread": ("SmartCar-v0", "planar", 4096, 1),
    "planar batch N=4096, 2 threads": ("SmartCar-v0", "planar", 4096, 2),
}

MEASURE = r"""
import json, sys, time, warnings
import gymnasium as gym
import numpy as np
import smartcar_gym
env_id, engine, n, threads = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
seconds = float(sys.argv[5])
rng = np.random.default_rng(0)
if n == 0:
    env = gym.make(env_id, engine=engine)
    env.reset(seed=0)
    act = lambda: rng.uniform(-1, 1, 2).astype(np.float32)
    step = lambda a: env.step(a)[2:4]
    cars = 1
else:
    env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                       engine=engine, **({"num_threads": threads} if threads else {}))
    env.reset(seed=0)
    act = lambda: rng.uniform(-1, 1, (n, 2)).astype(np.float32)
    step = lambda a: env.step(a)
    cars = n
for _ in range(5):
    out = step(act())
    if n == 0 and (out[0] or out[1]):
        env.reset()
steps, start = 0, time.perf_counter()
while time.perf_counter() - start < seconds:
    out = step(act())
    steps += 1
    if n == 0 and (out[0] or out[1]):
        env.reset()
elapsed = time.perf_counter() - start
env.close()
print(json.dumps({"rate": steps * cars / elapsed, "file": smartcar_gym.__file__}))
"""


def measure(checkout: Path, case: tuple[str, str, int, int], seconds: float) -> float:
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    out = subprocess.run([sys.executable, "-c", MEASURE, *map(str, case), str(seconds)],
                         env=env, cwd=checkout, capture_output=True, text=True, check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if not result["file"].startswith(str(checkout)):
        raise RuntimeError(f"measured {result['file']}, not the checkout {checkout}")
    return result["rate"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the commit to compare against")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=3.0, help="per measurement")
    parser.add_argument("--only", default="", help="cases whose label starts with this")
    args = parser.parse_args()
    cases = {k: v for k, v in CASES.items() if k.startswith(args.only)}
    rates: dict[str, dict[str, list[float]]] = {k: {"this": [], "base": []} for k in cases}
    ratios: dict[str, list[float]] = {k: [] for k in cases}
    with worktree_at(ROOT, args.base) as base:
        for r in range(args.rounds):
            for label, case in cases.items():
                order = [("this", ROOT), ("base", base)]
                if r % 2:
                    order.reverse()
                got = {side: measure(path, case, args.seconds) for side, path in order}
                for side, rate in got.items():
                    rates[label][side].append(rate)
                ratios[label].append(got["this"] / got["base"])
                print(f"round {r}: {label}: this {got['this']:.0f}/s, base "
                      f"{got['base']:.0f}/s, ratio {ratios[label][-1]:.3f}", flush=True)
    print(f"\n| case | this (steps/s) | {args.base} (steps/s) | ratio, median (min-max) |")
    print("|---|---|---|---|")
    for label in cases:
        med = {side: statistics.median(v) for side, v in rates[label].items()}
        rs = ratios[label]
        print(f"| {label} | {med['this']:.0f} | {med['base']:.0f} | "
              f"{statistics.median(rs):.3f} ({min(rs):.3f}-{max(rs):.3f}) |")


if __name__ == "__main__":
    main()
