"""What recording costs an evaluation: ``smartcar-eval`` wall time with ``--rerun`` and with a
ROS 2 bag, as ratios to the same evaluation without, measured interleaved in one run.

    python benchmarks/recording_cost.py [--episodes 100] [--rounds 3] [--n-envs 1] [--concurrent]
                                        [--variants rerun bag both] [--split]

Each round runs every variant once, in turn, each as a fresh ``smartcar-eval`` process (the
whole command: imports, model loading, the episodes, writing the files), for the shipped
SmartCar-v0 policy (``--pretrained``) and the shipped SmartCarNav-v0 policy (``--pretrained
nav``, whose bags and recordings also hold the laser scan). A ratio is taken within a round and
the table shows the median over rounds, with the range, of the CPU time (user + system: what
the recording adds to the work, little moved by other programs on a shared machine) and of
the wall time. This machine's speed drifts by up to a half within minutes, so only ratios
measured side by side mean anything. ``--concurrent`` starts a round's processes (every
variant of both policies) at once: on a machine busy with other jobs a round then takes the
time of one evaluation instead of eight, and the CPU times, each process's own, stay
comparable; wall times then mostly measure the sharing. ``--variants`` runs only some
variants (``plain`` always runs: the ratios are to it), so more rounds fit in the same time.
``--split`` also says where each process's CPU time went (``time.process_time`` around
``smartcar-eval``'s parts: start-up and model, starting the recorders, the episodes with
capture and sending, closing the files, the rest, the child processes that ``main`` reaped
(``--rerun``'s recorder process; vector-env workers), and exiting the interpreter: the CPU
time at exit less that at the end of ``main`` and the children's), as medians and as the
difference to plain. The CPU times always include the child processes (``--rerun``'s recorder:
``smartcar-eval`` imports ``rerun`` in a process of its own, ``RerunProcessSink``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Any

VARIANTS = {
    "plain": [],
    "--rerun": ["--rerun", "{tmp}/episodes.rrd"],
    "--bag ros2": ["--bag", "{tmp}/bag", "--bag-format", "ros2"],
    "both": ["--rerun", "{tmp}/episodes.rrd", "--bag", "{tmp}/bag", "--bag-format", "ros2"],
}
SHORT = {"rerun": "--rerun", "bag": "--bag ros2", "both": "both"}  # --variants names
SPLIT = """
import json, sys, time
import smartcar_gym.agents.cli_eval as ev
stamps = {}
def timed(name, f):
    def call(*args, **kwargs):
        stamps[name + " from"] = time.process_time()
        try:
            return f(*args, **kwargs)
        finally:
            stamps[name] = time.process_time()
    return call
for name in ("_recorders", "evaluate_policy_episodes", "_close_recorders"):
    setattr(ev, name, timed(name, getattr(ev, name)))
code = ev.main(sys.argv[2:])
stamps["end"] = time.process_time()
import resource
children = resource.getrusage(resource.RUSAGE_CHILDREN)  # reaped: the Rerun recorder
stamps["children"] = children.ru_utime + children.ru_stime
json.dump(stamps, open(sys.argv[1], "w"))
sys.exit(code)
"""
PARTS = ("start-up", "recorders", "episodes", "close", "rest", "children", "exit")
POLICIES = {"SmartCar-v0 (--pretrained)": ["--pretrained"],
            "SmartCarNav-v0 (--pretrained nav)": ["--pretrained", "nav"]}


def start(policy: list[str], extra: list[str], episodes: int, n_envs: int,
          split: bool = False) -> tuple[subprocess.Popen, str, float]:
    """Start one ``smartcar-eval`` process (into a folder of its own); ``split``: through
    ``SPLIT``, which writes its CPU time stamps to the folder's ``stamps.json``."""
    tmp = tempfile.mkdtemp(prefix="recording-cost-")
    head = ["-c", SPLIT, f"{tmp}/stamps.json"] if split else ["-m", "smartcar_gym.agents.cli_eval"]
    command = [sys.executable, *head, *policy, "--episodes",
               str(episodes), "--n-envs", str(n_envs), "--no-progress",
               *(a.format(tmp=tmp) for a in extra)]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return process, tmp, time.perf_counter()


def finish(started: tuple[subprocess.Popen, str, float]) -> tuple[float, float, dict]:
    """Wall time and CPU time (user + system, its threads and worker processes included) in
    seconds of a process that ``start`` started, and its parts' CPU times (``--split``)."""
    _, status, usage = os.wait4(started[0].pid, 0)
    return _result(started, status, usage)


