"""Robustness of policies to the plant: success on a grid of perturbed smartcars.

    nice -n 5 python benchmarks/robustness.py --episodes 100 --n-envs 2 \
        --json robustness.json > robustness.md

Each policy (``--policy NAME=FOLDER``; default: the shipped ones, ``nominal`` =
``smartcar_gym/pretrained`` and ``robust`` = ``smartcar_gym/pretrained/robust``) is evaluated
on SmartCar-v0 with the seeded episodes of ``smartcar-eval`` (episode i: seed SEED+i, so every
plant sees the same goals) on these plants:

- ``nominal``: ``randomize=None``;
- each factor of the preset alone, fixed at each end of its range that is not its nominal value
  (``randomize={factor: end}``): the same as ``smartcar-eval --env-kwargs
  "randomize={factor: end}"``;
- ``full preset``: ``randomize=<preset>``, every factor drawn per episode.

Prints a Markdown table (success rate per plant and policy) and the wall time; ``--json``
keeps every summary. A FOLDER is an exported policy's folder or a smartcar-train run folder
(its ``best_model.zip``); its normaliser is loaded from there (a pickle: only folders you
trust).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from importlib import resources
from pathlib import Path
from typing import Any

from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.records import summarize
from smartcar_gym.envs.randomization import FACTORS, Randomization
from smartcar_gym.policy import Policy

PRETRAINED = resources.files("smartcar_gym") / "pretrained"


def plants(preset: str) -> list[tuple[str, Any]]:
    """(label, randomize) of every plant of the grid for ``preset``."""
    spec = Randomization.from_spec(preset)
    out: list[tuple[str, Any]] = [("nominal", None)]
    for factor in FACTORS:
        for end in dict.fromkeys(spec.ranges[factor.name]):
            if end != factor.nominal:
                out.append((f"{factor.name} = {end:g}", {factor.name: end}))
    out.append((f"full preset ({preset})", preset))
    return out


def _policy(arg: str) -> tuple[str, Path]:
    name, sep, folder = arg.partition("=")
    if not sep or not name or not folder:
        raise argparse.ArgumentTypeError(f"expected NAME=FOLDER, got {arg!r}")
    return name, Path(folder)


def _load(folder: Path) -> Policy:
    path = folder / "best_model.zip" if (folder / "config.yaml").is_file() else folder
    return Policy.load(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--policy", type=_policy, action="append", metavar="NAME=FOLDER",
                        help="a policy to evaluate (repeat); default: the shipped ones")
    parser.add_argument("--preset", default="default", help="randomize preset or YAML file "
                        "whose ranges make the grid (default: default)")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--n-envs", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", nargs="+", metavar="LABEL", help="only plants whose label "
                        "starts with one of these (e.g. nominal track latency)")
    parser.add_argument("--json", type=Path, help="write every summary here")
    args = parser.parse_args(argv)
    policies = args.policy or [("nominal", Path(str(PRETRAINED))),
                               ("robust", Path(str(PRETRAINED / "robust")))]
    grid = plants(args.preset)
    if args.only:
        grid = [(label, spec) for label, spec in grid if label.startswith(tuple(args.only))]
    loaded = {name: _load(folder) for name, folder in policies}
    results: dict[str, dict[str, Any]] = {}
    start = time.perf_counter()
    for label, randomize in grid:
        results[label] = {}
        for name, policy in loaded.items():
            t0 = time.perf_counter()
            records = evaluate_policy_episodes(
                policy, "SmartCar-v0", n_episodes=args.episodes, n_envs=args.n_envs,
                seed=args.seed, env_kwargs={"randomize": randomize})
            results[label][name] = {**summarize(records), "wall_s": time.perf_counter() - t0}
            print(f"{label:<32} {name:<10} {results[label][name]['success_rate']:6.1%} "
                  f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    wall = time.perf_counter() - start
    names = list(loaded)
    print(f"| plant | {' | '.join(names)} |")
    print(f"|---|{'---:|' * len(names)}")
    for label, row in results.items():
        cells = " | ".join(f"{row[n]['success_rate']:.0%}" for n in names)
        print(f"| {label} | {cells} |")
    print(f"\n{len(grid)} plants x {len(names)} policies x {args.episodes} episodes "
          f"(seeds {args.seed}..{args.seed + args.episodes - 1}), {args.n_envs} envs: "
          f"{wall / 60:.1f} min")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "preset": args.preset, "episodes": args.episodes, "seed": args.seed,
            "n_envs": args.n_envs, "wall_s": wall,
            "policies": {n: str(f) for n, f in policies}, "results": results,
        }, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
