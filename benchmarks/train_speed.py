"""PPO training throughput of this checkout against the round-1 code, interleaved in one run.

    python benchmarks/train_speed.py [--timesteps 16384] [--rounds 3] [--baseline-ref 1103dff]

Each round runs ``smartcar-train`` with the shipped PPO defaults (8 subprocess envs, 2048 steps
per update; its own epochs) for ``--timesteps`` steps without evaluations or checkpoints, once with
the round-1 code (fixed 2 ms stepping, extracted with ``git archive``) and once with this
checkout, in turn. It reports the training steps/s of each (from ``summary.json``: rollouts and
PPO updates) and their ratio, median over rounds. The machine's speed drifts by up to a half,
so only the ratio measured side by side means anything; a whole default run's wall time is
about ``n_timesteps / steps_per_s`` plus its evaluations.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve()
sys.path.insert(0, str(HERE.parent))

from env_speed import REPO, extract_baseline  # noqa: E402


def train(tree: Path, run_dir: Path, timesteps: int) -> float:
    """Training steps/s of one ``smartcar-train`` run with the package at ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    command = [sys.executable, "-m", "smartcar_gym.agents.cli_train", "--timesteps", str(timesteps),
               "--eval-freq", "0", "--checkpoint-freq", "0", "--no-progress",
               "--run-dir", str(run_dir)]
    done = subprocess.run(command, capture_output=True, text=True, env=env, cwd=run_dir.parent,
                          timeout=3600, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"training with {tree} failed:\n{done.stderr[-2000:]}")
    return float(json.loads((run_dir / "summary.json").read_text())["steps_per_s"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=16384)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--baseline-ref", default="1103dff")
    args = parser.parse_args()
    rates: dict[str, list[float]] = {"round-1": [], "this": []}
    with tempfile.TemporaryDirectory(prefix="smartcar_train_bench_") as tmp:
        baseline = extract_baseline(args.baseline_ref, Path(tmp))
        if baseline is None:
            sys.exit("no round-1 baseline: run inside a git clone")
        for round_ in range(args.rounds):
            for name, tree in (("round-1", baseline), ("this", REPO)):
                rate = train(tree, Path(tmp) / f"{name}_{round_}", args.timesteps)
                rates[name].append(rate)
                print(f"round {round_ + 1}: {name}: {rate:,.0f} steps/s", file=sys.stderr,
                      flush=True)
    ratio = statistics.median(b / a for a, b in zip(rates["round-1"], rates["this"],
                                                    strict=True))
    print(f"PPO defaults, {args.timesteps} steps per run, median of {args.rounds} interleaved "
          f"rounds (round-1 code: {args.baseline_ref})")
    print("| what | training steps/s |")
    print("|---|---:|")
    for name in rates:
        print(f"| {name} code | {statistics.median(rates[name]):,.0f} |")
    print(f"| this / round-1 | {ratio:.2f} (wall time x {1 / ratio:.2f}) |")


if __name__ == "__main__":
    main()
