"""Wall time of ``smartcar-bench barn`` on the planar batch: the issue's 500 runs in 60 s.

    python benchmarks/barn_speed.py [--driver dwa | --pretrained barn] [--localize | --laser]
        [--cars 100 500] [--rounds 2] [--runs 10] [--workers W] [--out FILE.json] [--base REV]
        [--base-pretrained NAME] [--base-workers W] [--engine pybullet] [--worlds 0 6 ...]
        [--env-kwargs K=V ...]

Each round runs, one after the other, the command a user types for each number of cars:
``smartcar-bench barn --driver dwa --engine planar --runs 10 --n-envs N`` (with
``--env-kwargs localize=true`` under ``--localize``), the 50 test worlds x ``--runs``. Each
command's wall time (start-up included) and CPU time (its process and threads, from
``getrusage``) are measured, with the load average before it; ratios are taken within a round
(this shared machine's speed drifts). The runs' records must be the same for every number of
cars (each run's seed and world make it): the script says where they differ. Prints a
Markdown table; ``--out FILE.json`` keeps the numbers. ``--base REV`` measures that commit
too (a temporary git worktree), interleaved with this checkout in each round, and compares
their records run by run. ``--laser`` runs this checkout on the mapless protocol
(``map_mode=laser``, the LDS-01's 1 cm noise: issue 55's 500 distinct runs) and the base, if
any, on the known map localized (issue 55's yardstick: at most 1.5 times its time); the records
then differ by design and the success rates are printed instead. ``--workers W``: this
checkout's command shares its cars among W processes (``--workers W --n-envs cars/W``: the
same cars in all, each process on the CPUs / W); the base, which has no ``--workers``, runs
in one. ``--base-pretrained NAME``: the base's name for the shipped policy (the known-map
policy, ``barn-known`` here, was ``barn`` before the mapless one took that name). Run it once
first if numba's cache is cold (the first run after an install compiles, about 20 s more).
``--engine`` runs another engine (pybullet: issue 55's 20 minutes for a driver's 500 runs),
``--worlds`` a subset of the test worlds, ``--base-workers W`` the base in W processes too (a
base that has ``--workers``), and ``--env-kwargs`` gives both sides the same env kwargs instead
of the protocol's. For example, pybullet's DWA against an earlier commit, on the same mapless
protocol, 10 worlds once each (about a minute a round):

    python benchmarks/barn_speed.py --engine pybullet --base 10c3427 --cars 10 --workers 2 \
        --base-workers 2 --runs 1 --worlds 0 6 12 18 24 30 36 42 48 54 --rounds 3 \
        --env-kwargs map_mode=laser "laser={noise_std_m: 0.01}"
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

from timed import timed_run, worktree_at  # benchmarks/timed.py, beside this script

#: the issues' wall time for the 500-run benchmark: batched on planar, and a driver on pybullet
TARGET_S = {"planar": 60.0, "pybullet": 1200.0}
RECORD_KEYS = ("world", "run", "outcome", "time_s", "steps", "final_distance_m")
LASER = ["map_mode=laser", "laser={noise_std_m: 0.01}"]  # issue 55's headline protocol


def env_kwargs(args: argparse.Namespace, base: bool) -> list[str]:
    """The ``--env-kwargs`` of this checkout's command or of the base's."""
    if args.env_kwargs:
        return list(args.env_kwargs)
    if args.laser:
        return ["localize=true"] if base else LASER
    if args.localize:
        return ["localize=true"]
    # the known map: this checkout's DWA runs without it unless told (the base knows no map_mode)
    return [] if base or args.pretrained else ["map_mode=known"]


def run(cars: int, args: argparse.Namespace, folder: Path, checkout: Path | None = None
        ) -> dict:
    """One ``smartcar-bench barn`` command (``checkout``: that checkout's package, first on
    the path): its wall and CPU seconds and its records."""
    out = folder / f"cars_{cars}_{'base' if checkout else 'this'}.json"
    name = (args.base_pretrained or args.pretrained) if checkout else args.pretrained
    driver = ["--pretrained", name] if args.pretrained else ["--driver", args.driver]
    # --workers / --base-workers: each side's cars shared among W processes
    workers = args.base_workers if checkout else args.workers
    split = ["--workers", str(workers)] if workers > 1 else []
    worlds = ["--worlds", *map(str, args.worlds)] if args.worlds else []
    argv = [sys.executable, "-m", "smartcar_gym.bench.cli", "barn", *driver, "--engine",
            args.engine, *worlds, "--runs", str(args.runs), "--n-envs",
            str(max(1, cars // workers)), *split, "--quiet", "--json", str(out)]
    kwargs = env_kwargs(args, checkout is not None)
    if kwargs:
        argv += ["--env-kwargs", *kwargs]
    env = None if checkout is None else {**os.environ, "PYTHONPATH": str(checkout)}
    timing = timed_run(argv, env, None if checkout is None else str(checkout))
    data = json.loads(out.read_text())
    records = [{k: r[k] for k in RECORD_KEYS} for r in data["records"]]
    return {"cars": cars, **timing, "car_steps": sum(r["steps"] for r in records),
            "records": records, "success_rate": data["success_rate"],
            "command": "smartcar-bench " + " ".join(argv[3:]).replace(str(out), "OUT.json")}


def differing(a: list[dict], b: list[dict]) -> list[tuple[int, int]]:
    """The (world, run) of the records that differ between two runs of the benchmark."""
    return [(x["world"], x["run"]) for x, y in zip(a, b, strict=True) if x != y]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--driver", default="dwa")
    parser.add_argument("--pretrained", default=None, help="a shipped policy instead of DWA")
    parser.add_argument("--base-pretrained", default=None, metavar="NAME",
                        help="the base's name for that policy (default: --pretrained's)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--localize", action="store_true")
    mode.add_argument("--laser", action="store_true",
                      help="this checkout mapless with 1 cm noise, the base known-map localized")
    parser.add_argument("--cars", type=int, nargs="+", default=[100, 500])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--runs", type=int, default=10, help="runs per test world")
    parser.add_argument("--workers", type=int, default=1, metavar="W",
                        help="this checkout's command in W processes of cars / W cars each "
                             "(smartcar-bench barn --workers; the base runs in one)")
    parser.add_argument("--base-workers", type=int, default=1, metavar="W",
                        help="the base's command in W processes (a base with --workers)")
    parser.add_argument("--engine", default="planar", choices=sorted(TARGET_S))
    parser.add_argument("--worlds", type=int, nargs="+", default=None,
                        help="test worlds to run (default: all 50)")
    parser.add_argument("--env-kwargs", nargs="+", default=None, metavar="K=V",
                        help="both sides' env kwargs, instead of the protocol's")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--base", default=None,
                        help="a commit to measure too, interleaved (its records must be the "
                             "same)")
    args = parser.parse_args(argv)
    if args.base is not None:
        return versus(args)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for round_ in range(1, args.rounds + 1):
            for cars in args.cars:
                result = run(cars, args, Path(tmp))
                result["round"] = round_
                results.append(result)
                print(f"round {round_}, {cars} cars: {result['wall_s']:.1f} s", file=sys.stderr)
    first = results[0]["records"]
    target = TARGET_S[args.engine]
    print(f"| round | cars | wall (s) | CPU (s) | load before | car-steps | vs {args.cars[0]} cars"
          f" | within {target:.0f} s |\n|---|---|---|---|---|---|---|---|")
    for r in results:
        base = next(x for x in results if x["round"] == r["round"] and x["cars"] == args.cars[0])
        print(f"| {r['round']} | {r['cars']} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | "
              f"{r['load']:.2f} | {r['car_steps']:,} | {r['wall_s'] / base['wall_s']:.2f}x | "
              f"{'yes' if r['wall_s'] <= target else 'no'} |")
    changed = {r["cars"]: differing(first, r["records"]) for r in results}
    same = not any(changed.values())
    print("records: the same for every number of cars" if same else
          f"records differ (world, run): {changed}")
    if args.out is not None:
        args.out.write_text(json.dumps([{k: v for k, v in r.items() if k != "records"}
                                        for r in results], indent=2))
    return 0 if same else 1


def versus(args: argparse.Namespace) -> int:
    """Each round, for each number of cars: this checkout and ``args.base`` (a temporary git
    worktree) in turn, the order alternating; the ratios within rounds and the records
    compared."""
    root = Path(__file__).resolve().parent.parent
    rows = []
    with tempfile.TemporaryDirectory() as tmp, worktree_at(root, args.base) as base:
        for round_ in range(1, args.rounds + 1):
            for cars in args.cars:
                sides = [("this", None), ("base", base)][::1 if round_ % 2 else -1]
                got = {side: run(cars, args, Path(tmp), path) for side, path in sides}
                rows.append((round_, cars, got))
                print(f"round {round_}, {cars} cars: this {got['this']['wall_s']:.1f} s, "
                      f"{args.base} {got['base']['wall_s']:.1f} s", file=sys.stderr)
    print(f"| round | cars | this (s) | {args.base} (s) | ratio | records |")
    print("|---|---|---|---|---|---|")
    same = True
    for round_, cars, got in rows:
        diff = differing(got["this"]["records"], got["base"]["records"])
        this, then = got["this"]["wall_s"], got["base"]["wall_s"]
        if args.laser:  # different protocols: their successes, not their records
            records = (f"success {got['this']['success_rate']:.3f} (laser) and "
                       f"{got['base']['success_rate']:.3f} (known, localized)")
        else:
            same &= not diff
            records = "the same" if not diff else f"{len(diff)} differ"
        print(f"| {round_} | {cars} | {this:.1f} | {then:.1f} | {this / then:.3f} | {records} |")
    if args.out is not None:
        args.out.write_text(json.dumps([
            {"round": round_, "cars": cars, "base": args.base,
             **{side: {k: v for k, v in got[side].items() if k != "records"} for side in got},
             **({} if args.laser else {"records_differ": differing(got["this"]["records"],
                                                                    got["base"]["records"])})}
            for round_, cars, got in rows], indent=2))
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
