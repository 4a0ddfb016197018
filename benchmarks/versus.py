"""Steps per second of this checkout against another commit, measured interleaved.

    python benchmarks/versus.py --base 094ff80 [--rounds 5] [--seconds 3]

The base commit is checked out into a temporary git worktree. Each case runs on each side in
a process of its own, with that side's checkout first on ``sys.path``, which makes the env
once and then steps it for ``--seconds`` at each request (the others wait, idle). Each round
measures every case once on each side, alternating which side goes first: the two
measurements of a pair lie seconds apart. Cases: one env of each engine
(``gym.make("SmartCar-v0", engine=...)``), the MuJoCo batch at N = 64 and the planar batch at
N = 4096 (``gym.make_vec(..., vectorization_mode="vector_entry_point")``; its default
``num_threads``, one per CPU, and 1 and 2 threads: ``--only "planar batch N=4096,"``). The
table gives the median steps (car-steps for batches) per second of each side and the median
of the per-round ratios (this checkout / base): ratios within a round, since this machine's
speed drifts by half within minutes.
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
print(json.dumps({"file": smartcar_gym.__file__}), flush=True)
for line in sys.stdin:  # each line: the seconds of one measurement
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < float(line):
        out = step(act())
        steps += 1
        if n == 0 and (out[0] or out[1]):
            env.reset()
    print(json.dumps({"rate": steps * cars / (time.perf_counter() - start)}), flush=True)
env.close()
"""


class Side:
    """One case on one checkout: a process that made the env and measures it on request."""

    def __init__(self, checkout: Path, case: tuple[str, str, int, int]) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", MEASURE, *map(str, case)], cwd=checkout, text=True,
            env={**os.environ, "PYTHONPATH": str(checkout)}, stdin=subprocess.PIPE,
            stdout=subprocess.PIPE)
        measured = self._answer()["file"]
        if not measured.startswith(str(checkout)):
            raise RuntimeError(f"measured {measured}, not the checkout {checkout}")

    def _answer(self) -> dict:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the measuring process ended (exit {self.proc.wait()})")
        return json.loads(line)

    def measure(self, seconds: float) -> float:
        """Steps (car-steps) per second over ``seconds`` of stepping."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"{seconds}\n")
        self.proc.stdin.flush()
        return self._answer()["rate"]

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait()


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
        sides = {label: {"this": Side(ROOT, case), "base": Side(base, case)}
                 for label, case in cases.items()}
        try:
            for r in range(args.rounds):
                for label in cases:
                    order = ["this", "base"] if r % 2 == 0 else ["base", "this"]
                    got = {side: sides[label][side].measure(args.seconds) for side in order}
                    for side, rate in got.items():
                        rates[label][side].append(rate)
                    ratios[label].append(got["this"] / got["base"])
                    print(f"round {r}: {label}: this {got['this']:.0f}/s, base "
                          f"{got['base']:.0f}/s, ratio {ratios[label][-1]:.3f}", flush=True)
        finally:
            for pair in sides.values():
                for side in pair.values():
                    side.close()
    print(f"\n| case | this (steps/s) | {args.base} (steps/s) | ratio, median (min-max) |")
    print("|---|---|---|---|")
    for label in cases:
        med = {side: statistics.median(v) for side, v in rates[label].items()}
        rs = ratios[label]
        print(f"| {label} | {med['this']:.0f} | {med['base']:.0f} | "
              f"{statistics.median(rs):.3f} ({min(rs):.3f}-{max(rs):.3f}) |")


if __name__ == "__main__":
    main()
