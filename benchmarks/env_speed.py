"""SmartCar-v0 stepping speed as ratios, measured interleaved in one run.

    python benchmarks/env_speed.py [--steps 1500] [--rounds 3] [--baseline-ref 1103dff]
    python benchmarks/env_speed.py --robots [--steps 1500] [--rounds 3]

Each round measures every variant once, in turn, each in a fresh subprocess (random actions,
seeded, timed after a warm-up, episode resets included: what a rollout costs); a ratio is taken
within a round, and the table
shows the median over rounds. This machine's speed drifts by up to a half within minutes, so
only ratios measured side by side mean anything. Variants, for each wheel contact model:

- ``env``: ``gym.make("SmartCar-v0")`` of this checkout (event-driven stepping, 10 ms substeps).
- ``round-1 env``: the same, from the round-1 code (``--baseline-ref``, extracted with
  ``git archive``): fixed 2 ms stepping, 50 physics steps per 0.1 s.
- ``raw 500 Hz``: the same robot, spawned as the env spawns it, driven by pybullet's velocity
  motors (diff-drive targets from the random actions), ``stepSimulation`` 50 times per 0.1 s:
  bare physics at the rate the board's 34 ms frames needed before, nothing of the env.
- ``racecar``: bullet3's ``RacecarGymEnv`` (pybullet_envs, which needs the old ``gym`` API: a
  shim maps it to gymnasium in the worker only) at 10 physics steps of 10 ms per action, the
  same 0.1 s as one SmartCar-v0 step. Compared by real-time factor (simulated s per wall s).

``--robots`` instead compares what the default stepping costs for users' robots (the test
fixtures ``casterbot``, differential drive, and ``heavybot``, skid steer) against the smartcar,
each ``gym.make("SmartCar-v0", model=..., controller_config=...)`` at its defaults, plus the
casterbot without the differential-drive guards (taken for a skid base: 10 solver iterations,
encoders on an edge), which shows what the guards cost.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
import types
from pathlib import Path

HERE = Path(__file__).resolve()
REPO = HERE.parent.parent
CONTROL_PERIOD_S = 0.1
WARMUP = 100
FIXTURES = REPO / "tests" / "fixtures"
#: --robots: name -> (model, controller YAML) relative to FIXTURES; None: the shipped smartcar
ROBOTS = {
    "smartcar": None,
    "casterbot": ("casterbot_description/urdf/casterbot.urdf.xacro",
                  "casterbot_description/config/casterbot_arbotix.yaml"),
    "casterbot unguarded": ("casterbot_description/urdf/casterbot.urdf.xacro",
                            "casterbot_description/config/casterbot_arbotix.yaml"),
    "heavybot": ("heavybot_description/urdf/heavybot.urdf.xacro",
                 "heavybot_description/config/heavybot_arbotix.yaml"),
}


# -- workers (run in a subprocess: python env_speed.py --worker NAME ...) ----------------------
def _random_actions(n: int):
    import numpy as np

    return np.random.default_rng(0).uniform(-1, 1, size=(n, 2)).astype(np.float32)


def worker_env(steps: int, contact: str, robot: str = "smartcar") -> float:
    """Env steps per second of ``gym.make("SmartCar-v0")`` (whichever smartcar_gym imports)."""
    import gymnasium as gym

    import smartcar_gym  # noqa: F401

    files = ROBOTS[robot]
    kwargs = {} if files is None else {"model": str(FIXTURES / files[0]),
                                       "controller_config": str(FIXTURES / files[1])}
    if robot.endswith("unguarded"):
        from smartcar_gym.model import RobotModel

        RobotModel.drive_kind = property(lambda self: "skid")
    env = gym.make("SmartCar-v0", wheel_contact=contact, **kwargs)
    env.reset(seed=0)
    start = 0.0
    for i, action in enumerate(_random_actions(steps + WARMUP)):
        if i == WARMUP:
            start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return steps / elapsed


def worker_raw(steps: int, contact: str, robot: str = "smartcar") -> float:
    """Env-step equivalents per second of bare 500 Hz stepping of the same robot."""
    import numpy as np

    from smartcar_gym.controller import load_controller_config
    from smartcar_gym.envs.robots import SmartCarRobot
    from smartcar_gym.model import load_model
    from smartcar_gym.sim.pybullet.simulator import Simulator

    sim = Simulator(max_substep_s=0.002)
    config = load_controller_config()
    model = load_model()
    robot = SmartCarRobot(sim, model, config, mode="hardware", wheel_contact=contact)
    robot.spawn()
    c, body = sim.client, robot.body.uid
    idx = robot.wheel_joint_indices
    signs = np.array([w.forward_sign for w in robot.wheels])
    left = np.array([w.side == "left" for w in robot.wheels])
    forces = [config.motor.stall_torque_nm / 2] * len(idx)  # each wheel's share of its motor
    half_track = config.base_width_m / 2
    scale = np.array([0.5, 2.0])  # SmartCar-v0's max_linear, max_angular
    physics_steps = round(CONTROL_PERIOD_S / 0.002)
    step, set_motors = c.stepSimulation, c.setJointMotorControlArray
    elapsed = 0.0
    for i, action in enumerate(_random_actions(steps + WARMUP)):
        start = time.perf_counter()
        v, w = action * scale
        speeds = np.where(left, v - w * half_track, v + w * half_track) / model.wheel_radius_m
        set_motors(body, idx, c.VELOCITY_CONTROL, targetVelocities=list(speeds * signs),
                   forces=forces)
        for _ in range(physics_steps):
            step()
        if i >= WARMUP:
            elapsed += time.perf_counter() - start
    sim.close()
    return steps / elapsed


def _old_gym_shim() -> None:
    """Let pybullet_envs (written for ``gym`` < 0.26) import against gymnasium."""
    import gymnasium
    import gymnasium.spaces
    import gymnasium.utils.seeding

    sys.modules.setdefault("gym", gymnasium)
    sys.modules.setdefault("gym.spaces", gymnasium.spaces)
    sys.modules.setdefault("gym.utils", gymnasium.utils)
    sys.modules.setdefault("gym.utils.seeding", gymnasium.utils.seeding)
    # pybullet_envs/__init__.py registers its envs with gym's old registry: skip it
    import importlib.util

    spec = importlib.util.find_spec("pybullet")
    root = Path(spec.origin).parent / "pybullet_envs"
    for name, folder in (("pybullet_envs", root), ("pybullet_envs.bullet", root / "bullet")):
        package = types.ModuleType(name)
        package.__path__ = [str(folder)]
        sys.modules.setdefault(name, package)
    try:
        import pkg_resources  # noqa: F401
    except ImportError:  # setuptools without pkg_resources: racecarGymEnv only compares versions
        from packaging.version import parse

        sys.modules["pkg_resources"] = types.SimpleNamespace(parse_version=parse)


def worker_racecar(steps: int, contact: str, robot: str = "smartcar") -> float:
    """Actions per second of bullet3's RacecarGymEnv at 10 physics steps of 10 ms per action."""
    del contact, robot
    import contextlib
    import io

    _old_gym_shim()
    with contextlib.redirect_stdout(io.StringIO()):  # it prints "init"
        from pybullet_envs.bullet.racecarGymEnv import RacecarGymEnv

        env = RacecarGymEnv(actionRepeat=10, renders=False)
    env.seed(0)
    env.reset()
    start = 0.0
    for i, action in enumerate(_random_actions(steps + WARMUP)):
        if i == WARMUP:
            start = time.perf_counter()
        _, _, done, _ = env.step(action)
        if done:  # every 100 actions (its 1000 physics steps)
            env.reset()
    return steps / (time.perf_counter() - start)


