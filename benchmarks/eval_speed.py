"""Wall time of ``smartcar-eval`` batched against sequential: 1,000 episodes on MuJoCo.

    python benchmarks/eval_speed.py [--pretrained default] [--episodes 1000] [--rounds 2]
    python benchmarks/eval_speed.py --env SmartCarSim-v0 --engine none --no-subproc --rounds 1

Each round runs, one after the other, the same evaluation as the commands a user types:

- ``sequential``: ``smartcar-eval --pretrained NAME --engine mujoco --episodes E`` (one env
  in the evaluating process: the default; ``--env``/``--engine`` change the env);
- ``subproc x2``: the same with ``--n-envs 2`` (two worker processes: the other way to use two
  cores), unless ``--no-subproc``;
- ``batched``: the same with ``--vectorization batched`` (128 cars of the MuJoCo batch, two
  physics threads).

Each command's wall time (start-up and model loading included) and CPU time (its process and
threads, from ``getrusage``) are measured; the load average is read before each. Ratios are
taken within a round (this shared machine's speed drifts). The JSON records are compared: the
success rates, the episodes whose success differs, the largest difference of a final distance.
Prints a Markdown table; ``--out FILE.json`` keeps the numbers.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

from timed import timed_run  # benchmarks/timed.py, beside this script

MODES = {
    "sequential": [],
    "subproc x2": ["--n-envs", "2"],
    "batched": ["--vectorization", "batched"],
}


def run(mode: str, name: str, episodes: int, folder: Path, env: list[str]) -> dict:
    """One ``smartcar-eval`` command: its wall and CPU seconds and its JSON."""
    out = folder / f"{mode.replace(' ', '_')}.json"
    argv = [sys.executable, "-m", "smartcar_gym.agents.cli_eval", "--pretrained", name, *env,
            "--episodes", str(episodes), "--no-progress", "--json", str(out), *MODES[mode]]
    return {"mode": mode, **timed_run(argv),
            "command": "smartcar-eval " + " ".join(argv[3:]).replace(str(out), "OUT.json"),
            "record": json.loads(out.read_text())}


def compare(a: dict, b: dict) -> dict:
    """How two evaluations' records differ."""
    ra, rb = a["episode_records"], b["episode_records"]
    return {"success_rates": (a["success_rate"], b["success_rate"]),
            "episodes_ending_otherwise": sum(x["success"] != y["success"]
                                             for x, y in zip(ra, rb, strict=True)),
            "max_final_distance_diff_m": max(abs(x["final_distance_m"] - y["final_distance_m"])
                                             for x, y in zip(ra, rb, strict=True))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pretrained", default="default", help="shipped policy (default: "
                        "the one --pretrained alone names)")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--no-subproc", action="store_true", help="leave out --n-envs 2")
    parser.add_argument("--env", help="env id (default: the policy's, SmartCar-v0)")
    parser.add_argument("--engine", default="mujoco", help="--engine of the commands, or none")
    parser.add_argument("--out", type=Path, help="write the measurements as JSON")
    args = parser.parse_args()
    modes = [m for m in MODES if not (args.no_subproc and m == "subproc x2")]
    env = (["--env", args.env] if args.env else []) + (
        [] if args.engine == "none" else ["--engine", args.engine])
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            for mode in modes:
                row = run(mode, args.pretrained, args.episodes, Path(tmp), env)
                row["round"] = k
                rows.append(row)
                print(f"round {k} {mode}: {row['wall_s']:.1f} s wall, {row['cpu_s']:.1f} s CPU, "
                      f"load {row['load']:.1f}, success {row['record']['success_rate']:.1%}",
                      file=sys.stderr, flush=True)
    sequential = [r for r in rows if r["mode"] == "sequential"]
    print(f"\n{args.episodes} episodes, --pretrained {args.pretrained} {' '.join(env)}, "
          f"{args.rounds} rounds (median; ratio: sequential / this, per round)\n")
    print("| command | wall (s) | CPU (s) | wall ratio | success | load average |")
    print("|---|---:|---:|---:|---:|---:|")
    summary = {}
    for mode in modes:
        mine = [r for r in rows if r["mode"] == mode]
        ratios = [s["wall_s"] / r["wall_s"] for s, r in zip(sequential, mine, strict=True)]
        summary[mode] = {"wall_s": statistics.median(r["wall_s"] for r in mine),
                         "cpu_s": statistics.median(r["cpu_s"] for r in mine),
                         "wall_ratio": statistics.median(ratios),
                         "success_rate": mine[0]["record"]["success_rate"],
                         "command": mine[0]["command"],
                         "vs_sequential": compare(sequential[0]["record"], mine[0]["record"])}
        s = summary[mode]
        loads = ", ".join(f"{r['load']:.1f}" for r in mine)
        print(f"| `{s['command']}` | {s['wall_s']:.1f} | {s['cpu_s']:.1f} | "
              f"{s['wall_ratio']:.2f}x | {s['success_rate']:.1%} | {loads} |")
    print()
    for mode in modes[1:]:
        print(f"{mode} against sequential: {summary[mode]['vs_sequential']}")
    if args.out is not None:
        for r in rows:
            del r["record"]
        args.out.write_text(json.dumps({"rows": rows, "summary": summary}, indent=2) + "\n")


if __name__ == "__main__":
    main()
