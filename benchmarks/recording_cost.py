"""What recording costs an evaluation: ``smartcar-eval`` wall time with ``--rerun`` and with a
ROS 2 bag, as ratios to the same evaluation without, measured interleaved in one run.

    python benchmarks/recording_cost.py [--episodes 100] [--rounds 3] [--n-envs 1]

Each round runs every variant once, in turn, each as a fresh ``smartcar-eval`` process (the
whole command: imports, model loading, the episodes, writing the files), for the shipped
SmartCar-v0 policy (``--pretrained``) and the shipped SmartCarNav-v0 policy (``--pretrained
nav``, whose bags and recordings also hold the laser scan). A ratio is taken within a round and
the table shows the median over rounds, with the range, of the CPU time (user + system: what
the recording adds to the work, little moved by other programs on a shared machine) and of
the wall time. This machine's speed drifts by up to a half within minutes, so only ratios
measured side by side mean anything.
"""

from __future__ import annotations

import argparse
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

VARIANTS = {
    "plain": [],
    "--rerun": ["--rerun", "{tmp}/episodes.rrd"],
    "--bag ros2": ["--bag", "{tmp}/bag", "--bag-format", "ros2"],
    "both": ["--rerun", "{tmp}/episodes.rrd", "--bag", "{tmp}/bag", "--bag-format", "ros2"],
}
POLICIES = {"SmartCar-v0 (--pretrained)": ["--pretrained"],
            "SmartCarNav-v0 (--pretrained nav)": ["--pretrained", "nav"]}


def run(policy: list[str], extra: list[str], episodes: int, n_envs: int) -> tuple[float, float]:
    """Wall time and CPU time (user + system, its threads and worker processes included) in
    seconds of one ``smartcar-eval`` process."""
    tmp = tempfile.mkdtemp(prefix="recording-cost-")
    command = [sys.executable, "-m", "smartcar_gym.agents.evaluate", *policy, "--episodes",
               str(episodes), "--n-envs", str(n_envs), "--no-progress",
               *(a.format(tmp=tmp) for a in extra)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    shutil.rmtree(tmp)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return elapsed, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--n-envs", type=int, default=1)
    args = parser.parse_args()
    print(f"{args.episodes} episodes, --n-envs {args.n_envs}, {args.rounds} rounds; "
          f"python {sys.version.split()[0]}")
    print("| policy | variant | CPU s | CPU ratio (median, range) | wall s | wall ratio "
          "(median, range) |")
    print("|---|---|---:|---:|---:|---:|")
    for name, policy in POLICIES.items():
        wall: dict[str, list[float]] = {v: [] for v in VARIANTS}
        cpu: dict[str, list[float]] = {v: [] for v in VARIANTS}
        for _ in range(args.rounds):
            for variant, extra in VARIANTS.items():
                w, c = run(policy, extra, args.episodes, args.n_envs)
                wall[variant].append(w)
                cpu[variant].append(c)
        for variant in VARIANTS:
            cells = []
            for times in (cpu, wall):
                ratios = [t / p for t, p in zip(times[variant], times["plain"], strict=True)]
                cells.append(f"{statistics.median(times[variant]):.1f} | "
                             f"{statistics.median(ratios):.3f} "
                             f"({min(ratios):.3f}-{max(ratios):.3f})")
            print(f"| {name} | {variant} | {' | '.join(cells)} |", flush=True)


if __name__ == "__main__":
    main()
