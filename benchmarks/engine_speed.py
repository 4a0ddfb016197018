"""One env's steps/s on MuJoCo against pybullet, measured interleaved in one run (the ratio).

    python benchmarks/engine_speed.py [--steps 600] [--rounds 5] [--env SmartCar-v0 ...]
    python benchmarks/engine_speed.py --levers    # MuJoCo settings that trade fidelity for speed

Each round steps one env of each engine for ``--steps`` seeded random actions (episode resets
included: what a rollout costs), one engine after the other; a ratio is taken within a round
and the table shows the median over rounds. The time spent inside the engine's physics stepping
(``Simulator._step_physics``: pybullet's ``stepSimulation`` loop, MuJoCo's ``mj_step``) is timed
too, so the table also says how much of a step is physics and how much is the Python around it
(the emulated board and controller, the observation, the task), which both engines share.
This machine's speed drifts by up to a half within minutes: only the ratio means anything.
The ratio cell gives the median over rounds and, in brackets, the lowest and highest round;
the CPU ratio is the same from process CPU time, which counts no time spent waiting for a core
on a shared machine.

``--levers`` measures SmartCar-v0 on MuJoCo as shipped against two settings it does not use
(pyramidal friction cones; 20 ms substeps), each and both, against pybullet in the same rounds:
what they would buy. ``--lever-fidelity`` says what they cost: the fidelity table's spin rates
and coast-down under each setting, against pybullet's (at its shipped 10 ms substeps).
``--substep-costs`` times one MuJoCo substep of a driving car with its options switched one at a
time (where a substep's time goes); ``--impratio-sweep`` measures the slow spin at 20 ms substeps
for a range of ``impratio`` (whether any setting holds the fidelity tolerance).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401

ENGINES = ("pybullet", "mujoco")


class PhysicsTimer:
    """Wraps a simulator's ``_step_physics`` to add up the seconds spent in it."""

    def __init__(self, sim) -> None:
        self.seconds = 0.0
        inner = sim._step_physics

        def timed(interval_ns, probe):
            start = time.perf_counter()
            inner(interval_ns, probe)
            self.seconds += time.perf_counter() - start

        sim._step_physics = timed


def measure(env_id: str, steps: int, rounds: int) -> dict[str, list[tuple[float, float, float]]]:
    """For each engine, per round: (steps/s, share of the time in physics, steps per CPU s)."""
    envs = {engine: gym.make(env_id, engine=engine) for engine in ENGINES}
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, 2)).astype(np.float32)
    results: dict[str, list[tuple[float, float, float]]] = {engine: [] for engine in ENGINES}
    for env in envs.values():  # warm up
        env.reset(seed=0)
        for action in actions[:50]:
            env.step(action)
    for _ in range(rounds):
        for engine, env in envs.items():
            env.reset(seed=1)
            timer = PhysicsTimer(env.unwrapped.sim)  # the reset's world keeps the wrapper
            start, cpu = time.perf_counter(), time.process_time()
            for action in actions:
                _, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    env.reset()  # the same simulator: the wrapper stays
            elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
            results[engine].append((steps / elapsed, timer.seconds / elapsed, steps / cpu))
    for env in envs.values():
        env.close()
    return results


LEVERS = {"MuJoCo as shipped": ({}, 0.01), "pyramidal cones": ({"cone": 0}, 0.01),
          "20 ms substeps": ({}, 0.02), "both": ({"cone": 0}, 0.02)}


def levers(steps: int, rounds: int) -> None:
    """The ``--levers`` table."""
    from smartcar_gym.sim.mujoco import simulator

    reset = simulator.MujocoSimulator.reset
    options: dict[str, int] = {}

    def patched(self) -> None:
        reset(self)
        for key, value in options.items():
            setattr(self.spec.option, key, value)

    simulator.MujocoSimulator.reset = patched
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, 2)).astype(np.float32)
    speeds: dict[str, list[float]] = {"pybullet": [], **{name: [] for name in LEVERS}}
    cpu_speeds: dict[str, list[float]] = {name: [] for name in speeds}
    for _ in range(rounds):
        for name in speeds:
            if name == "pybullet":
                env = gym.make("SmartCar-v0")
            else:
                options, substep = LEVERS[name]
                env = gym.make("SmartCar-v0", engine="mujoco", max_substep_s=substep)
            env.reset(seed=1)
            start, cpu = time.perf_counter(), time.process_time()
            for action in actions:
                _, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    env.reset()
            speeds[name].append(steps / (time.perf_counter() - start))
            cpu_speeds[name].append(steps / (time.process_time() - cpu))
            env.close()
    print("| SmartCar-v0 | steps/s | / pybullet | CPU ratio |")
    print("|---|---|---|---|")
    for name, values in speeds.items():
        cells = []
        for table in (speeds, cpu_speeds):
            ratios = [v / p for v, p in zip(table[name], table["pybullet"], strict=True)]
            cells.append(f"x{statistics.median(ratios):.2f} ({min(ratios):.2f}-{max(ratios):.2f})")
        print(f"| {name} | {statistics.median(values):.0f} | {' | '.join(cells)} |")


