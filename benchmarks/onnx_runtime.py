"""Speed of an exported policy: the numpy evaluator and onnxruntime against SB3 (torch), and
the time to write a 1,000-episode Minari dataset.

    python benchmarks/onnx_runtime.py [--pretrained default] [--rounds 5] [--dataset]

Exports the shipped policy (``smartcar-export --pretrained NAME``) to a temporary folder and
times, on observations of seeded planar episodes, ``model.predict`` of each runtime:

- one action (a batch of one, as ``Policy.act`` and ``smartcar-ros policy`` ask): the median
  over 2,000 calls;
- a batch of 4,096 observations (as ``smartcar-eval --vectorization batched`` asks): the best
  and the median of ``--rounds`` x 10 calls.

``--dataset`` also times ``smartcar-eval --model policy.onnx --engine planar --vectorization
batched --episodes 1000 --minari ...``: the evaluation alone, then with the dataset (steps
recorded, reference scores, writing); the difference is the dataset's cost. Prints a
Markdown table; the load average is read first (this machine is shared). Targets
(issue 44): one action <= 50 us, 4,096 in <= 5 ms, the dataset in <= 60 s.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from smartcar_gym.agents.episodes import act_batch
from smartcar_gym.export.checks import episode_observations
from smartcar_gym.export.cli import main as export_main
from smartcar_gym.policy import Policy


def time_single(predict, obs: np.ndarray) -> float:
    """Median seconds of one call on a batch of one."""
    times = []
    for row in obs[:2000]:
        batch = row[None]
        start = time.perf_counter()
        predict(batch)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def time_batch(predict, batch: np.ndarray, rounds: int) -> tuple[float, float]:
    """(best, median) seconds of one call on ``batch``."""
    times = []
    for _ in range(rounds * 10):
        start = time.perf_counter()
        predict(batch)
        times.append(time.perf_counter() - start)
    return min(times), statistics.median(times)


def eval_seconds(model: Path, extra: list[str], env: dict[str, str]) -> float:
    command = [sys.executable, "-m", "smartcar_gym.agents.cli_eval", "--model", str(model),
               "--engine", "planar", "--vectorization", "batched", "--episodes", "1000",
               "--no-progress", *extra]
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, env=env)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description="Speed of an exported policy")
    parser.add_argument("--pretrained", default="default")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--dataset", action="store_true")
    args = parser.parse_args()
    print(f"load average: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "policy.onnx"
        export_main(["--pretrained", args.pretrained, "-o", str(path), "--check", "0"])
        sb3 = Policy.load(args.pretrained)
        runtimes = {"numpy evaluator": Policy.load(path, runtime="numpy")}
        try:
            runtimes["onnxruntime"] = Policy.load(path, runtime="onnxruntime")
        except ValueError as err:
            print(f"onnxruntime: {err}")
        obs = episode_observations(runtimes["numpy evaluator"], 4096)
        print("| runtime | one action (median) | 4,096 observations (best / median) |")
        print("|---|---:|---:|")
        import torch

        torch.set_num_threads(1)
        cases = {name: policy.model.predict for name, policy in runtimes.items()}
        cases["SB3 (torch, 1 thread)"] = lambda batch: act_batch(sb3, batch)
        for name, predict in cases.items():
            one = time_single(predict, obs)
            best, median = time_batch(predict, obs, args.rounds)
            print(f"| {name} | {one * 1e6:.1f} us | {best * 1e3:.2f} / {median * 1e3:.2f} ms |")
        if args.dataset:
            env = {**os.environ, "MINARI_DATASETS_PATH": str(Path(folder) / "minari")}
            plain = eval_seconds(path, [], env)
            with_dataset = eval_seconds(path, ["--minari", "bench/planar-v0"], env)
            print(f"\n1,000 episodes on the planar batch: evaluation {plain:.1f} s, with "
                  f"--minari {with_dataset:.1f} s (the dataset: {with_dataset - plain:.1f} s)")


if __name__ == "__main__":
    main()