WORKERS = {"env": worker_env, "raw": worker_raw, "racecar": worker_racecar}


# -- driver ------------------------------------------------------------------------------------
def extract_baseline(ref: str, into: Path) -> Path | None:
    """The package at git ``ref`` in ``into``; None (with a note) if git cannot give it."""
    archive = into / "baseline.tar"
    try:
        subprocess.run(["git", "-C", str(REPO), "archive", "-o", str(archive), ref,
                        "smartcar_gym"], check=True, capture_output=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as err:
        print(f"note: no round-1 baseline ({ref}): {err}", file=sys.stderr)
        return None
    with tarfile.open(archive) as tar:
        tar.extractall(into / "baseline", filter="data")
    return into / "baseline"


def measure(worker: str, steps: int, contact: str, pythonpath: Path | None = None,
            robot: str = "smartcar") -> float:
    env = {**os.environ, "PYTHONPATH": str(pythonpath or REPO)}
    out = subprocess.run(
        [sys.executable, str(HERE), "--worker", worker, "--steps", str(steps),
         "--wheel-contact", contact, "--robot", robot],
        capture_output=True, text=True, env=env, timeout=1800, check=False,
    )
    if out.returncode != 0:
        raise RuntimeError(f"worker {worker} ({contact}) failed:\n{out.stderr[-2000:]}")
    return float(json.loads(out.stdout.strip().splitlines()[-1])["rate"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1500)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--baseline-ref", default="1103dff",
                        help="git ref of the round-1 code (fixed 2 ms stepping)")
    parser.add_argument("--no-racecar", action="store_true")
    parser.add_argument("--robots", action="store_true",
                        help="compare users' robots (test fixtures) with the smartcar instead")
    parser.add_argument("--worker", choices=sorted(WORKERS), help=argparse.SUPPRESS)
    parser.add_argument("--wheel-contact", default="sphere", help=argparse.SUPPRESS)
    parser.add_argument("--robot", default="smartcar", choices=sorted(ROBOTS),
                        help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        rate = WORKERS[args.worker](args.steps, args.wheel_contact, args.robot)
        print(json.dumps({"rate": rate}))
        return
    if args.robots:
        robots(args)
        return

    with tempfile.TemporaryDirectory(prefix="smartcar_bench_") as tmp:
        baseline = extract_baseline(args.baseline_ref, Path(tmp))
        variants = []
        for contact in ("sphere", "urdf"):
            variants.append((f"env/{contact}", "env", contact, None))
            if baseline is not None:
                variants.append((f"round-1 env/{contact}", "env", contact, baseline))
            variants.append((f"raw 500 Hz/{contact}", "raw", contact, None))
        if not args.no_racecar:
            variants.append(("racecar", "racecar", "sphere", None))
        rates: dict[str, list[float]] = {name: [] for name, *_ in variants}
        for round_ in range(args.rounds):
            for name, worker, contact, path in variants:
                rates[name].append(measure(worker, args.steps, contact, path))
                print(f"round {round_ + 1}: {name}: {rates[name][-1]:,.0f} steps/s",
                      file=sys.stderr, flush=True)
    report(rates, args)


def robots(args: argparse.Namespace) -> None:
    """Each robot of ROBOTS at its default stepping, interleaved; ratios to the smartcar."""
    rates: dict[str, list[float]] = {name: [] for name in ROBOTS}
    for round_ in range(args.rounds):
        for name in ROBOTS:
            rates[name].append(measure("env", args.steps, "sphere", robot=name))
            print(f"round {round_ + 1}: {name}: {rates[name][-1]:,.0f} steps/s",
                  file=sys.stderr, flush=True)
    print(f"SmartCar-v0 at its defaults, random actions, {args.steps} steps per measurement, "
          f"median of {args.rounds} interleaved rounds")
    print("| robot | drive | env steps/s | / smartcar |")
    print("|---|---|---:|---:|")
    drives = {"smartcar": "skid, 4 wheels", "casterbot": "differential, guarded",
              "casterbot unguarded": "differential, taken for skid",
              "heavybot": "skid, 4 wheels"}
    for name, values in rates.items():
        ratio = statistics.median(x / y for x, y in zip(values, rates["smartcar"], strict=True))
        print(f"| {name} | {drives[name]} | {statistics.median(values):,.0f} | {ratio:.2f} |")
    guards = statistics.median(x / y for x, y in zip(
        rates["casterbot"], rates["casterbot unguarded"], strict=True))
    print(f"\ncasterbot / casterbot unguarded (what the guards cost): {guards:.2f}")


def report(rates: dict[str, list[float]], args: argparse.Namespace) -> None:
    def ratio(a: str, b: str) -> str:
        if a not in rates or b not in rates:
            return "-"
        return f"{statistics.median(x / y for x, y in zip(rates[a], rates[b], strict=True)):.2f}"

    print(f"SmartCar-v0, random actions, {args.steps} steps per measurement, median of "
          f"{args.rounds} interleaved rounds (round-1 code: {args.baseline_ref})")
    print("| what | sphere wheels (default) | urdf wheels (cylinders) |")
    print("|---|---:|---:|")
    for label in ("env", "round-1 env", "raw 500 Hz"):
        cells = [f"{statistics.median(rates[f'{label}/{c}']):,.0f}"
                 if f"{label}/{c}" in rates else "-" for c in ("sphere", "urdf")]
        print(f"| {label}, env steps/s | {cells[0]} | {cells[1]} |")
    print(f"| env / round-1 env | {ratio('env/sphere', 'round-1 env/sphere')} | "
          f"{ratio('env/urdf', 'round-1 env/urdf')} |")
    print(f"| env / raw 500 Hz | {ratio('env/sphere', 'raw 500 Hz/sphere')} | "
          f"{ratio('env/urdf', 'raw 500 Hz/urdf')} |")
    if "racecar" in rates:
        # both advance 0.1 s of simulated time per step: the rate ratio is the RTF ratio
        rtf = statistics.median(rates["racecar"]) * CONTROL_PERIOD_S
        print(f"| env real-time factor / RacecarGymEnv's ({rtf:,.0f}x real time at 10 x 10 ms "
              f"per action) | {ratio('env/sphere', 'racecar')} | {ratio('env/urdf', 'racecar')} |")


if __name__ == "__main__":
    main()