def finish_all(started: list[tuple[subprocess.Popen, str, float]]
               ) -> list[tuple[float, float, dict]]:
    """``finish`` for processes running at once: each is timed when it ends."""
    index = {s[0].pid: i for i, s in enumerate(started)}
    measured: list[tuple[float, float, dict]] = [(0.0, 0.0, {})] * len(started)
    while index:
        pid, status, usage = os.wait4(-1, 0)
        if pid in index:
            i = index.pop(pid)
            measured[i] = _result(started[i], status, usage)
    return measured


def _result(started: tuple[subprocess.Popen, str, float], status: int,
            usage: Any) -> tuple[float, float, dict]:
    process, tmp, begin = started
    elapsed = time.perf_counter() - begin
    process.returncode = os.waitstatus_to_exitcode(status)
    cpu = usage.ru_utime + usage.ru_stime
    parts = {}
    if os.path.exists(f"{tmp}/stamps.json"):
        with open(f"{tmp}/stamps.json") as file:
            t = json.load(file)
        parts = dict(zip(PARTS, (
            t["_recorders from"], t["_recorders"] - t["_recorders from"],
            t["evaluate_policy_episodes"] - t["evaluate_policy_episodes from"],
            t["_close_recorders"] - t["_close_recorders from"],
            (t["end"] - t["_close_recorders"]  # between the parts: summary, files
             + t["evaluate_policy_episodes from"] - t["_recorders"]
             + t["_close_recorders from"] - t["evaluate_policy_episodes"]),
            t["children"], cpu - t["end"] - t["children"]),
            strict=True))
    shutil.rmtree(tmp)
    if process.returncode != 0:
        raise subprocess.CalledProcessError(process.returncode, process.args)
    return elapsed, cpu, parts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--n-envs", type=int, default=1)
    parser.add_argument("--concurrent", action="store_true",
                        help="start a round's processes at once (CPU ratios only)")
    parser.add_argument("--variants", nargs="+", choices=list(SHORT), default=list(SHORT),
                        help="which variants to run besides plain: rerun (--rerun), bag (--bag "
                        "ros2), both (default: all)")
    parser.add_argument("--split", action="store_true",
                        help="also split each process's CPU time into its parts")
    args = parser.parse_args()
    variants = ["plain", *(SHORT[v] for v in SHORT if v in args.variants)]
    print(f"{args.episodes} episodes, --n-envs {args.n_envs}, {args.rounds} rounds; "
          f"python {sys.version.split()[0]}"
          f"{', concurrent' if args.concurrent else ''}")
    print("| policy | variant | CPU s | CPU ratio (median, range) | wall s | wall ratio "
          "(median, range) |")
    print("|---|---|---:|---:|---:|---:|")
    runs = [(name, variant) for name in POLICIES for variant in variants]
    wall: dict[tuple[str, str], list[float]] = {run: [] for run in runs}
    cpu: dict[tuple[str, str], list[float]] = {run: [] for run in runs}
    parts: dict[tuple[str, str], list[dict]] = {run: [] for run in runs}
    for _ in range(args.rounds):
        if args.concurrent:
            started = [start(POLICIES[n], VARIANTS[v], args.episodes, args.n_envs, args.split)
                       for n, v in runs]
            measured = finish_all(started)
        else:
            measured = [finish(start(POLICIES[n], VARIANTS[v], args.episodes, args.n_envs,
                                     args.split)) for n, v in runs]
        for run, (w, c, p) in zip(runs, measured, strict=True):
            wall[run].append(w)
            cpu[run].append(c)
            parts[run].append(p)
    for name, variant in runs:
        cells = []
        for times in (cpu, wall):
            ratios = [t / p for t, p in zip(times[name, variant], times[name, "plain"],
                                            strict=True)]
            cells.append(f"{statistics.median(times[name, variant]):.1f} | "
                         f"{statistics.median(ratios):.3f} "
                         f"({min(ratios):.3f}-{max(ratios):.3f})")
        print(f"| {name} | {variant} | {' | '.join(cells)} |", flush=True)
    if args.split:
        print_split(runs, parts)


def print_split(runs: list[tuple[str, str]], parts: dict[tuple[str, str], list[dict]]) -> None:
    """The median CPU seconds of each part, and (+) the median over rounds of the difference
    to plain's part in the same round."""
    print(f"\n| policy | variant | {' | '.join(PARTS)} |")
    print(f"|---|---|{'---:|' * len(PARTS)}")
    for name, variant in runs:
        cells = []
        for part in PARTS:
            mine = [p[part] for p in parts[name, variant]]
            cell = f"{statistics.median(mine):.3f}"
            if variant != "plain":
                plain = [p[part] for p in parts[name, "plain"]]
                extra = statistics.median(m - q for m, q in zip(mine, plain, strict=True))
                cell += f" ({extra:+.3f})"
            cells.append(cell)
        print(f"| {name} | {variant} | {' | '.join(cells)} |", flush=True)

if __name__ == "__main__":
    main()
