"""Car-steps per second and memory against the number of cars N, for the vector envs.

    python benchmarks/batched_speed.py [--rounds 3] [--out docs/batched_speed.png]

Each round measures every (env, N) once, in turn, each in a fresh subprocess: the env is made
with ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``, reset with a
seed, stepped with seeded random actions (autoresets included) after a warm-up, and timed by
the wall clock and by the process's CPU time. Memory is the growth of the process's resident
set from before the env was made to after the last step. Envs:

- ``SmartCarSim-v0 batched``: the kinematic mode in numpy arrays (``SmartCarSimVectorEnv``).
- ``SmartCarSim-v0 single``: one ``gym.make("SmartCarSim-v0")`` (pybullet world, kinematic).
- ``SmartCar-v0 loop``: the pybullet env's vector_entry_point (N single envs in a loop), up to
  ``--max-loop`` cars (each is a pybullet world).
- ``SmartCar-v0 MuJoCo batched``: ``engine="mujoco"`` through the vector_entry_point
  (``SmartCarBatchVectorEnv``: each car's physics in C, two worker threads), at every N; fewer
  steps per measurement (``--mujoco-car-steps``) since each car-step is a dozen physics steps.
- ``SmartCar-v0 MuJoCo single``: one ``gym.make("SmartCar-v0", engine="mujoco")``.
- ``SmartCarNav-v0 MuJoCo batched``: ``engine="mujoco"`` through the vector_entry_point
  (``SmartCarBatchVectorEnv`` with the Nav part: physics, laser and clearance in C, two
  worker threads), and
  ``SmartCarNav-v0 MuJoCo loop``: the same cars as the loop of single MuJoCo envs that the
  entry point falls back to (``SmartCarLoopVectorEnv``), at N = 16 and 64.

``--only PREFIX`` measures only the rows whose label starts with it (``--only SmartCarNav``:
the Nav rows alone, a minute or two); pass another ``--out`` then, to keep the full sweep's
figure.

The table shows the median over rounds; ratios are taken within a round, since this shared
machine's speed drifts by half within minutes.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SIZES = (1, 4, 16, 64, 256, 1024, 4096)


def _rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def measure(env_id: str, mode: str, n: int, car_steps: int) -> dict[str, float]:
    """One measurement in this process (run by the subprocess)."""
    import time

    import gymnasium as gym
    import numpy as np

    import smartcar_gym  # noqa: F401

    before = _rss_bytes()
    from smartcar_gym.envs.vector import SmartCarLoopVectorEnv

    kwargs = {"engine": "mujoco"} if mode.startswith("mujoco") else {}
    if mode in ("single", "mujoco-single"):
        envs = gym.make_vec(env_id, num_envs=1, vectorization_mode="sync", **kwargs)
    elif mode == "mujoco-loop":
        envs = SmartCarLoopVectorEnv(env_id, num_envs=n, **kwargs)
    else:
        envs = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                            **kwargs)
    rng = np.random.default_rng(0)
    envs.reset(seed=0)
    steps = min(max(5 if mode.startswith("mujoco") else 50, car_steps // n), 5000)
    actions = [rng.uniform(-1, 1, (n, 2)).astype(np.float32) for _ in range(16)]
    for k in range(min(20, steps // 5 or 1)):  # warm-up
        envs.step(actions[k % 16])
    wall, cpu = time.perf_counter(), time.process_time()
    for k in range(steps):
        envs.step(actions[k % 16])
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    grown = _rss_bytes() - before
    envs.close()
    return {"car_steps_per_s": steps * n / wall, "car_steps_per_cpu_s": steps * n / cpu,
            "rss_mib": grown / 2**20}


def run_one(env_id: str, mode: str, n: int, car_steps: int) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, __file__, "--one", env_id, mode, str(n), str(car_steps)],
        check=True, capture_output=True, text=True, cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (speed, memory) = plt.subplots(1, 2, figsize=(10, 4))
    for label, rows in results.items():
        sizes = sorted(int(n) for n in rows)
        speed.plot(sizes, [rows[str(n)]["car_steps_per_s"] for n in sizes], "o-", label=label)
        memory.plot(sizes, [rows[str(n)]["rss_mib"] for n in sizes], "o-", label=label)
    for ax, title in ((speed, "car-steps/s (wall clock)"), (memory, "memory growth (MiB)")):
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("cars N")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    speed.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--car-steps", type=int, default=400_000,
                        help="car-steps per batched measurement (fewer for the pybullet ones)")
    parser.add_argument("--max-loop", type=int, default=64, help="largest N of the loop env")
    parser.add_argument("--mujoco-car-steps", type=int, default=20_000,
                        help="car-steps per MuJoCo batched measurement")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "batched_speed.png")
    parser.add_argument("--nav-car-steps", type=int, default=3_000,
                        help="car-steps per SmartCarNav-v0 measurement")
    parser.add_argument("--only", default="", help="measure only the rows whose label starts "
                        "with this (e.g. SmartCarNav)")
    parser.add_argument("--one", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        env_id, mode, n, car_steps = args.one
        print(json.dumps(measure(env_id, mode, int(n), int(car_steps))))
        return
    plan = [("SmartCarSim-v0 batched", "SmartCarSim-v0", "vector", n, args.car_steps)
            for n in SIZES]
    plan += [("SmartCarSim-v0 single", "SmartCarSim-v0", "single", 1, 3000)]
    plan += [("SmartCar-v0 loop", "SmartCar-v0", "vector", n, 1500)
             for n in SIZES if n <= args.max_loop]
    plan += [("SmartCar-v0 MuJoCo batched", "SmartCar-v0", "mujoco", n, args.mujoco_car_steps)
             for n in SIZES]
    plan += [("SmartCar-v0 MuJoCo single", "SmartCar-v0", "mujoco-single", 1, 3000)]
    plan += [(f"SmartCarNav-v0 MuJoCo {kind}", "SmartCarNav-v0", mode, n, args.nav_car_steps)
             for n in (16, 64) for kind, mode in (("batched", "mujoco"), ("loop", "mujoco-loop"))]
    plan = [row for row in plan if row[0].startswith(args.only)]
    rounds: list[dict] = []
    for r in range(args.rounds):
        got: dict = {}
        for label, env_id, mode, n, steps in plan:
            got.setdefault(label, {})[str(n)] = run_one(env_id, mode, n, steps)
            print(f"round {r}: {label} N={n}: {got[label][str(n)]}", file=sys.stderr)
        rounds.append(got)
    median: dict = {}
    for label, _, _, n, _ in plan:
        rows = [rd[label][str(n)] for rd in rounds]
        median.setdefault(label, {})[str(n)] = {
            key: statistics.median(row[key] for row in rows) for key in rows[0]}
    top = str(SIZES[-1])
    pairs = {
        "batched N=4096 / single SmartCarSim-v0": (("SmartCarSim-v0 batched", top),
                                                    ("SmartCarSim-v0 single", "1")),
        "batched N=4096 / SmartCar-v0 loop N=1": (("SmartCarSim-v0 batched", top),
                                                   ("SmartCar-v0 loop", "1")),
        "MuJoCo batched N=64 / SmartCar-v0 loop N=1 (pybullet)": (
            ("SmartCar-v0 MuJoCo batched", "64"), ("SmartCar-v0 loop", "1")),
        "MuJoCo batched N=64 / MuJoCo single": (("SmartCar-v0 MuJoCo batched", "64"),
                                                ("SmartCar-v0 MuJoCo single", "1")),
    }
    for n in ("16", "64"):
        pairs[f"Nav MuJoCo batched / Nav MuJoCo loop, N={n}"] = (
            ("SmartCarNav-v0 MuJoCo batched", n), ("SmartCarNav-v0 MuJoCo loop", n))
    ratios = {}
    for name, ((a, na), (b, nb)) in pairs.items():
        if a in median and b in median:
            for unit, suffix in (("car_steps_per_s", ""), ("car_steps_per_cpu_s", " (CPU)")):
                ratios[name + suffix] = statistics.median(
                    rd[a][na][unit] / rd[b][nb][unit] for rd in rounds)
    print("| env | N | car-steps/s (wall) | car-steps per CPU-s | memory growth (MiB) |")
    print("|---|---|---|---|---|")
    for label, rows in median.items():
        for n, row in rows.items():
            print(f"| {label} | {n} | {row['car_steps_per_s']:,.0f} | "
                  f"{row['car_steps_per_cpu_s']:,.0f} | {row['rss_mib']:.1f} |")
    for name, value in ratios.items():
        print(f"{name}: x{value:,.1f} (median of per-round ratios)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    plot(median, args.out)
    (args.out.with_suffix(".json")).write_text(json.dumps(
        {"median": median, "ratios": ratios, "rounds": rounds}, indent=1) + "\n")
    print(f"wrote {args.out} and {args.out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