def lever_fidelity(names: tuple[str, ...] | None = None) -> None:
    """The ``--lever-fidelity`` table (of the maneuvers ``names``: spins and coast-down)."""
    from smartcar_gym.calibration import engines_compared
    from smartcar_gym.controller import load_controller_config
    from smartcar_gym.model import load_model
    from smartcar_gym.sim.mujoco import simulator

    model, config = load_model(), load_controller_config()
    rows = [m for m in engines_compared.MANEUVERS
            if (m.name in names if names else m.name.startswith(("spin rate", "coast-down")))]
    reference = {m.name: m.measure(model, config, "pybullet") for m in rows}
    reset, shipped_substep = simulator.MujocoSimulator.reset, engines_compared.DEFAULT_MAX_SUBSTEP_S
    print(f"| setting | {' | '.join(m.name for m in rows)} |")
    print(f"|---|{'---|' * len(rows)}")
    try:
        for name, (options, substep) in LEVERS.items():
            def patched(self, options=options) -> None:
                reset(self)
                for key, value in options.items():
                    setattr(self.spec.option, key, value)

            simulator.MujocoSimulator.reset = patched
            engines_compared.DEFAULT_MAX_SUBSTEP_S = substep
            cells = [engines_compared.relative_difference(m.measure(model, config, "mujoco"),
                                                          reference[m.name]) for m in rows]
            print(f"| {name} | {' | '.join(f'{c:+.1%}' for c in cells)} |", flush=True)
    finally:
        simulator.MujocoSimulator.reset = reset
        engines_compared.DEFAULT_MAX_SUBSTEP_S = shipped_substep


SUBSTEP_VARIANTS = {
    "as shipped": {},
    "no warm start": {"disableflags": "WARMSTART"},
    "no gearbox friction": {"disableflags": "FRICTIONLOSS"},
    "no wheel chain": {"disableflags": "EQUALITY"},
    "pyramidal cones": {"cone": 0},
    "no contacts": {"disableflags": "CONTACT"},
    "no constraints at all": {"disableflags": "CONSTRAINT"},
}


def substep_costs(repeats: int = 400, substeps: int = 12) -> None:
    """The ``--substep-costs`` table: CPU per ``mj_step`` of one mid-drive state."""
    import copy

    import mujoco

    env = gym.make("SmartCar-v0", engine="mujoco")
    env.reset(seed=0)
    for _ in range(40):  # a curve at speed: four wheels on the ground
        env.step(np.array([0.6, 0.4], dtype=np.float32))
    sim = env.unwrapped.sim
    shipped, data = sim.model_compiled(), sim.data
    state = [data.qpos.copy(), data.qvel.copy(), data.qacc_warmstart.copy(),
             data.qfrc_applied.copy()]
    print("| `mj_step` of the same state | us per substep (CPU) |")
    print("|---|---|")
    for name, change in SUBSTEP_VARIANTS.items():
        model = copy.copy(shipped)
        for key, value in change.items():
            if key == "disableflags":
                model.opt.disableflags |= getattr(mujoco.mjtDisableBit, f"mjDSBL_{value}")
            else:
                setattr(model.opt, key, value)
        d = mujoco.MjData(model)
        best = math.inf
        for _ in range(5):
            cpu = time.process_time()
            for _ in range(repeats):
                d.qpos[:], d.qvel[:], d.qacc_warmstart[:], d.qfrc_applied[:] = state
                mujoco.mj_step(model, d, substeps)
            best = min(best, (time.process_time() - cpu) / repeats / substeps)
        print(f"| {name} | {best * 1e6:.1f} |", flush=True)
    env.close()


def impratio_sweep(values: tuple[float, ...] = (1, 2, 3, 5, 10, 30)) -> None:
    """The ``--impratio-sweep`` row: the 0.5 rad/s spin at 20 ms substeps against pybullet."""
    global LEVERS
    shipped = LEVERS
    try:
        LEVERS = {f"impratio {v:g}": ({"impratio": float(v)}, 0.02) for v in values}
        lever_fidelity(("spin rate at cmd_vel 0.5 rad/s",))
    finally:
        LEVERS = shipped


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--env", nargs="+", default=["SmartCar-v0", "SmartCarNav-v0"])
    parser.add_argument("--levers", action="store_true",
                        help="MuJoCo settings it does not use, against pybullet")
    parser.add_argument("--lever-fidelity", action="store_true",
                        help="what those settings change in the fidelity table")
    parser.add_argument("--substep-costs", action="store_true",
                        help="CPU per MuJoCo substep with its options switched one at a time")
    parser.add_argument("--impratio-sweep", action="store_true",
                        help="the slow spin at 20 ms substeps for a range of impratio")
    args = parser.parse_args()
    if args.substep_costs:
        substep_costs()
        return
    if args.impratio_sweep:
        impratio_sweep()
        return
    if args.lever_fidelity:
        lever_fidelity()
        return
    if args.levers:
        levers(args.steps, args.rounds)
        return
    print("| env | pybullet steps/s | physics share | MuJoCo steps/s | physics share | "
          "MuJoCo / pybullet | CPU ratio |")
    print("|---|---|---|---|---|---|---|")
    for env_id in args.env:
        results = measure(env_id, args.steps, args.rounds)
        cells = []
        for engine in ENGINES:
            cells.append(f"{statistics.median(r[0] for r in results[engine]):.0f}")
            cells.append(f"{statistics.median(r[1] for r in results[engine]):.0%}")
        for column in (0, 2):  # wall clock, CPU time
            ratios = [m[column] / p[column] for p, m in zip(results["pybullet"],
                                                            results["mujoco"], strict=True)]
            cells.append(f"x{statistics.median(ratios):.2f} ({min(ratios):.2f}-{max(ratios):.2f})")
        print(f"| {env_id} | {' | '.join(cells)} |")


if __name__ == "__main__":
    main()
